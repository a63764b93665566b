"""The pen socket's one sample message, as both pages send it.

Both pages (the pen page, :mod:`.session`, and the experiment's page,
:mod:`tactilize.experiments.strokes`) send pen samples as one message::

    {"type": "samples", "batch": ID, "samples": [[t_ms, x_mm, y_mm, pressure?, tilt_x_deg?, tilt_y_deg?], ...],
     ...page-specific fields (the experiment's "trial" and "image")}

A row is the pointer event's own timestamp [ms], the position in millimetres
on the picture as shown (from its top-left corner, y down; the page converts
CSS pixels with its calibration), pressure in [0, 1] or null (a mouse), tilt
[deg]; the last three may be left out.  ``batch`` is the page's id of the
message, a string of 1 .. :data:`MAX_BATCH_ID` characters (optional): the
experiment stores each batch once by it and acknowledges it after the commit,
the pen page's drive echoes it.  :func:`pen_batch` is the one parser both
socket handlers call; :func:`sample_error` checks one row.

This module imports nothing of the web server, so the experiments and the
tests can use it without starting one.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, NamedTuple, Sequence

from ..pen.samples import PenSample

__all__ = ["DEFAULT_M_PER_CSS_PX", "MAX_ABS_TIME_MS", "MAX_ABS_POSITION", "MAX_ABS_TILT_DEG", "MAX_BATCH",
           "MAX_BATCH_ID", "M_PER_MM", "PenBatch", "PenMessageError", "batch_id", "pen_batch", "sample_error",
           "samples_from_css"]

#: A CSS pixel is 1/96 inch by definition (docs/references.md, section 5) [m];
#: the page replaces this with a calibrated value.
DEFAULT_M_PER_CSS_PX = 0.0254 / 96.0

#: Largest time a row may carry [ms]: 1e15 ms is 31 700 years, far beyond an
#: epoch timestamp; beyond it, differences of two times can overflow a float.
MAX_ABS_TIME_MS = 1e15
#: Largest coordinate a row may carry [mm]: ten kilometres; a finite
#: coordinate near the float limit makes a stroke's lengths infinite.
MAX_ABS_POSITION = 1e7
#: Tilt range of a pointer event [deg] (docs/references.md, section 5).
MAX_ABS_TILT_DEG = 90.0
#: Samples allowed in one message: a 1 kHz device coalesced at 4 Hz would fit.
MAX_BATCH = 256
#: Longest batch id a page may choose (the experiment's column is this wide).
MAX_BATCH_ID = 64
#: Metres per millimetre: the rows' positions are millimetres.
M_PER_MM = 1e-3

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
        return "a sample must be an array [t_ms, x_mm, y_mm, pressure?, tilt_x_deg?, tilt_y_deg?]"
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
    """Pen samples in SI from rows of positions in any unit.

    Parameters
    ----------
    rows : iterable of sequences
        ``[t_ms, x, y, pressure?, tilt_x_deg?, tilt_y_deg?]``, each
        already passed by :func:`sample_error`.
    m_per_px : float
        Size of the positions' unit [m]: :data:`M_PER_MM` for the socket's
        rows, a CSS pixel's calibrated size for rows in pixels.

    Returns
    -------
    list of PenSample
    """
    samples = []
    for t_ms, x_px, y_px, *given in rows:
        pressure, tilt_x_deg, tilt_y_deg = tuple(given) + _OPTIONAL_DEFAULTS[len(given) :]
        samples.append(PenSample(t_ms * 1e-3, x_px * m_per_px, y_px * m_per_px, pressure, tilt_x_deg, tilt_y_deg))
    return samples


class PenMessageError(ValueError):
    """A message the pen socket refuses; its text is the one line the page is told."""


class PenBatch(NamedTuple):
    """One sample message, checked: its id and its samples in SI."""

    #: The page's id of the message, or None when it gave none.
    batch: str | None
    #: The samples, positions in metres on the picture, times in seconds.
    samples: list[PenSample]


def batch_id(value: Any) -> str | None:
    """The page's batch id, checked: a string of 1 .. :data:`MAX_BATCH_ID` characters, or None when absent.

    Raises
    ------
    PenMessageError
        The id is of another type or length.
    """
    if value is None:
        return None
    if not isinstance(value, str) or not 1 <= len(value) <= MAX_BATCH_ID:
        raise PenMessageError(f"'batch' must be an id of 1 .. {MAX_BATCH_ID} characters, got {str(value)[:80]!r}")
    return value


def pen_batch(msg: Any) -> PenBatch:
    """The one parser of the pen socket's sample message, for both pages.

    Parameters
    ----------
    msg : any
        The parsed JSON of one message: ``{"type": "samples", "batch": ID?,
        "samples": [[t_ms, x_mm, y_mm, pressure?, tilt_x_deg?, tilt_y_deg?], ...]}``
        (other fields are the caller's).

    Returns
    -------
    PenBatch
        The batch id and the samples in SI (s, m); an empty list when the page sent none.

    Raises
    ------
    PenMessageError
        The message is not a sample message or a row is malformed; its text
        names the fault in one line, for the page.
    """
    if not isinstance(msg, dict) or msg.get("type") != "samples":
        raise PenMessageError("a sample message is a JSON object with \"type\": \"samples\"")
    rows = msg.get("samples")
    if not isinstance(rows, list):
        raise PenMessageError("'samples' must be an array of [t_ms, x_mm, y_mm, pressure?, tilt_x_deg?, tilt_y_deg?]")
    if len(rows) > MAX_BATCH:
        raise PenMessageError(f"too many samples in one message ({len(rows)}, limit {MAX_BATCH})")
    for i, row in enumerate(rows):
        err = sample_error(row)
        if err is not None:
            raise PenMessageError(f"sample {i}: {err}")
    return PenBatch(batch_id(msg.get("batch")), samples_from_css(rows, M_PER_MM))
