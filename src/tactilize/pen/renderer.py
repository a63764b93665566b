"""The pen's real-time loop: samples in, drives on an output.

:class:`PenRenderer` feeds the :class:`~.tracker.StrokeTracker`, looks the
texture up under the pen, asks the profile for the drive, splits it over the
pen's channels and applies it to an :class:`~tactilize.actuators.base.Output`.
Lifting the pen or leaving the picture stops the output at once.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, NamedTuple, Protocol, Sequence

from ..actuators.base import Output
from ..drive import Drive
from ..mapping import FeaturesForDrive, Profile
from ..surface.clock import StrokeClock
from ..surface.model import SurfaceLike
from ..surface.rendering import Frame, Rendering, rendering_for
from ..synthesis import pen_channels
from ..synthesis.wavelets import wavelet_rows
from .samples import PenSample
from .tracker import StrokeState, StrokeTracker

__all__ = ["RenderResult", "PenRenderer", "default_splitter"]


class PictureLookup(Protocol):
    """What the renderer reads of a picture: the features under the pen (a
    :class:`~tactilize.maps.FeatureLookup` is one; so is a picture with one set of
    features everywhere)."""

    def lookup(self, x_m: float, y_m: float) -> FeaturesForDrive | None:
        """The features at (``x_m``, ``y_m``) [m, from the top-left, y down]; None off the picture."""
        ...


@dataclass(frozen=True)
class RenderResult:
    """What the renderer did with a batch of samples.

    Attributes
    ----------
    down : bool
        The pen is on the surface (False after a lift).
    inside : bool
        The pen is over the picture.
    state : StrokeState or None
        The stroke estimate (None after a lift).
    features : TextureFeatures or None
        The texture under the pen (None outside the picture).
    requested : list of Drive
        Per channel, what the profile asked for (after the profile's limits).
    applied : list of Drive
        Per channel, what the output applied (after its safety envelope); all
        off when the output was stopped.
    """

    down: bool
    inside: bool
    state: StrokeState | None
    features: FeaturesForDrive | None
    requested: list[Drive]
    applied: list[Drive]
    #: Pulse events this batch's frame scheduled, on the stroke's clock (a steady rendering's
    #: regular train too); a batch re-schedules every event not yet fired, so count
    #: :attr:`pulses` instead.
    events: tuple = ()
    #: Pulses that became due since the previous batch.
    pulses: int = 0
    #: The events are the drive's own regular train (a steady rendering's frame).
    regular: bool = False

    @property
    def on(self) -> bool:
        """True when any channel is driven."""
        return any(not d.is_off for d in self.applied)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (SI, plus ``speed_mm_s`` and ``direction_deg`` for display)."""
        channels = []
        for req, app in zip(self.requested, self.applied):
            d = app.to_dict()
            # The page shows every limit that acted, the profile's and the envelope's.
            d["clamped"] = sorted(set(req.clamped) | set(app.clamped))
            d["requested_frequency_hz"] = req.pulse_frequency_hz
            channels.append(d)
        st, feat = self.state, self.features
        direction = st.direction_rad if st is not None else None
        speed = st.speed_m_s if st is not None else 0.0
        return {
            "down": self.down,
            "inside": self.inside,
            "on": self.on,
            "t_s": st.t_s if st is not None else None,
            "x_m": st.x_m if st is not None else None,
            "y_m": st.y_m if st is not None else None,
            "speed_m_s": speed,
            "speed_mm_s": speed * 1e3,
            # + 0.0 turns -0.0 into 0.0.
            "direction_deg": math.degrees(direction) + 0.0 if direction is not None else None,
            "pressure": st.pressure if st is not None else None,
            "spatial_frequency_per_m": float(feat.spatial_frequency_per_m) if feat is not None else None,
            "spectral_intensity": float(feat.spectral_intensity) if feat is not None else None,
            "channels": channels,
            "events": len(self.events),
            "pulses": self.pulses,
            # The page's audio plays each event as an acceleration wavelet: [dt_s from t_s, amplitude,
            # sigma_s]; a regular train it plays as its drive's pulse train, as the sound card does.
            "wavelets": wavelet_rows(self.events, st.t_s) if self.events and st is not None and not self.regular else [],
        }


def _equal_channels(drive: Drive, n: int, state: StrokeState | None) -> list[Drive]:
    return [drive] * n


def _phantom_channels(drive: Drive, n: int, state: StrokeState | None) -> list[Drive]:
    if n != 2:
        return [drive] * n
    return pen_channels(drive, state.direction_rad if state is not None else None)


def default_splitter(output: Output | None) -> Callable[[Drive, int, StrokeState | None], list[Drive]]:
    """How one drive becomes one per channel on ``output``.

    Where an output's amplitude is the felt intensity (voice coils and LRAs on
    audio), the phantom sensation follows the stroke direction by the energy
    model.  On the SMA wire the amplitude is the pulse current, and lowering it
    drops the wire out of its narrow vibrating band (both pins would fall
    still on a diagonal stroke), so both pins play the texture's drive as in
    the paper's pen.  Outputs say which with ``amplitude_is_intensity``.
    """
    if output is None or output.amplitude_is_intensity:
        return _phantom_channels
    return _equal_channels


class PenRenderer:
    """Turns a stream of pen samples into drives on an output, in real time.

    Parameters
    ----------
    texture_map : TextureMap
        The picture under the pen, at the physical size it is shown.
    profile : Profile
        The laws (the paper's by default).
    output : Output
        Where drives go (the simulated wire, the serial controller, audio...).
    tracker : StrokeTracker, optional
        A tracker with non-default settings.
    channels : int
        Actuators in the pen (the paper's has two).
    splitter : callable, optional
        ``splitter(drive, channels, state) -> list[Drive]``: how one drive
        becomes one per channel.  By default :func:`default_splitter`: the
        phantom sensation where the output's amplitude is intensity, the same
        drive on both pins on the SMA wire.
    resend_rel : float
        A drive within this relative difference of the one last applied, on
        every channel and quantity, is not sent again (0.5 %: twenty times
        finer than the fingertip's frequency discrimination: docs/references.md,
        section 3).
        0 sends every batch.
    refresh_s : float
        ...but the output gets the current drive at least this often [s], so a
        safety envelope that depends on the wire's state is asked again.
    surface : SurfaceModel or CompositeSurface, optional
        The picture as a surface; the profile's rendering (:func:`~tactilize.surface.rendering.rendering_for`)
        makes each batch's frame of events and their operating point, and the output
        plays the frame (``Output.play``: it decides how).
    clock : callable, optional
        ``clock() -> seconds``, monotonic, for ``refresh_s`` (:func:`time.monotonic`
        by default; tests inject one so the resend rule is deterministic).

    Notes
    -----
    One drive is computed per :meth:`feed` call, from the latest estimate: a
    batch of coalesced samples is one display frame, and the newest sample is
    the one that matters (older ones only improve the speed estimate).
    """

    def __init__(
        self,
        texture_map: PictureLookup,
        profile: Profile | None = None,
        output: Output | None = None,
        *,
        tracker: StrokeTracker | None = None,
        channels: int = 2,
        splitter: Callable[[Drive, int, StrokeState | None], list[Drive]] | None = None,
        resend_rel: float = 0.005,
        refresh_s: float = 0.1,
        surface: SurfaceLike | None = None,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.texture_map = texture_map
        self._clock = clock or time.monotonic
        self._stroke_clock = StrokeClock()
        self.profile = profile or Profile.preset("paper")
        self.rendering: Rendering = rendering_for(self.profile, surface)
        self._handed: _Handed | None = None  # the events the output holds
        self.output = output
        self.tracker = tracker or StrokeTracker()
        self.channels = channels if output is None else int(output.channels)
        self.splitter = splitter or default_splitter(output)
        self._off = [Drive.off()] * self.channels
        self._running = False  # did we leave the output driven?
        self.resend_rel = float(resend_rel)
        self.refresh_s = float(refresh_s)
        self._last = RenderResult(False, False, None, None, self._off, self._off)

    @property
    def last(self) -> RenderResult:
        """The latest result."""
        return self._last

    def set_texture(self, texture_map: PictureLookup, surface: SurfaceLike | None = None) -> RenderResult:
        """Show another picture (and its surface, for the surface rendering): the
        stroke restarts and the output stops."""
        self.texture_map = texture_map
        self.rendering = rendering_for(self.profile, surface)
        return self.lift()

    @property
    def surface(self) -> SurfaceLike | None:
        """The picture's surface model, or None."""
        return self.rendering.surface

    def set_profile(self, profile: Profile) -> None:
        """Use other laws from the next sample on."""
        self.profile = profile
        self.rendering = rendering_for(profile, self.rendering.surface, previous=self.rendering)

    def yield_output(self) -> None:
        """Another renderer drives the same output from now on (the experiments keep one per
        trial and picture): the next drive this one computes is sent, whatever it sent before;
        the stroke is kept."""
        self._handed = None

    def lift(self) -> RenderResult:
        """The pen left the surface: forget the stroke and rest the output at once
        (an SMA wire stays in standby for a while, ready for the next touch)."""
        self.tracker.reset()
        self.rendering.reset()
        self._handed = None
        self._stop()
        self._last = RenderResult(False, False, None, None, self._off, self._off)
        return self._last

    def feed(self, samples: Iterable[PenSample]) -> RenderResult:
        """Add a batch of samples and drive the output for the newest one."""
        batch = samples if isinstance(samples, list) else list(samples)
        return self._render(self.tracker.extend(batch), batch)

    def still(self) -> RenderResult:
        """No samples have arrived for a while although the pen is down.

        Browsers send no pointer events while a pen rests, so silence means the
        pen is not moving: render the same place at zero speed.
        """
        st = self.tracker.state
        if st is None:
            return self._last
        self.tracker.reset()
        self.tracker.add(PenSample(st.t_s, st.x_m, st.y_m, st.pressure))
        return self._render(self.tracker.state, [])

    def hover(self) -> None:
        """The pen hovers over the picture (or rests on it with nothing to render):
        hold the output ready, so the first pulse after it touches is felt at once."""
        if not self._running:
            self._rest()

    def _stop(self) -> None:
        if self._running:
            self._rest()
        self._running = False
        self._handed = None

    def _rest(self) -> None:
        """Texture pulses off; an output that can hold its actuators ready does."""
        if self.output is None:
            return
        self.output.standby()

    def _render(self, state: StrokeState | None, batch: list[PenSample]) -> RenderResult:
        # No state: every sample so far was rejected, nothing is known about the pen.
        feat = None if state is None else self.texture_map.lookup(state.x_m, state.y_m)
        frame = None
        if state is not None and feat is not None:
            # A batch held up arrives after the output played some of what the last one handed
            # out: the rendering is told, so a bump found again a little elsewhere is not played twice.
            played = self._stroke_clock.played_until_s(state.t_s, self._clock())
            frame = self.rendering.frame(state, feat, batch, played)
        return self.show(state, feat, frame)

    def show(self, state: StrokeState | None, features: FeaturesForDrive | None, frame: Frame | None) -> RenderResult:
        """Play a batch's ``frame`` (rendered for ``state`` over ``features``) on the output: the
        real-time loop's second half, which a whole stroke replayed offline
        (:func:`~tactilize.surface.playback.play_stroke`) calls for each frame it renders with this
        renderer's rendering, tracker and picture.  None (no state, off the picture): the
        rendering forgets the stroke and the output stops."""
        if state is None or features is None or frame is None:
            self.rendering.reset()
            self._handed = None
            self._stop()
            self._last = RenderResult(True, False, state, None, self._off, self._off)
            return self._last
        requested = self.splitter(frame.drive, self.channels, state)
        applied = self._play(frame, requested, state.t_s)
        self._last = RenderResult(True, True, state, features, requested, applied, frame.events,
                                  self.rendering.newly_fired, frame.regular)
        return self._last

    def _play(self, frame: Frame, requested: list[Drive], now_s: float) -> list[Drive]:
        """Hand ``frame`` to the output (``Output.play``: the output decides how it plays it),
        unless the output already holds it; returns what was applied."""
        if not frame.events and all(d.is_off for d in requested):
            self._stop()
            return self._off
        out = self.output
        if out is None:
            return requested
        now = self._clock()
        if self._running and self._holds(frame, requested, now_s, now):
            # Imperceptibly different from what the output already plays: spare it (and a
            # serial link) the frame.
            return self._handed.applied  # type: ignore[union-attr]
        # Marked running first: if play fails half-way, the next lift still stops it.
        self._running = True
        applied = list(out.play(frame, now_s, requested))
        self._handed = _Handed(frame.events, requested, applied, now_s, now, frame.regular)
        return applied

    def _holds(self, frame: Frame, requested: list[Drive], now_s: float, now: float) -> bool:
        """The output already plays ``frame``: handed within ``refresh_s`` (wall clock) and
        :data:`HAND_AGAIN_S` (the stroke's clock), with the same drives and the same events
        ahead.  A regular train's events are its drive's, so for one the drives within
        ``resend_rel`` are the same frame; other events must be those held not yet due (times
        within :data:`SAME_EVENT_S`), with the very same drives."""
        last = self._handed
        if (last is None or last.regular != frame.regular or not now - last.at < self.refresh_s
                or not 0.0 <= now_s - last.t_s < HAND_AGAIN_S or len(requested) != len(last.requested)):
            return False
        if frame.regular:
            return _close(requested, last.requested, self.resend_rel)
        return all(a is b for a, b in zip(requested, last.requested)) and _same_ahead(frame.events, last.events, now_s)

    def close(self) -> None:
        """Stop the output (the renderer does not own it, so it is not closed)."""
        self.lift()


class _Handed(NamedTuple):
    """A frame an output was handed: its events, the drives requested and applied, the stroke
    time and the wall-clock time, and whether the events were a regular train."""

    events: tuple
    requested: list[Drive]
    applied: list[Drive]
    t_s: float
    at: float
    regular: bool


#: A frame the output already holds is handed over again at least this often [s] of the stroke
#: all the same, so its plan of the operating point (what the page shows) follows the wire (as
#: ``refresh_s`` does on the wall clock).
HAND_AGAIN_S = 0.1
#: Events within this of each other [s] count as the same when the output already holds them
#: (over a window's events, typically 50 ms or more apart end to end, it moves the rate by under
#: the 0.5 % resend rule of steady drives); the events themselves are handed over exact.
SAME_EVENT_S = 1e-4
#: ...and strengths within this (a hundredth of the felt band).
SAME_STRENGTH = 0.01


def _same_ahead(events: Sequence[Any], held: Sequence[Any], now_s: float) -> bool:
    """``events`` are those of ``held`` not yet due at ``now_s`` [s]: times within
    :data:`SAME_EVENT_S`, strengths within :data:`SAME_STRENGTH`, the same clamps."""
    ahead = [y for y in held if y.t_s > now_s]
    return len(ahead) == len(events) and all(
        abs(x.t_s - y.t_s) <= SAME_EVENT_S and abs(x.strength - y.strength) <= SAME_STRENGTH and x.clamped == y.clamped
        for x, y in zip(events, ahead))


def _close(a: Sequence[Drive], b: Sequence[Drive], rel: float) -> bool:
    """Every channel's frequency, width and amplitude within ``rel`` of the other's."""
    if rel <= 0 or len(a) != len(b):
        return False
    return all(
        math.isclose(x.pulse_frequency_hz, y.pulse_frequency_hz, rel_tol=rel)
        and math.isclose(x.pulse_width_s, y.pulse_width_s, rel_tol=rel)
        and math.isclose(x.amplitude, y.amplitude, rel_tol=rel)
        for x, y in zip(a, b)
    )

