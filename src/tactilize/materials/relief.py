"""Heights in metres: a picture's relief scale, and what a tip of a material follows.

A picture's luminance is a height proxy with no unit (docs/references.md, section 3
(luminance as height)).  :class:`Relief` says how many metres of relief the full
luminance range is (the *relief scale*), where that came from (``"given"``,
``"material"`` or ``"estimate"``), and, with a material, how much of it and of the
material's micro-roughness a tip of a given radius follows under a light force
(its *hardness*): the contact's footprint low-passes the relief like the tip does
(docs/references.md, section 11 (hardness)).

From a material the scale makes the picture's visible structure (its luminance
with the lighting's slow variation taken out) have the material's typical RMS
relief (docs/references.md, section 11 (relief scale)); the lighting does not
change how deep the relief is, only the picture's share of it.

Units: SI (m, N, Pa, m/s^2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import MaterialError, check_finite
from .library import Material, material
from .roughness import MicroRoughness
from .threshold import LEAST_FELT_PROMINENCE_M

__all__ = ["Relief", "relief_for", "contact_radius_m", "follow_share", "visible_relief_std", "LIGHT_FORCE_N",
           "LIGHTING_SCALE_M", "ESTIMATED_RELIEF_RMS_M", "FULL_SCALE_ACCELERATION_M_S2", "FULL_PROMINENCE_M",
           "PROMINENCE_SHARE_OF_STD"]

#: Force of a light stylus stroke [N]: this project's assumption (docs/references.md,
#: section 11 (hardness)).
LIGHT_FORCE_N = 0.5
#: Luminance varying more slowly than this on the surface [m] is taken for lighting
#: (vignetting, a gradient), not relief, when the picture's visible relief is measured:
#: this project's assumption (docs/references.md, section 11 (relief scale)).
LIGHTING_SCALE_M = 5e-3
#: RMS of the visible relief assumed when no material or scale is given but metres are
#: asked for: the median of the library's relief_rms_m, an estimate (same section).
ESTIMATED_RELIEF_RMS_M = 20e-6
#: Acceleration played at full scale [m/s^2] for a surface in metres (voice coil, WAV):
#: this project's choice (docs/references.md, section 11 (full scale in acceleration)).
FULL_SCALE_ACCELERATION_M_S2 = 100.0
#: Prominence [m] that gets full strength on a surface in metres (same section).
FULL_PROMINENCE_M = 0.2e-3
#: The prominence floor's share of the height's standard deviation, as for pictures
#: (docs/surfaces.md, "What is rendered").
PROMINENCE_SHARE_OF_STD = 0.2
#: Least luminance deviation taken as the picture's visible relief (one grey level of
#: eight-bit): a uniform picture is flat, not infinitely deep.
_LEAST_STD = 1.0 / 255.0


def contact_radius_m(material: Material, tip_radius_m: float, force_n: float = LIGHT_FORCE_N) -> float:
    """Radius [m] of a rigid spherical tip's contact on ``material`` under ``force_n`` [N].

    Hertz's a = (3 F R / (4 E*))^(1/3); on a compliant layer of thickness t on a hard
    backing the tip cannot sink deeper than the layer, which bounds a by sqrt(R t)
    (indentation a^2 / R).  docs/references.md, section 11 (hardness).
    """
    a = (3.0 * force_n * tip_radius_m / (4.0 * material.modulus_pa)) ** (1.0 / 3.0)
    if material.thickness_m > 0:
        a = min(a, math.sqrt(tip_radius_m * material.thickness_m))
    return a


def follow_share(material: Material, tip_radius_m: float, force_n: float = LIGHT_FORCE_N) -> float:
    """Share of a compliant layer's relief a tip follows under ``force_n`` [N] (1 on a bulk solid).

    The tip would sink delta = a^2 / R into the material (Hertz, unbounded); a layer of
    thickness t compressed by the tip loses relief in proportion, 1 / (1 + delta / t):
    this project's model, docs/references.md, section 11 (hardness).  A knit's ribs, a
    fleece's pile are swallowed; a sheet of paper keeps about half.
    """
    if material.thickness_m <= 0:
        return 1.0
    a = (3.0 * force_n * tip_radius_m / (4.0 * material.modulus_pa)) ** (1.0 / 3.0)
    return 1.0 / (1.0 + a * a / tip_radius_m / material.thickness_m)


def visible_relief_std(raw: np.ndarray, surface_pitch_m: tuple[float, float]) -> float:
    """Standard deviation of a picture's luminance once variations slower than
    :data:`LIGHTING_SCALE_M` are taken out [luminance units], at least one grey level."""
    from scipy.ndimage import gaussian_filter

    a = np.asarray(raw, dtype=np.float64)
    sigma_px = (LIGHTING_SCALE_M / surface_pitch_m[1], LIGHTING_SCALE_M / surface_pitch_m[0])
    high = a - gaussian_filter(a, sigma_px, mode="reflect")
    return max(float(np.std(high)), _LEAST_STD)


@dataclass(frozen=True)
class Relief:
    """A picture's relief in metres, and the material it is made of (if known).

    Attributes
    ----------
    scale_m : float
        Metres of relief per unit of luminance (the full 0 .. 1 range).
    source : {"given", "material", "estimate"}
        Where the scale came from.
    material : Material or None
        The material; None when only a scale is known (a hard surface, no micro-roughness).
    """

    scale_m: float
    source: str
    material: Material | None = None

    def height_scale_m(self, tip_radius_m: float) -> float:
        """Metres of followed relief per unit of luminance: the scale times the share a tip
        of ``tip_radius_m`` [m] follows on the material (:func:`follow_share`)."""
        return self.scale_m * (1.0 if self.material is None else follow_share(self.material, tip_radius_m))

    def footprint_sigma_m(self, tip_radius_m: float) -> float:
        """Standard deviation [m] of the Gaussian low-pass of tip and contact: half the
        tip's radius (docs/references.md, section 3 (stylus tip)) and half the
        contact's radius on the material, added in quadrature."""
        tip = 0.5 * tip_radius_m
        if self.material is None:
            return tip
        return math.hypot(tip, 0.5 * contact_radius_m(self.material, tip_radius_m))

    def micro(self, tip_radius_m: float) -> MicroRoughness | None:
        """The material's micro-roughness as a tip of ``tip_radius_m`` [m] follows it."""
        m = self.material
        if m is None or m.micro_rms_m <= 0:
            return None
        return MicroRoughness.of(m.name, m.micro_rms_m * follow_share(m, tip_radius_m), m.micro_correlation_m,
                                 self.footprint_sigma_m(tip_radius_m))

    def prominence_floor_m(self, height_std_m: float) -> float:
        """Least prominence of a bump [m]: the least felt at any speed
        (:data:`~tactilize.materials.threshold.LEAST_FELT_PROMINENCE_M`), or a share of the
        height's standard deviation when that is larger (as for pictures)."""
        return max(LEAST_FELT_PROMINENCE_M, PROMINENCE_SHARE_OF_STD * height_std_m)

    def describe(self) -> dict[str, Any]:
        return {"material": None if self.material is None else self.material.name,
                "relief_scale_m": self.scale_m, "relief_source": self.source}


