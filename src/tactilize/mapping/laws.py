"""The paper's laws and their relatives, as small frozen values with a ``kind`` name.

The paper (docs/references.md, section 1 (the two laws)) drives each actuator with

    f_p = alpha(v_p) * g(f_s)        pulse frequency [Hz]
    p_w = h(i_s)                     pulse width [s]

Each law here is one role (frequency g, speed alpha, width h, amplitude,
direction) and one kind; the registry maps the TOML ``law`` key to the class.
Where the paper states a constant in other units (its alpha is in mm/s), the
parameter name says so.  Calls take SI.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

from ..errors import ProfileError, check_finite

__all__ = [
    "LinearFrequency",
    "LogFrequency",
    "SigmoidSpeed",
    "ConstantSpeed",
    "ProportionalSpeed",
    "LinearWidth",
    "InverseWidth",
    "ConstantWidth",
    "ConstantAmplitude",
    "PressureAmplitude",
    "NoDirection",
    "ProjectedSpeed",
    "PowerFrequency",
    "PowerSpeed",
    "EvenPulses",
    "PeriodicityRegularity",
    "law_from_dict",
    "law_kinds",
    "FrequencyLaw",
    "SpeedLaw",
    "WidthLaw",
    "AmplitudeLaw",
    "DirectionLaw",
    "RegularityLaw",
]


# What a Profile holds in each role (any class with these members will do; the
# ones below are registered by their TOML name).  Arguments are positional.
class _Law(Protocol):
    @property
    def kind(self) -> str: ...

    def to_dict(self) -> dict[str, Any]: ...


class FrequencyLaw(_Law, Protocol):
    """g: the image's spatial frequency [cycles/m] -> a frequency factor [Hz]."""

    def __call__(self, spatial_frequency_per_m: float, /) -> float: ...


class SpeedLaw(_Law, Protocol):
    """alpha: stroking speed [m/s] -> the factor multiplying g."""

    def __call__(self, speed_m_s: float, /) -> float: ...


class WidthLaw(_Law, Protocol):
    """h: spectral intensity in [0, 1] -> pulse width [s]."""

    def __call__(self, spectral_intensity: float, /) -> float: ...


class AmplitudeLaw(_Law, Protocol):
    """Pen pressure in [0, 1] (None: no pressure) -> amplitude in [0, 1]."""

    def __call__(self, pressure: float | None, /) -> float: ...


class DirectionLaw(_Law, Protocol):
    """The speed [m/s] that counts, from the stroke's direction and the texture's wave angle [rad]."""

    def effective_speed(self, speed_m_s: float, direction_rad: float | None, wave_angle_rad: float, /) -> float: ...


class RegularityLaw(_Law, Protocol):
    """Periodicity in [0, 1] -> the pulses' regularity (None: even pulses)."""

    def __call__(self, periodicity: float, /) -> float | None: ...


_LAWS: dict[str, dict[str, type[_LawBase]]] = {
    "frequency": {}, "speed": {}, "width": {}, "amplitude": {}, "direction": {}, "regularity": {},
}


def _law(role: str, kind: str):
    """Register a law class under its role and kind name (the TOML ``law`` key)."""

    def deco(cls):
        cls.kind = kind
        cls.role = role
        _LAWS[role][kind] = cls
        return cls

    return deco


class _LawBase:
    kind: ClassVar[str]
    role: ClassVar[str]
    #: Each coefficient's domain, as :func:`tactilize.errors.check_finite`'s bounds
    #: (``minimum``, ``above``, ``maximum``); a coefficient not named takes any finite
    #: number.  Checked when a profile loads (:func:`law_from_dict`), so a law that
    #: could only give negative or no drives is refused there, not at every drive.
    domains: ClassVar[dict[str, dict[str, float]]] = {}
    # Every law is a dataclass (its registration makes it one): what dataclasses.asdict takes.
    __dataclass_fields__: ClassVar[dict[str, Any]]

    def to_dict(self) -> dict[str, Any]:
        return {"law": self.kind, **dataclasses.asdict(self)}


