"""The description of one SMA (NiTi) micro-wire actuator: its material, size and temperatures.

A :class:`WireSpec` is a plain, frozen value.  Everything the physics needs
(heat capacity, convective conductance, latent heat, resistances, stroke) is
derived from its fields; the driver circuit lives apart, in
:mod:`tactilize.actuators.sma.circuit`, because the same wire behaves very
differently behind a stiff and a soft source.

Units: SI (metres, seconds, ohms, joules), temperatures in degrees Celsius
(names end in ``_c``).

References
----------
docs/references.md, section 2 (material constants) for every material value.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, TypeVar

from ...errors import WireError, check_finite

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

__all__ = ["WireSpec", "wire_names", "MODEL_VERSION"]

#: Bumped whenever the physics changes, so anything cached from the model is rebuilt.
MODEL_VERSION = 3

# Temperatures may be any finite number; every other field must be > 0.
_TEMPERATURE_FIELDS = frozenset(
    ("ambient_c", "austenite_start_c", "austenite_finish_c", "martensite_start_c", "martensite_finish_c", "max_temperature_c")
)


@dataclass(frozen=True)
class WireSpec:
    """Physical description of one SMA wire actuator and the air around it.

    Parameters
    ----------
    name : str
        Label (presets: ``"50um"``, ``"75um"``, ``"100um"``).
    diameter_m : float
        Wire diameter [m]; the paper's is 75 um.
    length_m : float
        Active length [m].  Default 3 mm: a pin actuator in a pen grip is a few
        mm long, and the operating point in docs/references.md, section 2 is
        worked out for 3 mm.
    density_kg_m3, specific_heat_j_kg_k, latent_heat_j_kg : float
        6450 kg/m^3, 837 J/(kg K), 24.2 kJ/kg (datasheet values).
    resistivity_martensite_ohm_m, resistivity_austenite_ohm_m : float
        80 and 100 uOhm cm.
    convection_w_m2_k : float
        Still-air film coefficient h [W/(m^2 K)]; 190 for 75 um, scaled as
        D^-0.83 for the other presets.
    austenite_start_c, austenite_finish_c, martensite_start_c, martensite_finish_c : float
        Transformation temperatures [deg C].  The paper gives only T1 = 68 C
        (back to length) and T2 = 73 C (contracted).  Assumption: T2 is the end
        of the heating branch (A_f = 73), T1 the end of the cooling branch
        (M_f = 68), each branch 4 K wide, which leaves 1 K of thermal
        hysteresis (A_s = 69, M_s = 72).
    max_strain : float
        Recoverable strain eps_L (5 %, the paper).
    lever_gain : float
        Pin displacement per metre of wire contraction.  The paper says only
        that the pin makes the stimulus greater; 1.0 reports the wire's own
        contraction, the quantity the paper measured (about 2 um at 50 Hz).
    rated_current_a : float
        The pulse current [A] the circuit presets are sized for (0.5 A for
        75 um, the middle of the 0.3 .. 0.7 A operating range of section 2;
        scaled as D^1.085 for the other presets, which keeps the same duty since
        I^2 R duty = h pi D L dT with h ~ D^-0.83).  Only the presets of
        :class:`~tactilize.actuators.sma.circuit.Circuit` read it: the current
        that flows is always the circuit's.
    ambient_c : float
        Air temperature around the wire [deg C].
    max_temperature_c : float
        Highest temperature the safety envelope allows [deg C].  Assumption:
        90 C, 17 K above A_f, well below the 100+ C where NiTi loses its
        training.
    """

    name: str = "75um"
    diameter_m: float = 75e-6
    length_m: float = 3e-3
    density_kg_m3: float = 6450.0
    specific_heat_j_kg_k: float = 837.0
    latent_heat_j_kg: float = 24.2e3
    resistivity_martensite_ohm_m: float = 80e-8
    resistivity_austenite_ohm_m: float = 100e-8
    convection_w_m2_k: float = 190.0
    austenite_start_c: float = 69.0
    austenite_finish_c: float = 73.0
    martensite_start_c: float = 72.0
    martensite_finish_c: float = 68.0
    max_strain: float = 0.05
    lever_gain: float = 1.0
    rated_current_a: float = 0.5
    ambient_c: float = 25.0
    max_temperature_c: float = 90.0

    def __post_init__(self) -> None:
        src = f"<wire {self.name}>"
        for f in dataclasses.fields(self):
            if f.name == "name":
                continue
            above = None if f.name in _TEMPERATURE_FIELDS else 0.0
            check_finite(getattr(self, f.name), src, what=f.name, error=WireError, above=above)
        if not (self.austenite_start_c < self.austenite_finish_c and self.martensite_finish_c < self.martensite_start_c):
            raise WireError(src, "need A_s < A_f and M_f < M_s")
        # The restart curves divide by how much of a branch is left at the reversal
        # point; these orderings keep that bounded away from zero.
        if not (self.martensite_finish_c < self.austenite_start_c and self.martensite_start_c < self.austenite_finish_c):
            raise WireError(src, "need M_f < A_s and M_s < A_f")
        if not self.max_strain < 1:
            raise WireError(src, "max_strain must be < 1")
        if not self.max_temperature_c > self.austenite_finish_c:
            raise WireError(src, "max_temperature_c must be above A_f")
        if not self.ambient_c < self.martensite_finish_c:
            raise WireError(src, "ambient_c must be below M_f (the wire must be able to relax)")

    # -- presets

    @classmethod
    def preset(cls, name: str, length_m: float | None = None, **changes: Any) -> "WireSpec":
        """A preset wire by name (``"50um"``, ``"75um"``, ``"100um"``), optionally changed."""
        key = str(name).strip().lower().replace("µ", "u")
        if key not in _PRESETS:
            raise WireError(str(name), f"no such wire (known: {', '.join(wire_names())})")
        spec = _PRESETS[key]
        if length_m is not None:
            changes["length_m"] = length_m
        return changed_preset(spec, name, changes)

    @classmethod
    def resolve(cls, wire: "WireSpec | str | None") -> "WireSpec":
        """A :class:`WireSpec` from a spec, a preset name, or None (the paper's 75 um)."""
        if wire is None:
            return _PRESETS["75um"]
        if isinstance(wire, WireSpec):
            return wire
        return cls.preset(wire)

    def replace(self, **changes: Any) -> "WireSpec":
        return dataclasses.replace(self, **changes)

    # -- derived quantities (SI); cached, since the controller reads them per pulse

    @cached_property
    def cross_section_m2(self) -> float:
        return math.pi * self.diameter_m**2 / 4

    @cached_property
    def volume_m3(self) -> float:
        return self.cross_section_m2 * self.length_m

    @cached_property
    def surface_m2(self) -> float:
        """Lateral surface [m^2] (the ends are clamped, not cooled by air)."""
        return math.pi * self.diameter_m * self.length_m

    @cached_property
    def heat_capacity_j_k(self) -> float:
        """rho c V [J/K]."""
        return self.density_kg_m3 * self.specific_heat_j_kg_k * self.volume_m3

    @cached_property
    def conductance_w_k(self) -> float:
        """h A_s [W/K]."""
        return self.convection_w_m2_k * self.surface_m2

    @cached_property
    def latent_j(self) -> float:
        """rho V L_h [J]: heat absorbed by a full martensite -> austenite transformation."""
        return self.density_kg_m3 * self.volume_m3 * self.latent_heat_j_kg

    @cached_property
    def time_constant_s(self) -> float:
        """Thermal time constant rho c V / (h A_s) [s] outside the transformation band."""
        return self.heat_capacity_j_k / self.conductance_w_k

    @cached_property
    def resistance_martensite_ohm(self) -> float:
        """Resistance of the relaxed (all martensite) wire [ohm]."""
        return self.resistivity_martensite_ohm_m * self.length_m / self.cross_section_m2

    @cached_property
    def resistance_austenite_ohm(self) -> float:
        """Resistance of the contracted (all austenite) wire [ohm]."""
        return self.resistivity_austenite_ohm_m * self.length_m / self.cross_section_m2

    def resistance_at(self, martensite_fraction: Any) -> Any:
        """Resistance [ohm] at a martensite fraction (linear mix of the two phases).

        The model has no separate temperature coefficient: across the 5 K band
        the phase change (about 25 %) dwarfs it, which is what makes the
        resistance a sensor of the phase (docs/references.md, section 8).
        """
        RA = self.resistance_austenite_ohm
        return RA + (self.resistance_martensite_ohm - RA) * martensite_fraction

    def martensite_from_resistance(self, resistance_ohm: float) -> float:
        """The martensite fraction a measured resistance [ohm] means, clipped to [0, 1]."""
        RA, RM = self.resistance_austenite_ohm, self.resistance_martensite_ohm
        return min(1.0, max(0.0, (RA - resistance_ohm) / (RA - RM)))

    @cached_property
    def stroke_m(self) -> float:
        """Pin displacement [m] of a full transformation: gain * L * eps_L."""
        return self.lever_gain * self.length_m * self.max_strain

    def displacement_m(self, martensite_fraction: Any) -> Any:
        """Pin displacement [m] (0 when relaxed): gain * L * eps_L * (1 - xi)."""
        return self.stroke_m * (1.0 - martensite_fraction)

    def heating_fraction(self, temperature_c: float) -> float:
        """Martensite fraction on the major heating curve at a temperature [deg C]."""
        As, Af = self.austenite_start_c, self.austenite_finish_c
        if temperature_c <= As:
            return 1.0
        if temperature_c >= Af:
            return 0.0
        return 0.5 * (1 + math.cos(math.pi * (temperature_c - As) / (Af - As)))

    def heating_temperature_c(self, martensite_fraction: float) -> float:
        """Temperature [deg C] on the major heating curve at a martensite fraction in [0, 1]."""
        xi = min(1.0, max(0.0, martensite_fraction))
        As, Af = self.austenite_start_c, self.austenite_finish_c
        return As + (Af - As) / math.pi * math.acos(2 * xi - 1)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def key(self) -> str:
        """A short hash of every field and the model version (a cache key)."""
        text = json.dumps({"v": MODEL_VERSION, **self.to_dict()}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _scaled_preset(name: str, diameter_m: float) -> WireSpec:
    ratio = diameter_m / 75e-6
    # h ~ D^-0.83; current for the same duty ~ D^((3 - 0.83)/2) (docs/references.md, section 2).
    return WireSpec(
        name=name,
        diameter_m=diameter_m,
        convection_w_m2_k=190.0 * ratio**-0.83,
        rated_current_a=0.5 * ratio ** ((3 - 0.83) / 2),
    )


_PRESETS: dict[str, WireSpec] = {
    "50um": _scaled_preset("50um", 50e-6),
    "75um": WireSpec(),
    "100um": _scaled_preset("100um", 100e-6),
}


_Preset = TypeVar("_Preset", bound="DataclassInstance")


def changed_preset(preset: _Preset, name: str, changes: dict[str, Any]) -> _Preset:
    """The preset ``name`` (a dataclass: a wire or a circuit) with ``changes`` made; a field it
    does not have is a :class:`WireError` naming the preset."""
    if not changes:
        return preset
    try:
        return dataclasses.replace(preset, **changes)
    except TypeError as exc:
        raise WireError(str(name), str(exc)) from None


def wire_names() -> list[str]:
    """Names of the preset wires."""
    return list(_PRESETS)