def relief_for(raw: Any, surface_pitch_m: tuple[float, float], material_name: Any = None,
               relief_scale_m: float | str | None = None, relief_rms_m: float | None = None) -> Relief | None:
    """The relief of a picture: from a given scale, a given RMS relief, a material, or an estimate.

    Parameters
    ----------
    raw : ndarray
        The picture's luminance [0 .. 1].
    surface_pitch_m : (float, float)
        Real size of a pixel (x, y) [m].
    material_name : str or Material, optional
        A library material (:func:`~tactilize.materials.library.material`).
    relief_scale_m : float or "estimate", optional
        Metres of relief per unit of luminance, given; ``"estimate"`` for this
        project's estimate (:data:`ESTIMATED_RELIEF_RMS_M`).  A given scale wins over
        the material's typical relief; the material's hardness and roughness stay.
    relief_rms_m : float, optional
        RMS height of the picture's visible relief [m], given: the scale that gives the
        picture's visible structure this RMS, as a material's typical relief does (it
        replaces the material's; its hardness and roughness stay).  Not with
        ``relief_scale_m``.

    Returns
    -------
    Relief or None
        None when neither is given: the picture alone, heights in luminance units.

    Raises
    ------
    MaterialError
        An unknown material, a scale or RMS that is not a positive finite number, or both
        a scale and an RMS.
    """
    mat = None if material_name is None else material(material_name)
    if relief_rms_m is not None:
        if relief_scale_m is not None:
            raise MaterialError("relief", "give a relief scale or a relief RMS, not both")
        rms = check_finite(relief_rms_m, "relief RMS", error=MaterialError, above=0.0, unit="m")
        return Relief(float(rms) / visible_relief_std(raw, surface_pitch_m), "given", mat)
    if relief_scale_m is None and mat is None:
        return None
    if isinstance(relief_scale_m, str):
        if relief_scale_m != "estimate":
            raise MaterialError("relief scale", f"a number of metres or 'estimate', got {relief_scale_m!r}")
        return Relief(ESTIMATED_RELIEF_RMS_M / visible_relief_std(raw, surface_pitch_m), "estimate", mat)
    if relief_scale_m is not None:
        scale = check_finite(relief_scale_m, "relief scale", error=MaterialError, above=0.0, unit="m")
        return Relief(float(scale), "given", mat)
    assert mat is not None
    return Relief(mat.relief_rms_m / visible_relief_std(raw, surface_pitch_m), "material", mat)
