"""What a picture is rendered as: picture only, or a material and its relief.

The surface commands (``--material``, ``--relief-mm``), the pen server (its default
and the page's picker) and the catalogue's ``material`` column all name a
rendering the same way; :class:`MaterialChoice` holds it, checks it once, gives
:func:`~tactilize.surface.surface_model` its arguments and says it in words
("picture only", "fabric-knit (relief 30 um RMS, ...)").

Units: SI (m, Pa).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import MaterialError, check_finite
from .library import Material, material

__all__ = ["MaterialChoice", "PICTURE_ONLY", "length_text"]

#: The page's and the catalogue's words for "no material".
PICTURE_ONLY = "picture only"


def length_text(m: float) -> str:
    """A length [m] as a person reads it: mm from 0.1 mm, um from 0.1 um, nm below."""
    if m >= 0.1e-3:
        return f"{m * 1e3:.3g} mm"
    if m >= 0.1e-6:
        return f"{m * 1e6:.3g} um"
    return f"{m * 1e9:.3g} nm"


@dataclass(frozen=True)
class MaterialChoice:
    """How a picture's surface is rendered.

    Attributes
    ----------
    material : Material or None
        The library material (None: no material).
    relief_rms_m : float or None
        RMS height of the picture's visible relief [m], given; None: the material's
        typical relief (or, without a material, the picture alone).
    """

    material: Material | None = None
    relief_rms_m: float | None = None

    @classmethod
    def of(cls, material_name: Any = None, relief_rms_m: float | None = None) -> MaterialChoice:
        """A checked choice; ``material_name`` None, ``""`` or ``"picture only"`` is no material.

        Raises
        ------
        MaterialError
            An unknown material (the message names it and close names), or a relief RMS
            that is not a positive finite number.
        """
        mat = None
        if isinstance(material_name, Material):
            mat = material_name
        elif material_name is not None and str(material_name).strip().lower() not in ("", PICTURE_ONLY):
            mat = material(material_name)
        rms = None
        if relief_rms_m is not None:
            rms = float(check_finite(relief_rms_m, "relief RMS", error=MaterialError, above=0.0, unit="m"))
        return cls(mat, rms)

    @property
    def name(self) -> str | None:
        """The material's name, or None."""
        return None if self.material is None else self.material.name

    @property
    def picture_only(self) -> bool:
        """Neither a material nor a relief: heights in luminance units, as the picture has them."""
        return self.material is None and self.relief_rms_m is None

    def surface_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of :func:`~tactilize.surface.surface_model` for this choice."""
        return {"material": self.material, "relief_rms_m": self.relief_rms_m}

    def label(self) -> str:
        """In words: ``"picture only"``, or the material with its relief, micro-roughness and
        modulus, e.g. ``"fabric-knit (relief 30 um RMS, micro-roughness 10 um, E* 50 kPa)"``."""
        if self.picture_only:
            return PICTURE_ONLY
        m = self.material
        if m is None:
            assert self.relief_rms_m is not None
            return f"picture with relief {length_text(self.relief_rms_m)} RMS (given)"
        rms = m.relief_rms_m if self.relief_rms_m is None else self.relief_rms_m
        given = "" if self.relief_rms_m is None else " given"
        return (f"{m.name} (relief {length_text(rms)} RMS{given}, micro-roughness {length_text(m.micro_rms_m)}, "
                f"E* {_pressure_text(m.modulus_pa)})")

    def to_dict(self) -> dict[str, Any]:
        """``material`` (name or None), ``relief_rms_m`` [m] (given, or None) and ``rendered_as``."""
        return {"material": self.name, "relief_rms_m": self.relief_rms_m, "rendered_as": self.label()}


def _pressure_text(pa: float) -> str:
    for unit, scale in (("GPa", 1e9), ("MPa", 1e6), ("kPa", 1e3)):
        if pa >= scale:
            return f"{pa / scale:.3g} {unit}"
    return f"{pa:.3g} Pa"
