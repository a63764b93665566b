"""The numbers the pages need from the server's rules, served rather than copied into JavaScript.

``GET /api/constants`` (the pen app) and ``GET /experiment/api/constants`` (the
experiment's routes) answer :func:`page_constants`; ``static/constants.js``
loads it once for every module of either page (the calibration, the pen input,
the surface's repeat, the audio worklet's wavelet rule), so a rule changed here
changes on the pages too.
"""

from __future__ import annotations

from typing import Any

from ..pen.display import CARD_MM, MM_PER_PX_RANGE
from ..synthesis.wavelets import GLIDE_S, LATE_SIGMAS, SAME_S, SPAN_SIGMAS
from .rows import DEFAULT_M_PER_CSS_PX, MAX_BATCH, MAX_BATCH_ID
from .session import MAX_REPEAT

__all__ = ["page_constants"]


def page_constants() -> dict[str, Any]:
    """The constants both pages read from the server (JSON-ready).

    Returns
    -------
    dict
        ``max_repeat`` (copies of a repeated picture), ``card_mm`` (the ID-1
        card's width and height [mm]), ``default_mm_per_px`` (a CSS pixel by
        definition [mm]), ``mm_per_px_range`` (believable display scales [mm]),
        ``max_batch`` (samples in one sample message), ``max_batch_id``
        (characters of a batch id), and ``wavelet``: the audio worklet's rule
        for the surface's wavelets (``span_sigmas``, ``same_s`` [s],
        ``glide_s`` [s], ``late_sigmas``, :mod:`tactilize.synthesis.wavelets`).
    """
    return {
        "max_repeat": MAX_REPEAT,
        "card_mm": list(CARD_MM),
        "default_mm_per_px": DEFAULT_M_PER_CSS_PX * 1e3,
        "mm_per_px_range": list(MM_PER_PX_RANGE),
        "max_batch": MAX_BATCH,
        "max_batch_id": MAX_BATCH_ID,
        "wavelet": {"span_sigmas": SPAN_SIGMAS, "same_s": SAME_S, "glide_s": GLIDE_S, "late_sigmas": LATE_SIGMAS},
    }
