"""Profiles: one law of each role, the actuator limits, stored as TOML; and what a drive needs to know.

A :class:`Profile` composes a frequency law g, a speed law alpha, a width law h,
an amplitude law and a direction law, plus the :class:`ActuatorLimits` it was
tuned for.  Presets ship as TOML in ``tactilize/profiles``.  :meth:`Profile.drive`
is pure: features and stroke in, a :class:`~tactilize.drive.Drive` out.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from ..drive import Drive
from ..errors import DriveError, ProfileError, check_finite
from .laws import (
    AmplitudeLaw,
    ConstantAmplitude,
    DirectionLaw,
    EvenPulses,
    FrequencyLaw,
    LinearWidth,
    LogFrequency,
    NoDirection,
    RegularityLaw,
    SigmoidSpeed,
    SpeedLaw,
    WidthLaw,
    law_from_dict,
)
from .limits import ActuatorLimits

__all__ = ["DEFAULT_PRESET", "Profile", "preset_names", "DriveFeatures", "FeaturesForDrive", "RENDERINGS", "TIP_RADIUS_RANGE_M"]

#: How a profile renders a picture: ``steady`` (one drive from the picture's features
#: and the stroke's speed, the paper's way) or ``surface`` (a pulse per bump the tip
#: crosses, docs/surfaces.md).  A TOML without ``rendering`` is steady.
RENDERINGS = ("steady", "surface")
#: The preset every command and the library use when none is named: the surface rendering.
DEFAULT_PRESET = "surface"


@runtime_checkable
class FeaturesForDrive(Protocol):
    """What :meth:`Profile.drive` reads from a texture's features.

    :class:`~tactilize.features.TextureFeatures` has all of it; so has
    :class:`DriveFeatures`, the plain value the catalog and the experiments make
    from stored numbers.  Read-only: frozen values satisfy it.
    """

    @property
    def spatial_frequency_per_m(self) -> float: ...
    @property
    def spectral_intensity(self) -> float: ...
    @property
    def orientation_deg(self) -> float: ...
    @property
    def anisotropy(self) -> float: ...
    @property
    def periodicity(self) -> float: ...


@dataclass(frozen=True)
class DriveFeatures:
    """The four numbers a drive needs, when there is no image to analyse.

    Attributes
    ----------
    spatial_frequency_per_m : float
        Dominant spatial frequency [cycles/m].
    spectral_intensity : float
        The paper's i_s, in [0, 1].
    orientation_deg : float
        Direction of the wave vector [deg], counter-clockwise from +x, y up.
    anisotropy : float
        In [0, 1]; 1 (directional) when unknown, as :meth:`Profile.drive` assumes.
    periodicity : float
        Share of the AC power in the dominant peak, in [0, 1]; 1 (regular) when unknown.
    """

    spatial_frequency_per_m: float
    spectral_intensity: float
    orientation_deg: float = 0.0
    anisotropy: float = 1.0
    periodicity: float = 1.0


@dataclass(frozen=True)
class Profile:
    """A complete mapping from texture features and stroke to a :class:`Drive`.

    Use :meth:`preset`, :meth:`load` or build one from law objects.  A profile is
    pure: :meth:`drive` has no side effects and keeps no state.
    """

    name: str = "custom"
    frequency: FrequencyLaw = field(default_factory=LogFrequency)
    speed: SpeedLaw = field(default_factory=SigmoidSpeed)
    width: WidthLaw = field(default_factory=LinearWidth)
    amplitude: AmplitudeLaw = field(default_factory=ConstantAmplitude)
    direction: DirectionLaw = field(default_factory=NoDirection)
    regularity: RegularityLaw = field(default_factory=EvenPulses)
    limits: ActuatorLimits = field(default_factory=ActuatorLimits)
    description: str = ""
    #: One of :data:`RENDERINGS`; the laws above still give the drive where only
    #: features are known (catalogs, experiments).
    rendering: str = "steady"
    #: Stylus tip radius [m] of the surface rendering (docs/references.md, section 3 (stylus tip)).
    tip_radius_m: float = 0.25e-3

    # -- the laws

    def drive(
        self,
        features: FeaturesForDrive,
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
        check_finite(speed_m_s, "<speed>", what="speed", error=DriveError, minimum=0.0, unit="m/s")
        if direction_rad is not None:
            check_finite(direction_rad, "<direction>", what="direction", error=DriveError)
        if pressure is not None:
            check_finite(pressure, "<pressure>", what="pressure", error=DriveError)
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
        regularity = self.regularity(float(getattr(features, "periodicity", 1.0)))
        return (limits or self.limits).apply(Drive(f_p, p_w, amp, (), strength, regularity))

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
        """A preset by name, or a TOML file by path; :data:`DEFAULT_PRESET` for None."""
        if name_or_path is None:
            return cls.preset(DEFAULT_PRESET)
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
        known = {"name", "description", "rendering", "surface", "frequency", "speed", "width", "amplitude", "direction",
                 "regularity", "actuator"}
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
        for role in ("frequency", "speed", "width", "amplitude", "direction", "regularity"):
            if role in data:
                kwargs[role] = law_from_dict(role, data[role], source)
        kwargs.update(_rendering_from_dict(data, source))
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
        profile = cls(**kwargs)
        _check_laws(profile, source)
        return profile

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "frequency": self.frequency.to_dict(),
            "speed": self.speed.to_dict(),
            "width": self.width.to_dict(),
            "amplitude": self.amplitude.to_dict(),
            "direction": self.direction.to_dict(),
            "regularity": self.regularity.to_dict(),
            "actuator": self.limits.to_dict(),
        } | ({"rendering": self.rendering, "surface": {"tip_radius_mm": self.tip_radius_m * 1e3}}
             if self.rendering != "steady" else {})

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


def _rendering_from_dict(data: dict[str, Any], source: str) -> dict[str, Any]:
    """``rendering`` and the ``[surface]`` table of a profile's TOML (both optional)."""
    out: dict[str, Any] = {}
    rendering = data.get("rendering", "steady")
    if rendering not in RENDERINGS:
        raise ProfileError(source, f"rendering must be one of {', '.join(RENDERINGS)}, got {rendering!r}")
    out["rendering"] = rendering
    surface = data.get("surface", {})
    if not isinstance(surface, dict) or set(surface) - {"tip_radius_mm"}:
        raise ProfileError(source, "[surface] takes only tip_radius_mm")
    if "tip_radius_mm" in surface:
        tip = check_finite(surface["tip_radius_mm"], source, what="[surface] tip_radius_mm", error=ProfileError,
                           minimum=TIP_RADIUS_RANGE_M[0] * 1e3, maximum=TIP_RADIUS_RANGE_M[1] * 1e3, unit="mm")
        out["tip_radius_m"] = tip * 1e-3
    return out