@_law("frequency", "linear")
@dataclass(frozen=True)
class LinearFrequency(_LawBase):
    """Paper eq. (3): g(f_s) = k1 * f_s.  ``k1`` in Hz per (cycle/m), i.e. m/s."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"k1": {"above": 0.0}}

    k1: float = 1.0

    def __call__(self, spatial_frequency_per_m: float) -> float:
        return self.k1 * spatial_frequency_per_m


@_law("frequency", "log")
@dataclass(frozen=True)
class LogFrequency(_LawBase):
    """Paper eq. (4): g(f_s) = k2 * ln(f_s + 1), f_s in cycles/m, ``k2`` in Hz."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"k2": {"above": 0.0}}

    k2: float = 40.0

    def __call__(self, spatial_frequency_per_m: float) -> float:
        return self.k2 * math.log(spatial_frequency_per_m + 1.0)


@_law("frequency", "power")
@dataclass(frozen=True)
class PowerFrequency(_LawBase):
    """g(f_s) = scale_hz * (f_s / reference_per_m) ** exponent, f_s in cycles/m.

    With :class:`PowerSpeed` of the same exponent the product is a power of the
    temporal frequency a stylus meets, v * f_s (the perceptual preset).
    """

    domains: ClassVar[dict[str, dict[str, float]]] = {"scale_hz": {"above": 0.0}, "reference_per_m": {"above": 0.0}}

    scale_hz: float = 300.0
    reference_per_m: float = 5000.0
    exponent: float = 1.0

    def __call__(self, spatial_frequency_per_m: float) -> float:
        return self.scale_hz * (max(spatial_frequency_per_m, 0.0) / self.reference_per_m) ** self.exponent


@_law("speed", "power")
@dataclass(frozen=True)
class PowerSpeed(_LawBase):
    """alpha(v) = (v / reference_mm_s) ** exponent; the call takes m/s."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"reference_mm_s": {"above": 0.0}}

    reference_mm_s: float = 160.0
    exponent: float = 1.0

    def __call__(self, speed_m_s: float) -> float:
        return (max(speed_m_s, 0.0) * 1e3 / self.reference_mm_s) ** self.exponent


@_law("speed", "sigmoid")
@dataclass(frozen=True)
class SigmoidSpeed(_LawBase):
    """Paper eq. (7): alpha(v) = range / (1 + exp(-k5 (v - centre))) + floor.

    The paper writes v in mm/s (its centre, 60, is a pen speed in mm/s), so the
    slope and centre keep the paper's units and say so; the call takes m/s.
    """

    domains: ClassVar[dict[str, dict[str, float]]] = {"slope_per_mm_s": {"minimum": 0.0}, "centre_mm_s": {"minimum": 0.0}, "range": {"minimum": 0.0}, "floor": {"minimum": 0.0}}

    slope_per_mm_s: float = 0.05
    centre_mm_s: float = 60.0
    range: float = 2.9
    floor: float = 0.1

    def __call__(self, speed_m_s: float) -> float:
        v_mm_s = speed_m_s * 1e3
        z = -self.slope_per_mm_s * (v_mm_s - self.centre_mm_s)
        # exp overflows for absurd speeds; the sigmoid has saturated long before.
        return self.range / (1.0 + math.exp(min(z, 700.0))) + self.floor


@_law("speed", "constant")
@dataclass(frozen=True)
class ConstantSpeed(_LawBase):
    """alpha(v) = value: the frequency ignores the stroking speed."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"value": {"above": 0.0}}

    value: float = 1.0

    def __call__(self, speed_m_s: float) -> float:
        return self.value


