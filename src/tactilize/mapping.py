"""The laws that turn texture features and stroking speed into pulse drives.

The paper (docs/references.md, section 1 (the two laws)) drives each actuator with

    f_p = alpha(v_p) * g(f_s)        pulse frequency [Hz]
    p_w = h(i_s)                     pulse width [s]

where ``f_s`` is the image's dominant spatial frequency [cycles/m], ``i_s`` its
spectral intensity in [0, 1] and ``v_p`` the pen's speed.  Each law is a small
frozen dataclass with a ``kind`` name; a :class:`Profile` composes one of each
(plus an amplitude law, an optional direction law and the actuator limits it was
tuned for) and is stored as a TOML file.  Presets ship in ``tactilize/profiles``.

Everything here is SI: speeds in m/s, frequencies in Hz, widths in s.  Where the
paper states a constant in other units (its alpha is written in mm/s), the
parameter name says so.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar, Protocol

from .errors import DriveError, ProfileError

__all__ = [
    "Drive",
    "ActuatorLimits",
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
    "Profile",
    "preset_names",
]


# --------------------------------------------------------------------------- drive


@dataclass(frozen=True)
class Drive:
    """One actuator's pulse drive.

    Parameters
    ----------
    pulse_frequency_hz : float
        Pulse repetition frequency [Hz].  0 means the actuator is off.
    pulse_width_s : float
        Width of each pulse [s].
    amplitude : float
        Pulse height as a fraction of the actuator's rated peak current (the
        paper's H), in [0, 1].  The paper keeps H fixed (two AA cells), so 1.0.
    clamped : tuple of str
        Names of the limits that changed this drive on its way here
        (e.g. ``"max_frequency_hz"``, ``"max_duty_ratio"``, ``"envelope"``);
        empty when the laws' result went through untouched.
    strength : float or None
        Where the profile's width law puts this texture between its weakest and
        strongest, in [0, 1] (:meth:`Profile.drive` sets it).  An actuator with a
        narrow felt band (the SMA wire) plays this position inside its band
        rather than the absolute width, which could fall outside it.  None: a
        hand-made drive; such outputs then place it by its own heat.

    Notes
    -----
    ``duty_ratio`` (the paper's W/L) is derived, never stored, so it cannot
    disagree with frequency and width.
    """

    pulse_frequency_hz: float
    pulse_width_s: float
    amplitude: float = 1.0
    clamped: tuple[str, ...] = ()
    strength: float | None = None

    def __post_init__(self) -> None:
        # Drives are made for every pen batch: one chained comparison is the fast
        # path (NaN fails it, so does infinity); the slow path says what is wrong.
        try:
            ok = (
                0.0 <= self.pulse_frequency_hz < math.inf
                and 0.0 <= self.pulse_width_s < math.inf
                and 0.0 <= self.amplitude <= 1.0
                and not isinstance(self.pulse_frequency_hz, bool)
            )
        except TypeError:
            ok = False
        if not ok:
            self._explain()
        if self.strength is not None and not (0.0 <= self.strength <= 1.0):
            raise DriveError("<drive>", f"strength must be in [0, 1] or None, got {self.strength!r}")
        if type(self.clamped) is not tuple:
            # Accept any iterable of names but store an immutable tuple (hashable, comparable).
            object.__setattr__(self, "clamped", tuple(self.clamped))

    def _explain(self) -> None:
        for name in ("pulse_frequency_hz", "pulse_width_s", "amplitude"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value) or value < 0:
                raise DriveError("<drive>", f"{name} must be a finite number >= 0, got {value!r}")
        raise DriveError("<drive>", f"amplitude must be in [0, 1], got {self.amplitude!r}")

    @classmethod
    def _trusted(
        cls,
        pulse_frequency_hz: float,
        pulse_width_s: float,
        amplitude: float,
        clamped: tuple[str, ...],
        strength: float | None = None,
    ) -> "Drive":
        """A Drive from values already known to be valid (finite, >= 0,
        amplitude <= 1, ``clamped`` a tuple), without ``__init__``'s checks.

        For the limits and envelopes that clamp a valid drive into a valid
        range: they run for every pen batch, and a checked frozen dataclass
        costs several times more to build.
        """
        d = object.__new__(cls)
        d.__dict__.update(
            pulse_frequency_hz=pulse_frequency_hz,
            pulse_width_s=pulse_width_s,
            amplitude=amplitude,
            clamped=clamped,
            strength=strength,
        )
        return d

    @classmethod
    def off(cls, clamped: tuple[str, ...] = ()) -> "Drive":
        """A drive that keeps the actuator off."""
        return cls(0.0, 0.0, 0.0, clamped)

    @property
    def is_off(self) -> bool:
        """True when the drive produces no pulses."""
        return self.pulse_frequency_hz <= 0 or self.pulse_width_s <= 0 or self.amplitude <= 0

    @property
    def duty_ratio(self) -> float:
        """Fraction of time the current is on, W/L = f_p * p_w (dimensionless)."""
        return self.pulse_frequency_hz * self.pulse_width_s

    @property
    def period_s(self) -> float:
        """Pulse period [s]; ``inf`` when off."""
        return 1.0 / self.pulse_frequency_hz if self.pulse_frequency_hz > 0 else math.inf

    def replace(self, **changes: Any) -> "Drive":
        """A copy with some fields changed (validated like any new Drive)."""
        # Spelled out rather than dataclasses.replace: this runs for every pen batch.
        return Drive(
            changes.pop("pulse_frequency_hz", self.pulse_frequency_hz),
            changes.pop("pulse_width_s", self.pulse_width_s),
            changes.pop("amplitude", self.amplitude),
            changes.pop("clamped", self.clamped),
            changes.pop("strength", self.strength),
            **changes,
        )

    def with_clamp(self, name: str, **changes: Any) -> "Drive":
        """A copy with fields changed and ``name`` appended to :attr:`clamped`."""
        clamped = self.clamped if name in self.clamped else self.clamped + (name,)
        return self.replace(clamped=clamped, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready mapping (SI units, plus ``pulse_width_ms`` for display)."""
        return {
            "pulse_frequency_hz": self.pulse_frequency_hz,
            "pulse_width_s": self.pulse_width_s,
            "pulse_width_ms": self.pulse_width_s * 1e3,
            "duty_ratio": self.duty_ratio,
            "amplitude": self.amplitude,
            "clamped": list(self.clamped),
            "strength": self.strength,
        }


@dataclass(frozen=True)
class ActuatorLimits:
    """The operating limits of an actuator, applied to every drive with a record.

    Parameters
    ----------
    name : str
        Which actuator these limits describe.
    min_frequency_hz, max_frequency_hz : float
        Pulse frequency band [Hz].  A positive request below the band is raised
        to ``min_frequency_hz``; 0 stays 0 (off).
    min_pulse_width_s, max_pulse_width_s : float
        Pulse-width range [s].
    max_duty_ratio : float
        Largest f_p * p_w; above it the width is shortened.
    """

    name: str = "sma-75um-pen"
    min_frequency_hz: float = 1.0
    # The paper: "vibration up to 300 Hz is generated" by the pin actuator.
    max_frequency_hz: float = 300.0
    # Shorter pulses than a few tens of microseconds do not heat a 75 um wire
    # measurably (docs/references.md, section 2 (operating point): 1 ms at 0.42 A gives ~1.7 K).
    min_pulse_width_s: float = 20e-6
    max_pulse_width_s: float = 2e-3
    # docs/references.md, section 2 (duty ratio in practice): SMA micro-vibration is driven at duty ratios of a few
    # per cent; above ~10 % the mean temperature leaves the transformation band.
    max_duty_ratio: float = 0.10

    def __post_init__(self) -> None:
        values = dataclasses.asdict(self)
        values.pop("name")
        for key, value in values.items():
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ProfileError(f"<actuator {self.name}>", f"{key} must be a finite number >= 0")
        if self.min_frequency_hz > self.max_frequency_hz:
            raise ProfileError(f"<actuator {self.name}>", "min_frequency_hz exceeds max_frequency_hz")
        if self.min_pulse_width_s > self.max_pulse_width_s:
            raise ProfileError(f"<actuator {self.name}>", "min_pulse_width_s exceeds max_pulse_width_s")
        if not 0 < self.max_duty_ratio <= 1:
            raise ProfileError(f"<actuator {self.name}>", "max_duty_ratio must be in (0, 1]")

    def apply(self, drive: Drive) -> Drive:
        """Clamp a drive into these limits, naming each limit that changed it."""
        if drive.is_off:
            return drive
        # The clamped values first, then one Drive (this runs for every pen batch).
        f, w, clamped = drive.pulse_frequency_hz, drive.pulse_width_s, drive.clamped
        names: list[str] = []
        if f > self.max_frequency_hz:
            f = self.max_frequency_hz
            names.append("max_frequency_hz")
        elif f < self.min_frequency_hz:
            f = self.min_frequency_hz
            names.append("min_frequency_hz")
        if w > self.max_pulse_width_s:
            w = self.max_pulse_width_s
            names.append("max_pulse_width_s")
        elif w < self.min_pulse_width_s:
            w = self.min_pulse_width_s
            names.append("min_pulse_width_s")
        # Relative tolerance: a width computed as max_duty / f must not re-trigger.
        if f * w > self.max_duty_ratio * (1 + 1e-12):
            w = self.max_duty_ratio / f
            names.append("max_duty_ratio")
        if not names:
            return drive
        for name in names:
            if name not in clamped:
                clamped = clamped + (name,)
        # Every value is the valid drive's own or a limit (checked finite, >= 0).
        return Drive._trusted(f, w, drive.amplitude, clamped, drive.strength)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


# --------------------------------------------------------------------------- laws

_LAWS: dict[str, dict[str, type]] = {"frequency": {}, "speed": {}, "width": {}, "amplitude": {}, "direction": {}}


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

    def to_dict(self) -> dict[str, Any]:
        return {"law": self.kind, **dataclasses.asdict(self)}


class FrequencyLaw(Protocol):
    def __call__(self, spatial_frequency_per_m: float) -> float: ...


@_law("frequency", "linear")
@dataclass(frozen=True)
class LinearFrequency(_LawBase):
    """Paper eq. (3): g(f_s) = k1 * f_s.  ``k1`` in Hz per (cycle/m), i.e. m/s."""

    k1: float = 1.0

    def __call__(self, spatial_frequency_per_m: float) -> float:
        return self.k1 * spatial_frequency_per_m


@_law("frequency", "log")
@dataclass(frozen=True)
class LogFrequency(_LawBase):
    """Paper eq. (4): g(f_s) = k2 * ln(f_s + 1), f_s in cycles/m, ``k2`` in Hz."""

    k2: float = 40.0

    def __call__(self, spatial_frequency_per_m: float) -> float:
        return self.k2 * math.log(spatial_frequency_per_m + 1.0)


@_law("speed", "sigmoid")
@dataclass(frozen=True)
class SigmoidSpeed(_LawBase):
    """Paper eq. (7): alpha(v) = range / (1 + exp(-k5 (v - centre))) + floor.

    The paper writes v in mm/s (its centre, 60, is a pen speed in mm/s), so the
    slope and centre keep the paper's units and say so; the call takes m/s.
    """

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

    value: float = 1.0

    def __call__(self, speed_m_s: float) -> float:
        return self.value


@_law("speed", "proportional")
@dataclass(frozen=True)
class ProportionalSpeed(_LawBase):
    """alpha(v) = gain * v, v in m/s.  With g linear (k1 = 1) this is the physics of
    a stylus on a grating, f = v * f_s (docs/references.md, section 3 (stylus on a grating))."""

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

    value: float = 1.0

    def __call__(self, pressure: float | None) -> float:
        return self.value


@_law("amplitude", "pressure")
@dataclass(frozen=True)
class PressureAmplitude(_LawBase):
    """Amplitude rising linearly with pen pressure in [0, 1] from ``minimum`` to
    ``maximum``; ``default`` when the input reports no pressure (a mouse)."""

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

    min_anisotropy: float = 0.2

    def effective_speed(self, speed_m_s: float, direction_rad: float | None, wave_angle_rad: float) -> float:
        if direction_rad is None:
            return speed_m_s
        return speed_m_s * abs(math.cos(direction_rad - wave_angle_rad))


def _law_from_dict(role: str, data: Any, source: str):
    if not isinstance(data, dict):
        raise ProfileError(source, f"[{role}] must be a table")
    data = dict(data)
    kind = data.pop("law", None)
    cls = _LAWS[role].get(kind)
    if cls is None:
        known = ", ".join(sorted(_LAWS[role]))
        raise ProfileError(source, f"[{role}] law {kind!r} is unknown (known: {known})")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(data) - names
    if unknown:
        raise ProfileError(source, f"[{role}] {kind}: unknown key(s) {', '.join(sorted(unknown))}")
    for key, value in data.items():
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
            raise ProfileError(source, f"[{role}] {key} must be a finite number, got {value!r}")
    return cls(**{k: float(v) for k, v in data.items()})


# --------------------------------------------------------------------------- profile


@dataclass(frozen=True)
class Profile:
    """A complete mapping from texture features and stroke to a :class:`Drive`.

    Use :meth:`preset`, :meth:`load` or build one from law objects.  A profile is
    pure: :meth:`drive` has no side effects and keeps no state.
    """

    name: str = "custom"
    frequency: Any = field(default_factory=LogFrequency)
    speed: Any = field(default_factory=SigmoidSpeed)
    width: Any = field(default_factory=LinearWidth)
    amplitude: Any = field(default_factory=ConstantAmplitude)
    direction: Any = field(default_factory=NoDirection)
    limits: ActuatorLimits = field(default_factory=ActuatorLimits)
    description: str = ""

    # -- the laws

    def drive(
        self,
        features: Any,
        speed_m_s: float,
        direction_rad: float | None = None,
        pressure: float | None = None,
        *,
        limits: ActuatorLimits | None = None,
    ) -> Drive:
        """The drive for a texture stroked at a given speed.

        Parameters
        ----------
        features : TextureFeatures
            Anything with ``spatial_frequency_per_m`` [cycles/m],
            ``spectral_intensity`` in [0, 1] and ``orientation_deg`` [deg].
        speed_m_s : float
            Stroking speed [m/s], >= 0.
        direction_rad : float, optional
            Stroke direction [rad], counter-clockwise from the image's +x axis
            with y pointing up (the same frame as ``orientation_deg``).
        pressure : float, optional
            Pen pressure in [0, 1]; None when the input has none.
        limits : ActuatorLimits, optional
            Overrides the profile's own actuator limits.

        Returns
        -------
        Drive
            Clamped into the limits; ``clamped`` names every limit that acted.
        """
        if not isinstance(speed_m_s, (int, float)) or not math.isfinite(speed_m_s) or speed_m_s < 0:
            raise DriveError("<speed>", f"speed must be a finite number >= 0 m/s, got {speed_m_s!r}")
        if direction_rad is not None and not math.isfinite(direction_rad):
            raise DriveError("<direction>", f"direction must be finite, got {direction_rad!r}")
        if pressure is not None and not math.isfinite(pressure):
            raise DriveError("<pressure>", f"pressure must be finite, got {pressure!r}")
        f_s = float(features.spatial_frequency_per_m)
        i_s = float(features.spectral_intensity)
        if f_s <= 0:
            # No periodic content: nothing to render (g would give 0 Hz anyway
            # for the log law, and a linear law must not be asked to guess).
            return Drive.off()
        wave_angle = math.radians(float(getattr(features, "orientation_deg", 0.0)))
        v = speed_m_s
        if getattr(features, "anisotropy", 1.0) >= getattr(self.direction, "min_anisotropy", 0.0):
            v = self.direction.effective_speed(speed_m_s, direction_rad, wave_angle)
        f_p = self.speed(v) * self.frequency(f_s)
        p_w = self.width(i_s)
        amp = min(1.0, max(0.0, self.amplitude(pressure)))
        if f_p <= 0 or p_w <= 0 or amp <= 0:
            return Drive.off()
        position = getattr(self.width, "position", None)
        strength = position(i_s) if position is not None else None
        return (limits or self.limits).apply(Drive(f_p, p_w, amp, (), strength))

    # -- storage

    @classmethod
    def preset(cls, name: str) -> "Profile":
        """A profile shipped with tactilize (see :func:`preset_names`)."""
        if name not in preset_names():
            raise ProfileError(name, f"no such preset (known: {', '.join(preset_names())})")
        text = resources.files("tactilize.profiles").joinpath(f"{name}.toml").read_text("utf-8")
        return cls.from_toml(text, source=f"preset {name}")

    @classmethod
    def load(cls, path: str | Path) -> "Profile":
        """Read a profile from a TOML file."""
        p = Path(path)
        try:
            text = p.read_text("utf-8")
        except FileNotFoundError:
            raise ProfileError(str(path), "file not found") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise ProfileError(str(path), f"cannot read ({exc.__class__.__name__})") from None
        return cls.from_toml(text, source=str(path))

    @classmethod
    def resolve(cls, name_or_path: str | Path | None) -> "Profile":
        """A preset by name, or a TOML file by path; the paper preset for None."""
        if name_or_path is None:
            return cls.preset("paper")
        text = str(name_or_path)
        if text in preset_names():
            return cls.preset(text)
        if text.endswith(".toml") or Path(text).exists():
            return cls.load(text)
        raise ProfileError(text, f"neither a preset ({', '.join(preset_names())}) nor a TOML file")

    @classmethod
    def from_toml(cls, text: str, source: str = "<toml>") -> "Profile":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ProfileError(source, f"invalid TOML ({exc})") from None
        return cls.from_dict(data, source=source)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "Profile":
        known = {"name", "description", "frequency", "speed", "width", "amplitude", "direction", "actuator"}
        unknown = set(data) - known
        if unknown:
            raise ProfileError(source, f"unknown section(s) {', '.join(sorted(unknown))}")
        for role in ("frequency", "speed", "width"):
            if role not in data:
                raise ProfileError(source, f"missing [{role}] section")
        kwargs: dict[str, Any] = {
            "name": str(data.get("name", Path(source).stem if source.endswith(".toml") else "custom")),
            "description": str(data.get("description", "")),
        }
        for role in ("frequency", "speed", "width", "amplitude", "direction"):
            if role in data:
                kwargs[role] = _law_from_dict(role, data[role], source)
        if "actuator" in data:
            act = dict(data["actuator"])
            fields_ = {f.name for f in dataclasses.fields(ActuatorLimits)}
            unknown = set(act) - fields_
            if unknown:
                raise ProfileError(source, f"[actuator] unknown key(s) {', '.join(sorted(unknown))}")
            try:
                kwargs["limits"] = ActuatorLimits(**act)
            except TypeError as exc:
                raise ProfileError(source, f"[actuator] {exc}") from None
            except ProfileError as exc:
                raise ProfileError(source, f"[actuator] {exc.fault}") from None
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "frequency": self.frequency.to_dict(),
            "speed": self.speed.to_dict(),
            "width": self.width.to_dict(),
            "amplitude": self.amplitude.to_dict(),
            "direction": self.direction.to_dict(),
            "actuator": self.limits.to_dict(),
        }

    def to_toml(self) -> str:
        import tomli_w

        return tomli_w.dumps(self.to_dict())

    def save(self, path: str | Path) -> Path:
        """Write this profile as TOML (readable back with :meth:`load`)."""
        p = Path(path)
        try:
            p.write_text(self.to_toml(), "utf-8")
        except OSError as exc:
            raise ProfileError(str(path), f"cannot write ({exc.strerror or exc})") from None
        return p

    def replace(self, **changes: Any) -> "Profile":
        return dataclasses.replace(self, **changes)


def preset_names() -> list[str]:
    """Names of the profiles shipped in ``tactilize/profiles``."""
    root = resources.files("tactilize.profiles")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))