#: The stylus tip radii [m] a profile's surface rendering takes.  The pen's path is
#: sampled every quarter of the radius (:attr:`tactilize.surface.SurfaceModel.step_m`),
#: so the work of a stroke grows as 1 / radius: 10 um (finer than any pen's tip, 400
#: samples per mm of stroke) keeps a live stroke's profile within memory and time;
#: 10 mm is a fingertip's size.
TIP_RADIUS_RANGE_M = (10e-6, 10e-3)


def preset_names() -> list[str]:
    """Names of the profiles shipped in ``tactilize/profiles``."""
    root = resources.files("tactilize.profiles")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


#: The fastest pulse train a profile may ask for [Hz]: far above touch (the
#: Pacinian channel ends near 400 Hz, docs/references.md, section 3) and below
#: what every output can place (two samples per period at the audio output's
#: 48 kHz; the simulated wire's 1 us schedule stops at 500 kHz).
MAX_PROFILE_FREQUENCY_HZ = 20_000.0
# The laws' declared domains, sampled at load: spatial frequency [cycles/m] from
# a 1 km period to a 1 um one, stroking speed [m/s] from rest to 10 m/s,
# spectral intensity, pressure and periodicity over [0, 1].
_DOMAIN: dict[str, list[Any]] = {
    "frequency": [10.0**e for e in range(-3, 7)],
    "speed": [0.0, 1e-4, 1e-3, 0.01, 0.06, 0.3, 1.0, 3.0, 10.0],
    "width": [0.0, 0.25, 0.5, 0.75, 1.0],
    "amplitude": [None, 0.0, 0.5, 1.0],
    "regularity": [0.0, 0.5, 1.0],
}
_DOMAIN_UNIT = {"frequency": "cycles/m", "speed": "m/s", "width": "i_s", "amplitude": "pressure",
                "regularity": "periodicity"}
# The roles whose product is the drive: each must be positive somewhere.
_MUST_BE_POSITIVE = ("frequency", "speed", "width", "amplitude")


def _check_laws(profile: Profile, source: str) -> None:
    """Refuse, at load, a profile whose laws fail or leave the finite numbers
    anywhere on their domains, or whose band no output can render: such a
    profile would load and then fail every drive (a batch, the pen page)."""
    if profile.limits.max_frequency_hz > MAX_PROFILE_FREQUENCY_HZ:
        raise ProfileError(source, f"[actuator] max_frequency_hz {profile.limits.max_frequency_hz:g} is above the "
                                   f"{MAX_PROFILE_FREQUENCY_HZ:g} Hz any output can render")
    for role, xs in _DOMAIN.items():
        law = getattr(profile, role)
        ys = []
        for x in xs:
            try:
                y = law(x)
                bad = y is not None and not math.isfinite(float(y))
            except (ArithmeticError, ValueError, TypeError) as exc:
                raise ProfileError(source, f"[{role}] {law.kind} law fails at {x}: {exc.__class__.__name__}") from None
            if bad:
                raise ProfileError(source, f"[{role}] {law.kind} law gives {y} at {x}")
            ys.append(y)
        # A drive is the product of these laws: one that is nowhere positive turns
        # every drive off, and each command would then report a texture as silent.
        if role in _MUST_BE_POSITIVE and not any(y is not None and y > 0 for y in ys):
            raise ProfileError(source, f"[{role}] {law.kind} law is zero or negative all over its domain "
                                       f"({xs[0]} .. {xs[-1]} {_DOMAIN_UNIT[role]}): it would never drive")
    corners = DriveFeatures
    for f_s in (_DOMAIN["frequency"][0], 1000.0, _DOMAIN["frequency"][-1]):
        for i_s in (0.0, 1.0):
            for v in (0.0, 0.06, _DOMAIN["speed"][-1]):
                try:
                    profile.drive(corners(f_s, i_s, 30.0, 1.0, 0.3), v, 0.5)
                except (ArithmeticError, ValueError, TypeError, DriveError) as exc:
                    what = getattr(exc, "fault", exc.__class__.__name__)
                    raise ProfileError(source, f"no drive at {f_s:g} cycles/m, i_s {i_s:g}, {v:g} m/s: {what}") from None
