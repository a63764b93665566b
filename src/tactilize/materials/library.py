"""The material library: what a photograph of a surface cannot show.

A picture shows where the relief is, not how deep it is, how rough it is below a
pixel or how much of it a tip follows.  The library (``library.toml`` beside this
module) says that per material; every number's source is in docs/references.md,
section 11 (material library).

Units: SI (m, Pa).
"""

from __future__ import annotations

import difflib
import functools
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

from ..errors import MaterialError

__all__ = ["Material", "library", "material", "material_names"]

_NUMBERS = ("relief_rms_m", "micro_rms_m", "micro_correlation_m", "modulus_pa", "thickness_m", "friction")


@dataclass(frozen=True)
class Material:
    """One material of the library.

    Attributes
    ----------
    name : str
        Its library name, e.g. ``"stone-granite"``.
    description : str
        In words.
    relief_rms_m : float
        RMS height of the relief its visible texture typically has [m].
    micro_rms_m : float
        RMS height of its roughness below a picture's resolution, before the tip [m].
    micro_correlation_m : float
        Correlation length of that roughness [m] (1/e of a Gaussian autocorrelation).
    modulus_pa : float
        Effective elastic modulus E* against a rigid tip [Pa].
    thickness_m : float
        Thickness of a compliant layer on a hard backing [m]; 0 for a bulk solid.
    friction : float
        Kinetic friction coefficient of a hard tip on it.
    sources : dict of str to str
        Where each value comes from (docs/references.md, section 11 (material library)).

    References
    ----------
    .. [1] docs/references.md, section 11 (material library).
    """

    name: str
    description: str
    relief_rms_m: float
    micro_rms_m: float
    micro_correlation_m: float
    modulus_pa: float
    thickness_m: float
    friction: float
    sources: dict[str, str] = field(default_factory=dict, compare=False)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "description": self.description,
                **{k: getattr(self, k) for k in _NUMBERS}, "sources": dict(self.sources)}


def _parse(name: str, row: Any, source: str) -> Material:
    if not isinstance(row, dict):
        raise MaterialError(source, f"material {name!r} must be a table")
    values: dict[str, float] = {}
    for key in _NUMBERS:
        v = row.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise MaterialError(source, f"material {name!r}: {key} must be a finite number >= 0, got {v!r}")
        values[key] = float(v)
    for key in ("micro_correlation_m", "modulus_pa"):
        if values[key] <= 0:
            raise MaterialError(source, f"material {name!r}: {key} must be > 0")
    sources = row.get("sources", {})
    if not isinstance(sources, dict):
        raise MaterialError(source, f"material {name!r}: sources must be a table")
    return Material(name, str(row.get("description", name)), **values,
                    sources={str(k): str(v) for k, v in sources.items()})


@functools.lru_cache(maxsize=1)
def library() -> dict[str, Material]:
    """Every material of the library, by name (read once)."""
    text = resources.files(__package__).joinpath("library.toml").read_text(encoding="utf-8")
    return {name: _parse(name, row, "materials/library.toml") for name, row in tomllib.loads(text).items()}


def material_names() -> list[str]:
    """The library's names, in its order."""
    return list(library())


def material(name: Any) -> Material:
    """The library's material ``name`` (a :class:`Material` is returned as it is).

    Raises
    ------
    MaterialError
        ``name`` is not in the library; the message lists the close names.
    """
    if isinstance(name, Material):
        return name
    lib = library()
    key = str(name).strip().lower()
    if key in lib:
        return lib[key]
    close = difflib.get_close_matches(key, list(lib), n=4, cutoff=0.5)
    hint = f"did you mean {', '.join(close)}?" if close else f"known: {', '.join(lib)}"
    raise MaterialError(f"material {name!r}", f"unknown material ({hint}; `tactilize materials` lists them)")
