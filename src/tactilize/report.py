"""A profile report a designer reads: what each texture gets at each speed, whether the wire
follows it, and which textures the finger cannot tell apart.

:func:`profile_report` runs a profile over textures (the built-in ones, or given
images) and steady strokes at 10 .. 160 mm/s, plays every drive on the simulated
wire (:func:`tactilize.actuators.felt.feel`), and compares every pair of textures at
equal speed.  ``tactilize profile report`` prints it and draws it.

Every rendering is judged by what it gives a straight stroke
(:meth:`tactilize.surface.rendering.Rendering.straight`): the pulses' rate, interval CV
and strength are the row, the stroke's Drive is what the wire plays.  A steady
rendering's are its law's Drive (its frequency, :func:`interval_cv` and strength); a
surface rendering's are measured on the events of the stroke over each texture's
surface (docs/surfaces.md).

Two pulse trains are told apart (:func:`distinguishable_measured`, on the rate and CV;
:func:`distinguishable`, on two drives) when their rates differ by at least one
frequency JND (Weber fraction 0.2, docs/references.md, section 3 (frequency
discrimination)), or when one train is clearly irregular and the other is not: their
intervals' coefficients of variation differ by at least :data:`REGULARITY_JND_CV` (at
that difference successive intervals of the irregular train typically differ by one
frequency JND).  Strength is not counted.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from .drive import Drive, interval_cv
from .errors import TactilizeError
from .mapping import FeaturesForDrive, Profile

if TYPE_CHECKING:
    from .actuators.sma import WireSpec

__all__ = ["profile_report", "ProfileReport", "distinguishable", "distinguishable_measured", "interval_cv", "SPEEDS_MM_S",
           "FREQUENCY_JND"]

#: The stroking speeds of the report [mm/s] (docs/references.md, section 9 (stroking speeds)).
SPEEDS_MM_S = (10.0, 20.0, 40.0, 60.0, 100.0, 160.0)
#: Weber fraction of vibration frequency on the fingertip (0.18 .. 0.25; the middle).
FREQUENCY_JND = 0.2
#: Difference of interval CV that tells an irregular train from a regular one:
#: successive intervals of a train with CV c differ by about sqrt(2) c, so
#: 0.2 / sqrt(2) = 0.14 makes them differ by a frequency JND.
REGULARITY_JND_CV = 0.14


def distinguishable(a: Drive, b: Drive) -> bool:
    """True when the finger tells the two drives' trains apart (see the module docstring)."""
    return distinguishable_measured(_train_of(a), _train_of(b))


def _train_of(d: Drive) -> tuple[float, float]:
    """A drive's train as (rate [1/s], interval CV): an off drive has no pulses."""
    return (0.0 if d.is_off else d.pulse_frequency_hz), interval_cv(d)


