"""The display's scale: how large a CSS pixel is on the screen, and which scales are believable.

One rule for the pen page (``calibrate`` messages, web/session.py) and the
experiments' calibration check (experiments/flow.py), so a scale one accepts
the other accepts too.  The page's calibrate.js applies the same bounds before
it sends.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["CARD_MM", "MM_PER_PX_RANGE", "display_scale_error"]

#: An ID-1 card (a bank card), width and height [mm] (ISO/IEC 7810): what both pages'
#: calibration matches on the screen.
CARD_MM = (85.60, 53.98)

#: Bounds on the display scale [mm per CSS px]: a CSS pixel is 0.26 mm by definition
#: (CSS Values 4, the reference pixel); outside 0.01 .. 5 mm it is a typo, not a screen.
MM_PER_PX_RANGE = (0.01, 5.0)


def display_scale_error(mm_per_px: Any) -> str | None:
    """Why ``mm_per_px`` [mm per CSS px] is not a believable display scale, or None when it is."""
    lo, hi = MM_PER_PX_RANGE
    if (
        isinstance(mm_per_px, bool)
        or not isinstance(mm_per_px, (int, float))
        or not math.isfinite(mm_per_px)
        or not lo <= mm_per_px <= hi
    ):
        return f"must be a number of {lo} .. {hi} mm per CSS px, got {mm_per_px!r}"
    return None
