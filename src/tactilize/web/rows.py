"""The pen samples as the pages send them: rows in CSS pixels and milliseconds.

A row is ``[t_ms, x_px, y_px, pressure?, tilt_x_deg?, tilt_y_deg?]``: the
pointer event's own timestamp [ms], the position in CSS pixels from the
picture's top-left corner (y down), pressure in [0, 1] or null, tilt [deg].
The pen page (:mod:`.session`) and the experiments' page
(:mod:`tactilize.experiments.flow`) check each row with :func:`sample_error`
and convert the good ones with :func:`samples_from_css`.

This module imports nothing of the web server, so the experiments and the
tests can use it without starting one.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, Sequence

from ..pen.samples import PenSample

__all__ = ["DEFAULT_M_PER_CSS_PX", "MAX_ABS_TIME_MS", "MAX_ABS_POSITION", "MAX_ABS_TILT_DEG", "sample_error",
           "samples_from_css"]

#: A CSS pixel is 1/96 inch by definition (docs/references.md, section 5) [m];
#: the page replaces this with a calibrated value.
DEFAULT_M_PER_CSS_PX = 0.0254 / 96.0

#: Largest time a row may carry [ms]: 1e15 ms is 31 700 years, far beyond an
#: epoch timestamp; beyond it, differences of two times can overflow a float.
MAX_ABS_TIME_MS = 1e15
#: Largest coordinate a row may carry [CSS px on the pen page, mm on the
#: experiments' page]: kilometres either way; a finite coordinate near the
#: float limit makes a stroke's lengths infinite.
MAX_ABS_POSITION = 1e7
#: Tilt range of a pointer event [deg] (docs/references.md, section 5).
MAX_ABS_TILT_DEG = 90.0

#: What a row that stops early means: no pressure (a mouse), no tilt.
_OPTIONAL_DEFAULTS = (None, 0.0, 0.0)  # pressure, tilt_x_deg, tilt_y_deg


def _finite_number(v: Any) -> bool:
    """An int or float (not a bool) with a finite value."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:  # an integer beyond any float (JSON allows any length)
        return False


_MAX_ABS = (MAX_ABS_TIME_MS, MAX_ABS_POSITION, MAX_ABS_POSITION, math.inf, MAX_ABS_TILT_DEG, MAX_ABS_TILT_DEG)
_NAMES = ("time", "x", "y", "pressure", "tilt x", "tilt y")


def sample_error(row: Any) -> str | None:
    """Why a page's sample row is malformed, or None when it is fine.

    Parameters
    ----------
    row : any
        What the page sent as one sample (parsed JSON).

    Returns
    -------
    str or None
        The fault in a few words, for the page.
    """
    if not isinstance(row, (list, tuple)):
        return "a sample must be an array [t_ms, x_px, y_px, pressure?, tilt_x_deg?, tilt_y_deg?]"
    if not 3 <= len(row) <= 6:
        return f"a sample has 3 to 6 values, got {len(row)}"
    for i, v in enumerate(row):
        if i == 3 and v is None:  # no pressure (a mouse)
            continue
        if not _finite_number(v):
            return f"sample value {i} must be a finite number, got {v!r}"
        if abs(v) > _MAX_ABS[i]:
            return f"sample value {i} ({_NAMES[i]}) must be within +-{_MAX_ABS[i]:g}, got {v!r}"
    if len(row) > 3 and row[3] is not None and not 0.0 <= row[3] <= 1.0:
        return f"pressure must be in [0, 1], got {row[3]!r}"
    return None


def samples_from_css(rows: Iterable[Sequence[Any]], m_per_px: float) -> list[PenSample]:
    """Pen samples in SI from the page's rows.

    Parameters
    ----------
    rows : iterable of sequences
        ``[t_ms, x_px, y_px, pressure?, tilt_x_deg?, tilt_y_deg?]``, each
        already passed by :func:`sample_error`.
    m_per_px : float
        Calibrated size of one CSS pixel on the screen [m].

    Returns
    -------
    list of PenSample
    """
    samples = []
    for t_ms, x_px, y_px, *given in rows:
        pressure, tilt_x_deg, tilt_y_deg = tuple(given) + _OPTIONAL_DEFAULTS[len(given) :]
        samples.append(PenSample(t_ms * 1e-3, x_px * m_per_px, y_px * m_per_px, pressure, tilt_x_deg, tilt_y_deg))
    return samples