def distinguishable_measured(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """True when the finger tells apart two pulse trains measured as (rate [1/s], interval CV)."""
    (fa, ca), (fb, cb) = a, b
    if fa <= 0 or fb <= 0:
        return (fa <= 0) != (fb <= 0)
    lo, hi = sorted((fa, fb))
    return hi >= lo * (1.0 + FREQUENCY_JND) or abs(ca - cb) >= REGULARITY_JND_CV


@dataclass
class ProfileReport:
    """The report: one row per texture and speed, and the pairs closer than one JND.

    Attributes
    ----------
    profile : str
    rows : list of dict
        ``texture``, ``speed_mm_s``, ``frequency_hz`` (pulses per second of the straight
        stroke), ``pulse_width_ms``, ``strength``, ``regularity`` (the stroke's Drive's),
        ``interval_cv``, ``pulses`` (over the stroke), ``clamped``, ``follows``,
        ``displacement_pp_um``, ``first_follow_ms`` (the simulated wire, from standby).
    close_pairs : list of dict
        ``speed_mm_s``, ``a``, ``b``, ``frequency_ratio``: pairs the finger cannot tell apart.
    pairs : int
        Texture pairs compared (pairs x speeds).
    """

    profile: str
    rows: list[dict[str, Any]] = field(default_factory=list)
    close_pairs: list[dict[str, Any]] = field(default_factory=list)
    pairs: int = 0

    @property
    def distinct_share(self) -> float:
        """Share of texture pairs told apart at equal speed."""
        return 1.0 - len(self.close_pairs) / self.pairs if self.pairs else 1.0

    @property
    def followed_share(self) -> float:
        """Share of drives the simulated wire follows."""
        return sum(r["follows"] for r in self.rows) / len(self.rows) if self.rows else 1.0

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["distinct_share"] = self.distinct_share
        d["followed_share"] = self.followed_share
        return d


def profile_report(
    profile: Profile,
    textures: Mapping[str, FeaturesForDrive] | None = None,
    speeds_mm_s: Sequence[float] = SPEEDS_MM_S,
    *,
    wire: WireSpec | str | None = None,
    simulate_wire: bool = True,
    images: dict[str, Any] | None = None,
    material: Any = None,
) -> ProfileReport:
    """Drives, wire response and JND pairs of a profile over textures and speeds.

    Parameters
    ----------
    profile : Profile
    textures : dict of name -> features, optional
        Anything :meth:`Profile.drive` takes, one per texture reported; by default the
        features of ``images``.
    speeds_mm_s : sequence of float
        Steady stroking speeds [mm/s] (no direction: full speed).
    wire : WireSpec or str, optional
        The simulated wire (the paper's 75 um).
    simulate_wire : bool
        Play every drive on the simulated wire (a few hundredths of a second each).
    images : dict of name -> TextureImage, optional
        The pictures of ``textures`` (a surface rendering strokes them); a texture not
        among them is the built-in one of that name.  The built-in textures by default.
    material : MaterialChoice, optional
        What a surface rendering renders every picture as (:class:`tactilize.materials.MaterialChoice`);
        the picture alone by default.

    Raises
    ------
    TactilizeError
        A rendering that strokes the pictures is given a texture without one (neither in
        ``images`` nor built in).
    """
    from .surface.rendering import rendering_for

    kw = {} if material is None else material.surface_kwargs()
    pictures = _pictures(textures, images)
    renderings = {name: (feat, rendering_for(profile, image=picture, **kw)) for name, (feat, picture) in pictures.items()}
    report = ProfileReport(profile.name)
    for v in speeds_mm_s:
        measured: dict[str, tuple[float, float]] = {}
        for name, (feat, rendering) in renderings.items():
            st = rendering.straight(feat, v / 1e3)
            measured[name] = (st.rate_hz, st.interval_cv)
            row = {
                "texture": name,
                "speed_mm_s": float(v),
                "frequency_hz": st.rate_hz,
                "pulse_width_ms": st.drive.pulse_width_s * 1e3,
                "strength": st.strength,
                "regularity": st.drive.regularity,
                "interval_cv": st.interval_cv,
                "pulses": st.pulses,
                "clamped": list(st.clamped),
            }
            row.update(_felt_columns(st.drive, wire, simulate_wire))
            report.rows.append(row)
        for a, b in itertools.combinations(measured, 2):
            report.pairs += 1
            if not distinguishable_measured(measured[a], measured[b]):
                report.close_pairs.append(_close_pair(v, a, b, measured[a][0], measured[b][0]))
    return report


def _pictures(textures: Mapping[str, FeaturesForDrive] | None,
              images: dict[str, Any] | None) -> dict[str, tuple[Any, Callable[[], Any]]]:
    """Per texture reported, its features and its picture (a callable: read only by a rendering
    that strokes it).  Features not given are extracted only when a rendering reads them."""
    from .data import texture_ids

    given = images or {}

    def picture(name: str) -> Callable[[], Any]:
        def load() -> Any:
            if name in given:
                return given[name]
            from .data import get_texture

            try:
                return get_texture(name).image
            except KeyError:
                raise TactilizeError(name, "no picture of this texture to stroke (give it in images)") from None

        return load

    if textures is not None:
        return {name: (feat, picture(name)) for name, feat in textures.items()}
    return {name: (_LazyFeatures(picture(name)), picture(name)) for name in (images if images is not None else texture_ids())}


class _LazyFeatures:
    """A picture's features (:func:`tactilize.features.extract_features`), extracted when first read."""

    def __init__(self, picture: Callable[[], Any]) -> None:
        self._picture = picture
        self._features: Any = None

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        if self._features is None:
            from .features import extract_features

            self._features = extract_features(self._picture())
        return getattr(self._features, name)


def _felt_columns(d: Any, wire: Any, simulate_wire: bool) -> dict[str, Any]:
    """What the simulated wire makes of drive ``d`` (follows, displacement [um], first felt pulse [ms])."""
    if not simulate_wire or d.is_off:
        return {"follows": False, "displacement_pp_um": 0.0, "first_follow_ms": None}
    from .actuators.felt import feel

    felt = feel(d, wire)
    return {"follows": felt.follows, "displacement_pp_um": felt.displacement_pp_um,
            "first_follow_ms": felt.first_follow_ms if math.isfinite(felt.first_follow_ms) else None}


def _close_pair(speed_mm_s: float, a: str, b: str, fa_hz: float, fb_hz: float) -> dict[str, Any]:
    """One pair the finger cannot tell apart at ``speed_mm_s``, with its frequency ratio."""
    ratio = max(fa_hz, fb_hz) / min(fa_hz, fb_hz) if min(fa_hz, fb_hz) > 0 else math.inf
    return {"speed_mm_s": float(speed_mm_s), "a": a, "b": b, "frequency_ratio": ratio}


# ----------------------------------------------------------------- the voice coil's signal


def audio_report(profile: Profile, images: dict[str, Any] | None = None,
                 speeds_mm_s: Sequence[float] = SPEEDS_MM_S, material: Any = None) -> list[dict[str, Any]]:
    """Per texture and speed, the spectrum of the tip's acceleration along a straight stroke
    (:func:`tactilize.synthesis.acceleration.audio_rows`): what a voice coil plays and the WAV
    export carries.  The built-in textures when ``images`` is None; every picture rendered as
    ``material`` (a :class:`tactilize.materials.MaterialChoice`) when given."""
    from .surface.model import TIP_RADIUS_M, surface_model
    from .synthesis.acceleration import audio_rows

    if images is None:
        from .data import get_texture, texture_ids

        images = {tid: get_texture(tid).image for tid in texture_ids()}
    tip = getattr(profile, "tip_radius_m", None) or TIP_RADIUS_M
    rows = []
    for name, img in images.items():
        kw = {} if material is None else material.surface_kwargs()
        for r in audio_rows(surface_model(img, tip_radius_m=tip, **kw), speeds_mm_s):
            rows.append({"texture": name, **r})
    return rows
