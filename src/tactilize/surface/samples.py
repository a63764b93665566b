"""One pen sample, in SI, and the check that it can be tracked.

Positions are metres from the picture's top-left corner with y pointing *down*
(screen coordinates, as pointers report them and as
:meth:`~tactilize.maps.texturemap.TextureMap.lookup` takes them).  Where the samples
come from (a web page's rows in CSS pixels, a tablet driver, a recording) is the
caller's business: :mod:`tactilize.web.rows` converts the page's rows.
"""

from __future__ import annotations

import math
from typing import NamedTuple

__all__ = ["PenSample", "is_trackable"]


class PenSample(NamedTuple):
    """One pen sample.

    A named tuple: a pen reports up to a thousand samples per second, and a
    tuple is the cheapest immutable record Python has.

    Attributes
    ----------
    t_s : float
        The sample's own timestamp [s] (any origin; only differences matter).
    x_m, y_m : float
        Position from the picture's top-left corner [m], y pointing down.
    pressure : float or None
        Pen pressure in [0, 1]; None when the device reports none (a mouse).
    tilt_x_deg, tilt_y_deg : float
        Pen tilt [deg] as Pointer Events report it (-90..90).
    """

    t_s: float
    x_m: float
    y_m: float
    pressure: float | None = None
    tilt_x_deg: float = 0.0
    tilt_y_deg: float = 0.0


def is_trackable(sample: PenSample) -> bool:
    """True when the sample's time and position are finite numbers.

    Pressure and tilt are not looked at: the tracker only needs where and when.
    """
    return math.isfinite(sample.t_s) and math.isfinite(sample.x_m) and math.isfinite(sample.y_m)