@_law("speed", "proportional")
@dataclass(frozen=True)
class ProportionalSpeed(_LawBase):
    """alpha(v) = gain * v, v in m/s.  With g linear (k1 = 1) this is the physics of
    a stylus on a grating, f = v * f_s (docs/references.md, section 3 (stylus on a grating))."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"gain_per_m_s": {"above": 0.0}}

    gain_per_m_s: float = 1.0

    def __call__(self, speed_m_s: float) -> float:
        return self.gain_per_m_s * speed_m_s


@_law("width", "linear")
@dataclass(frozen=True)
class LinearWidth(_LawBase):
    """Paper eq. (5): p_w = (k3 * i_s + l) * unit_s.

    The paper gives k3 and l without a unit; ``unit_s`` is the time unit they are
    counted in [s] (the reasoning for the paper preset's choice is in paper.toml).
    """

    domains: ClassVar[dict[str, dict[str, float]]] = {"unit_s": {"above": 0.0}}

    k3: float = 40.0
    l: float = 0.0  # noqa: E741 - the paper's name
    unit_s: float = 1e-5

    def __call__(self, spectral_intensity: float) -> float:
        return max(0.0, (self.k3 * spectral_intensity + self.l) * self.unit_s)

    def position(self, spectral_intensity: float) -> float:
        """Where this width lies between the law's own widths at i_s = 0 and 1, in [0, 1]."""
        return _width_position(self, spectral_intensity)


@_law("width", "inverse")
@dataclass(frozen=True)
class InverseWidth(_LawBase):
    """Paper eq. (6): p_w = (c - k4 * i_s) * unit_s, the paper's c being 5."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"unit_s": {"above": 0.0}}

    k4: float = 4.0
    c: float = 5.0
    unit_s: float = 1e-5

    def __call__(self, spectral_intensity: float) -> float:
        return max(0.0, (self.c - self.k4 * spectral_intensity) * self.unit_s)

    def position(self, spectral_intensity: float) -> float:
        """Where this width lies between the law's own widths at i_s = 0 and 1, in [0, 1]."""
        return _width_position(self, spectral_intensity)


@_law("width", "constant")
@dataclass(frozen=True)
class ConstantWidth(_LawBase):
    """p_w = width_s [s] whatever the image."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"width_s": {"above": 0.0}}

    width_s: float = 3e-4

    def __call__(self, spectral_intensity: float) -> float:
        return self.width_s

    def position(self, spectral_intensity: float) -> float:
        """A constant width says nothing about strength: the middle of the band."""
        return 0.5


def _width_position(law: Any, spectral_intensity: float) -> float:
    """The width law's value at i_s as a position between its values at i_s = 0 and 1.

    This is how every preset's h reaches an actuator with a felt band: the paper's
    h = 0.4 ms * i_s gives position i_s (a stronger spectral peak, a stronger
    pulse, as the paper meant); the inverse law 5 - 4 i_s gives 1 - i_s.  A wider
    pulse is always the stronger end, whatever the law's slope.
    """
    lo, hi = sorted((law(0.0), law(1.0)))
    if hi <= lo:
        return 0.5
    i_s = min(1.0, max(0.0, spectral_intensity))
    return min(1.0, max(0.0, (law(i_s) - lo) / (hi - lo)))


@_law("amplitude", "constant")
@dataclass(frozen=True)
class ConstantAmplitude(_LawBase):
    """Amplitude (fraction of rated peak current) fixed at ``value``; the paper's H."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"value": {"above": 0.0, "maximum": 1.0}}

    value: float = 1.0

    def __call__(self, pressure: float | None) -> float:
        return self.value


@_law("amplitude", "pressure")
@dataclass(frozen=True)
class PressureAmplitude(_LawBase):
    """Amplitude rising linearly with pen pressure in [0, 1] from ``minimum`` to
    ``maximum``; ``default`` when the input reports no pressure (a mouse)."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"minimum": {"minimum": 0.0, "maximum": 1.0}, "maximum": {"minimum": 0.0, "maximum": 1.0}, "default": {"minimum": 0.0, "maximum": 1.0}}

    minimum: float = 0.4
    maximum: float = 1.0
    default: float = 1.0

    def __call__(self, pressure: float | None) -> float:
        if pressure is None:
            return self.default
        p = min(1.0, max(0.0, pressure))
        return self.minimum + (self.maximum - self.minimum) * p


@_law("direction", "none")
@dataclass(frozen=True)
class NoDirection(_LawBase):
    """The paper's law: the stroke direction does not matter."""

    def effective_speed(self, speed_m_s: float, direction_rad: float | None, wave_angle_rad: float) -> float:
        return speed_m_s


@_law("direction", "project")
@dataclass(frozen=True)
class ProjectedSpeed(_LawBase):
    """Beyond the paper: only the stroke's component along the texture's wave
    vector counts, v_eff = v * |cos(stroke - wave)| (docs/references.md, section 3 (stylus on a grating): a stylus
    on a grating feels v * f_s * |cos|).  Isotropic textures (anisotropy below
    ``min_anisotropy``) keep the full speed, since they have no direction."""

    domains: ClassVar[dict[str, dict[str, float]]] = {"min_anisotropy": {"minimum": 0.0, "maximum": 1.0}}

    min_anisotropy: float = 0.2

    def effective_speed(self, speed_m_s: float, direction_rad: float | None, wave_angle_rad: float) -> float:
        if direction_rad is None:
            return speed_m_s
        return speed_m_s * abs(math.cos(direction_rad - wave_angle_rad))


@_law("regularity", "none")
@dataclass(frozen=True)
class EvenPulses(_LawBase):
    """The paper's trains: every texture an even pulse train (regularity None)."""

    def __call__(self, periodicity: float) -> float | None:
        return None


@_law("regularity", "periodicity")
@dataclass(frozen=True)
class PeriodicityRegularity(_LawBase):
    """Regularity from the texture's ``periodicity`` (share of its AC power in the peak).

    ``(periodicity - irregular_below) / (regular_above - irregular_below)``, clipped
    to [0, 1]: a clean grating (periodicity near 1) gives an even train, a noisy
    surface (periodicity near 0) the most jitter.
    """

    domains: ClassVar[dict[str, dict[str, float]]] = {"irregular_below": {"minimum": 0.0, "maximum": 1.0}, "regular_above": {"minimum": 0.0, "maximum": 1.0}}

    irregular_below: float = 0.05
    regular_above: float = 0.5

    def __call__(self, periodicity: float) -> float | None:
        span = self.regular_above - self.irregular_below
        if span <= 0:
            return 1.0 if periodicity >= self.regular_above else 0.0
        return min(1.0, max(0.0, (periodicity - self.irregular_below) / span))


def law_kinds(role: str) -> list[str]:
    """The ``law`` names known for a role (``frequency``, ``speed``, ``width``, ``amplitude``,
    ``direction``, ``regularity``)."""
    return sorted(_LAWS[role])


def law_from_dict(role: str, data: Any, source: str):
    """A law from its TOML table: ``law`` names the kind, the other keys its coefficients."""
    if not isinstance(data, dict):
        raise ProfileError(source, f"[{role}] must be a table")
    data = dict(data)
    kind = data.pop("law", None)
    cls = _LAWS[role].get(kind)
    if cls is None:
        raise ProfileError(source, f"[{role}] law {kind!r} is unknown (known: {', '.join(law_kinds(role))})")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(data) - names
    if unknown:
        raise ProfileError(source, f"[{role}] {kind}: unknown key(s) {', '.join(sorted(unknown))}")
    values = {}
    for k, v in data.items():
        d = cls.domains.get(k, {})
        values[k] = check_finite(v, source, what=f"[{role}] {kind} {k}", error=ProfileError,
                                 minimum=d.get("minimum"), above=d.get("above"), maximum=d.get("maximum"))
    return cls(**values)
