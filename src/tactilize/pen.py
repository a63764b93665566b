"""The tactile pen in software: stroke tracking and real-time rendering.

The paper's pen system (its Fig. 6) tracks the pen on a tablet while the texture
picture is shown on a display, and drives the two actuators in the pen's grip
with the texture *under the pen*, at a frequency that follows the stroking
speed.  This module holds the two stateful pieces of that loop:

:class:`StrokeTracker`
    Speed [m/s] and direction [rad] of the stroke from the pen samples' *own*
    timestamps (never the arrival time: samples come in bursts, coalesced to the
    display's frame rate).  A least-squares line through the last ~30 ms of
    samples; robust to jitter, duplicate and out-of-order samples, gaps, clock
    resets and jumps (see the class for each rule).
:class:`PenRenderer`
    Feeds the tracker, looks the texture up under the pen, asks the profile for
    the drive, splits it over the two channels and applies it to an
    :class:`~tactilize.actuators.base.Output`.  Lifting the pen or leaving the
    picture stops the output at once.

Frames
------
Positions are metres from the picture's top-left corner with y pointing *down*
(screen coordinates, as pointers report them and as
:meth:`~tactilize.texturemap.TextureMap.lookup` takes them).  Directions are
counter-clockwise from +x with y pointing *up* (the frame of
``TextureFeatures.orientation_deg`` and ``Profile.drive``), so a stroke moving up
the screen has direction +pi/2.

The page reports positions in CSS pixels and times in milliseconds;
:func:`samples_from_css` converts them with the calibrated size of a CSS pixel.
"""

from __future__ import annotations

import math
import time
from bisect import bisect_left
from collections import deque
from dataclasses import dataclass, field
from itertools import islice
from operator import mul
from typing import Any, Callable, Iterable, NamedTuple, Sequence

from .mapping import Drive, Profile
from .synthesis import pen_channels

__all__ = [
    "PenSample",
    "StrokeState",
    "StrokeTracker",
    "RenderResult",
    "PenRenderer",
    "samples_from_css",
    "DEFAULT_M_PER_CSS_PX",
    "sample_error",
    "sample_ok",
]

#: A CSS pixel is 1/96 inch by definition (FACTS.md section 5); the page
#: replaces this with a calibrated value.
DEFAULT_M_PER_CSS_PX = 0.0254 / 96.0


class PenSample(NamedTuple):
    """One pen sample (a named tuple: thousands are made per second, and a
    tuple is the cheapest immutable record Python has).

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


def sample_error(row: Any) -> str | None:
    """Why a CSS sample row is malformed, or None when it is fine.

    A row is ``[t_ms, x_px, y_px]`` optionally followed by ``pressure``,
    ``tilt_x_deg``, ``tilt_y_deg`` (numbers; ``pressure`` may be null).
    """
    if not isinstance(row, (list, tuple)):
        return "a sample must be an array [t_ms, x_px, y_px, pressure?, tilt_x_deg?, tilt_y_deg?]"
    if not 3 <= len(row) <= 6:
        return f"a sample has 3 to 6 values, got {len(row)}"
    for i, v in enumerate(row):
        if i == 3 and v is None:
            continue
        try:
            finite = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
        except OverflowError:  # an integer beyond any float (JSON allows any length)
            finite = False
        if not finite:
            return f"sample value {i} must be a finite number, got {v!r}"
    if len(row) > 3 and row[3] is not None and not 0.0 <= row[3] <= 1.0:
        return f"pressure must be in [0, 1], got {row[3]!r}"
    return None


_NUMBER_TYPES = frozenset((float, int))


def sample_ok(row: Any) -> bool:
    """True when a CSS sample row is certainly well formed (the fast path of
    :func:`sample_error`, which says why a row is not).

    False does not mean malformed: unusual but valid rows (a tuple, an integer
    subclass) are left to :func:`sample_error`.  Every pen batch checks each of
    its rows, so this does it with a few C-level calls instead of a loop.
    """
    if type(row) is not list:
        return False
    n = len(row)
    if not 3 <= n <= 6:
        return False
    if n > 3:
        p = row[3]
        if p is None:
            row = row[:3] + row[4:]  # pressure may be null (a mouse)
        elif not ((type(p) is float or type(p) is int) and 0.0 <= p <= 1.0):
            return False
    # bool is its own type, so it fails here as in sample_error.
    if not _NUMBER_TYPES.issuperset(map(type, row)):
        return False
    try:
        # A finite sum means every value is finite (inf and nan propagate; an
        # integer too large for a float raises).
        return -math.inf < math.fsum(row) < math.inf
    except (OverflowError, ValueError):
        return False


def samples_from_css(rows: Iterable[Sequence[Any]], m_per_px: float) -> list[PenSample]:
    """Pen samples in SI from the page's rows.

    Parameters
    ----------
    rows : iterable of sequences
        ``[t_ms, x_px, y_px, pressure?, tilt_x_deg?, tilt_y_deg?]``: the event's
        timestamp [ms], the position in CSS pixels from the picture's top-left
        corner (y down), pressure in [0, 1] or None, tilt [deg].  Rows must
        already pass :func:`sample_error`.
    m_per_px : float
        Calibrated size of one CSS pixel on the screen [m].

    Returns
    -------
    list of PenSample
    """
    # tuple.__new__ skips the named tuple's Python-level __new__ (one per sample).
    new = tuple.__new__
    out = []
    for r in rows:
        n = len(r)
        if n == 6:
            out.append(new(PenSample, (r[0] * 1e-3, r[1] * m_per_px, r[2] * m_per_px, r[3], r[4], r[5])))
        else:
            out.append(
                new(
                    PenSample,
                    (
                        r[0] * 1e-3,
                        r[1] * m_per_px,
                        r[2] * m_per_px,
                        r[3] if n > 3 else None,
                        r[4] if n > 4 else 0.0,
                        r[5] if n > 5 else 0.0,
                    ),
                )
            )
    return out


class StrokeState(NamedTuple):
    """The tracker's estimate after the latest accepted sample.

    Attributes
    ----------
    t_s : float
        Timestamp of the latest sample [s].
    x_m, y_m : float
        Its position [m] (y down).
    speed_m_s : float
        Stroking speed [m/s].
    direction_rad : float or None
        Stroke direction [rad], counter-clockwise from +x with y *up*, in
        (-pi, pi]; None while the pen is (nearly) still.
    pressure : float or None
        Latest pressure in [0, 1].
    samples : int
        Samples in the estimation window.
    """

    t_s: float
    x_m: float
    y_m: float
    speed_m_s: float
    direction_rad: float | None
    pressure: float | None
    samples: int


class StrokeTracker:
    """Stroke speed and direction from timestamped pen samples.

    The velocity is the slope of a least-squares line through the samples of
    the last ``window_s`` seconds (at least ``min_samples`` of them when the
    stroke has that many), fitted in x and y separately.  Over 30 ms a 240 Hz
    pen gives 7 samples and a 100 Hz tablet 3 to 4, enough to average out
    position jitter of a pixel or two while lagging the hand by only ~15 ms
    (published texture renderers budget ~40 ms end to end, FACTS.md section 3).

    Slow strokes on devices that report whole pixels (mice, touch screens,
    many tablets through some browsers) move less than a pixel between samples;
    over 30 ms the fit would see a staircase.  So the window grows, up to
    ``max_window_s``, until the pen has travelled ``min_travel_m`` across it:
    fast strokes keep the short window, slow ones average over enough pixels.

    Bad input, and what happens to it (each is counted in :attr:`counts`):

    ``invalid``
        Non-finite time or position: dropped.
    ``duplicate``
        Same timestamp and position as the previous sample (pointer stacks
        resend samples): dropped.
    ``out_of_order``
        Timestamp not after the previous one: dropped, since the estimate is
        built from the samples' own clock.  A step back by more than
        ``max_gap_s`` is a clock reset (a reloaded page restarts its clock) and
        starts a new stroke instead.
    ``gap``
        More than ``max_gap_s`` since the previous sample (the pen was lifted
        without telling us, or the connection stalled): a new stroke starts.
    ``jump``
        A sample implying a speed above ``max_speed_m_s`` is held back as a
        candidate.  If the next sample continues from the candidate, the pen
        really moved (re-entered elsewhere): a new stroke starts at the
        candidate.  If it continues from before, the candidate was a glitch and
        is discarded.  Either way no impossible speed reaches the output.

    Parameters
    ----------
    window_s : float
        Length of the fitting window [s].
    min_samples : int
        Fit at least this many of the latest samples even if they span more
        than ``window_s`` (sparse devices), never reaching across a new stroke.
    min_travel_m : float
        Grow the window until the pen moved this far across it [m] (about four
        CSS pixels, so one pixel of quantisation is under ~25 % of it)...
    max_window_s : float
        ...but never beyond this [s].
    max_gap_s : float
        Longest silence within one stroke [s].
    max_speed_m_s : float
        Fastest believable pen speed [m/s]; hand strokes stay under ~1.5 m/s.
    still_speed_m_s : float
        Below this speed [m/s] the direction is undefined (None).
    max_samples : int
        Bound on the samples kept, whatever the sample rate.
    """

    def __init__(
        self,
        window_s: float = 0.030,
        *,
        min_samples: int = 3,
        min_travel_m: float = 1.0e-3,
        max_window_s: float = 0.100,
        max_gap_s: float = 0.100,
        max_speed_m_s: float = 4.0,
        still_speed_m_s: float = 1e-4,
        max_samples: int = 64,
    ) -> None:
        if not window_s > 0 or not max_gap_s > 0 or not max_speed_m_s > 0:
            raise ValueError("window_s, max_gap_s and max_speed_m_s must be positive")
        if min_samples < 2 or max_samples < min_samples:
            raise ValueError("need 2 <= min_samples <= max_samples")
        self.window_s = float(window_s)
        self.min_samples = int(min_samples)
        self.min_travel_m = float(min_travel_m)
        self.max_window_s = max(float(max_window_s), self.window_s)
        self.max_gap_s = float(max_gap_s)
        self.max_speed_m_s = float(max_speed_m_s)
        self.still_speed_m_s = float(still_speed_m_s)
        self._buf: deque[PenSample] = deque(maxlen=int(max_samples))
        # The same samples' timestamps and positions as x + iy, kept beside
        # _buf for the fit (see _fit).
        self._t: deque[float] = deque(maxlen=int(max_samples))
        self._z: deque[complex] = deque(maxlen=int(max_samples))
        self._candidate: PenSample | None = None
        self._state: StrokeState | None = None
        self._dirty = False
        self.counts: dict[str, int] = dict.fromkeys(
            ("accepted", "invalid", "duplicate", "out_of_order", "gap", "jump", "glitch", "clock_reset"), 0
        )

    # ------------------------------------------------------------------ input

    def reset(self) -> None:
        """Forget the stroke (the pen was lifted)."""
        self._buf.clear()
        self._t.clear()
        self._z.clear()
        self._candidate = None
        self._state = None
        self._dirty = False

    @property
    def state(self) -> StrokeState | None:
        """The latest estimate; None before the first sample of a stroke.

        The line is fitted here, on demand, not on every sample: a batch of
        coalesced samples costs one fit.
        """
        if self._dirty:
            self._dirty = False
            self._state = self._fit()
        return self._state

    def add(self, sample: PenSample) -> bool:
        """Add one sample; True when it was accepted into the stroke."""
        t_s, x_m, y_m = sample.t_s, sample.x_m, sample.y_m
        # v - v is 0 for every finite v and NaN for infinities and NaN: one test
        # for all three (this runs for every sample).
        if (t_s - t_s) + (x_m - x_m) + (y_m - y_m) != 0.0:
            self.counts["invalid"] += 1
            return False
        buf = self._buf
        if not buf:
            self._start(sample)
            return True
        cand = self._candidate
        last = cand or buf[-1]
        dt = t_s - last.t_s
        if dt <= 0:
            if dt == 0 and x_m == last.x_m and y_m == last.y_m:
                self.counts["duplicate"] += 1
                return False
            if dt < -self.max_gap_s:
                self.counts["clock_reset"] += 1
                self._start(sample)
                return True
            self.counts["out_of_order"] += 1
            return False
        if dt > self.max_gap_s:
            self.counts["gap"] += 1
            self._start(sample)
            return True
        if cand is not None:
            self._candidate = None
            if self._speed_between(cand, sample) <= self.max_speed_m_s:
                # The pen really is over there now: new stroke from the candidate.
                self.counts["jump"] += 1
                self._start(cand)
                return self._append(sample)
            # The candidate was a glitch; judge this sample against the stroke.
            self.counts["glitch"] += 1
            if t_s <= buf[-1].t_s:
                self.counts["out_of_order"] += 1
                return False
            if buf[-1].t_s < t_s - self.max_gap_s:
                self.counts["gap"] += 1
                self._start(sample)
                return True
            dt = t_s - buf[-1].t_s
        prev = buf[-1]
        # _speed_between inlined (dt > 0 here): the common path of every sample.
        if math.hypot(x_m - prev.x_m, y_m - prev.y_m) / dt > self.max_speed_m_s:
            self._candidate = sample
            return False
        buf.append(sample)
        self._t.append(t_s)
        self._z.append(complex(x_m, y_m))
        self.counts["accepted"] += 1
        self._dirty = True
        return True

    def extend(self, samples: Iterable[PenSample]) -> StrokeState | None:
        """Add many samples; returns the latest estimate."""
        for s in samples:
            self.add(s)
        return self.state

    # ------------------------------------------------------------------ estimate

    @staticmethod
    def _speed_between(a: PenSample, b: PenSample) -> float:
        dt = b.t_s - a.t_s
        d = math.hypot(b.x_m - a.x_m, b.y_m - a.y_m)
        return math.inf if dt <= 0 else d / dt

    def _start(self, sample: PenSample) -> None:
        self._buf.clear()
        self._t.clear()
        self._z.clear()
        self._candidate = None
        self._buf.append(sample)
        self._t.append(sample.t_s)
        self._z.append(complex(sample.x_m, sample.y_m))
        self.counts["accepted"] += 1
        self._dirty = False
        self._state = StrokeState(sample.t_s, sample.x_m, sample.y_m, 0.0, None, sample.pressure, 1)

    def _append(self, sample: PenSample) -> bool:
        self._buf.append(sample)
        self._t.append(sample.t_s)
        self._z.append(complex(sample.x_m, sample.y_m))
        self.counts["accepted"] += 1
        self._dirty = True
        return True

    def _fit(self) -> StrokeState:
        buf = self._buf
        sample = buf[-1]
        t0, x0, y0 = sample.t_s, sample.x_m, sample.y_m
        n = len(buf)
        # Samples in the window, but at least min_samples (all are of this
        # stroke).  Timestamps increase strictly within a stroke (add() drops
        # the rest), so the window's first sample is found by bisection.
        start = bisect_left(self._t, t0 - self.window_s)
        start = max(0, min(start, n - self.min_samples))
        # Slow stroke: widen the window until it spans enough travel.
        t_limit = t0 - self.max_window_s
        while start > 0 and buf[start - 1].t_s >= t_limit:
            p = buf[start]
            if abs(x0 - p.x_m) + abs(y0 - p.y_m) >= self.min_travel_m:
                break
            start -= 1
        # Sums relative to the newest sample (keeps the subtraction exact for
        # timestamps of any origin), with built-ins over whole columns: a 1 kHz
        # pen puts ~30 samples in the window, and a Python loop over them was
        # the costliest step of a pen batch.  Positions are x + iy, so one
        # complex sum gives the x and the y sum: complex addition, and a float
        # times a complex, round each part exactly as the real operations do.
        # sum() adds in order, as a loop does.
        m = n - start
        z0 = complex(x0, y0)
        ts = [t - t0 for t in islice(self._t, start, n)]
        zs = [z - z0 for z in islice(self._z, start, n)]
        st = sum(ts, 0.0)
        stt = sum(map(mul, ts, ts), 0.0)
        var = stt - st * st / m
        if var > 0:
            sz = sum(zs, 0j)
            stz = sum(map(mul, ts, zs), 0j)
            vx = (stz.real - st * sz.real / m) / var
            vy = (stz.imag - st * sz.imag / m) / var
        else:
            vx = vy = 0.0
        speed = math.hypot(vx, vy)
        # y is down on screen, up in the direction frame: flip its sign.
        direction = math.atan2(-vy, vx) if speed > self.still_speed_m_s else None
        return StrokeState(t0, x0, y0, speed, direction, sample.pressure, m)


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
    features: Any
    requested: list[Drive]
    applied: list[Drive]

    @property
    def on(self) -> bool:
        """True when any channel is driven."""
        return any(not d.is_off for d in self.applied)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (SI, plus ``speed_mm_s`` and ``direction_deg`` for display)."""
        st = self.state
        chans: list[dict[str, Any]] = []
        on = False
        prev: tuple[Any, Any, dict[str, Any]] | None = None
        # Written out rather than via Drive.to_dict: this builds every pen batch's reply.
        for req, app in zip(self.requested, self.applied):
            if prev is not None and req is prev[0] and app is prev[1]:
                # Channels given the same drives (the SMA pen's two pins): same entry.
                d = dict(prev[2])
                d["clamped"] = list(d["clamped"])
                chans.append(d)
                continue
            f, w, a = app.pulse_frequency_hz, app.pulse_width_s, app.amplitude
            on = on or not (f <= 0 or w <= 0 or a <= 0)
            d = {
                "pulse_frequency_hz": f,
                "pulse_width_s": w,
                "pulse_width_ms": w * 1e3,
                "duty_ratio": f * w,
                "amplitude": a,
                # The page shows every limit that acted, the profile's and the envelope's.
                "clamped": sorted(set(req.clamped) | set(app.clamped)) if req.clamped or app.clamped else [],
                "requested_frequency_hz": req.pulse_frequency_hz,
            }
            chans.append(d)
            prev = (req, app, d)
        if len(self.applied) > len(self.requested):  # zip stopped early: judge "on" by every channel
            on = self.on
        feat = self.features
        if st is None:
            return {
                "down": self.down,
                "inside": self.inside,
                "on": on,
                "t_s": None,
                "x_m": None,
                "y_m": None,
                "speed_m_s": 0.0,
                "speed_mm_s": 0.0,
                "direction_deg": None,
                "pressure": None,
                "spatial_frequency_per_m": float(feat.spatial_frequency_per_m) if feat is not None else None,
                "spectral_intensity": float(feat.spectral_intensity) if feat is not None else None,
                "channels": chans,
            }
        direction = st.direction_rad
        return {
            "down": self.down,
            "inside": self.inside,
            "on": on,
            "t_s": st.t_s,
            "x_m": st.x_m,
            "y_m": st.y_m,
            "speed_m_s": st.speed_m_s,
            "speed_mm_s": st.speed_m_s * 1e3,
            "direction_deg": math.degrees(direction) + 0.0 if direction is not None else None,
            "pressure": st.pressure,
            "spatial_frequency_per_m": float(feat.spatial_frequency_per_m) if feat is not None else None,
            "spectral_intensity": float(feat.spectral_intensity) if feat is not None else None,
            "channels": chans,
        }


def _equal_channels(drive: Drive, n: int, state: StrokeState | None) -> list[Drive]:
    return [drive] * n


def _phantom_channels(drive: Drive, n: int, state: StrokeState | None) -> list[Drive]:
    if n != 2:
        return [drive] * n
    return pen_channels(drive, state.direction_rad if state is not None else None)


def default_splitter(output: Any) -> Callable[[Drive, int, StrokeState | None], list[Drive]]:
    """How one drive becomes one per channel on ``output``.

    Where an output's amplitude is the felt intensity (voice coils and LRAs on
    audio), the phantom sensation follows the stroke direction by the energy
    model.  On the SMA wire the amplitude is the pulse current, and lowering it
    drops the wire out of its narrow vibrating band (both pins would fall
    still on a diagonal stroke), so both pins play the texture's drive as in
    the paper's pen.  Outputs say which with ``amplitude_is_intensity``.
    """
    if getattr(output, "amplitude_is_intensity", True):
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
        finer than the fingertip's frequency discrimination, FACTS.md section 3).
        0 sends every batch.
    refresh_s : float
        ...but the output gets the current drive at least this often [s], so a
        safety envelope that depends on the wire's state is asked again.

    Notes
    -----
    One drive is computed per :meth:`feed` call, from the latest estimate: a
    batch of coalesced samples is one display frame, and the newest sample is
    the one that matters (older ones only improve the speed estimate).
    """

    def __init__(
        self,
        texture_map: Any,
        profile: Profile | None = None,
        output: Any = None,
        *,
        tracker: StrokeTracker | None = None,
        channels: int = 2,
        splitter: Callable[[Drive, int, StrokeState | None], list[Drive]] | None = None,
        resend_rel: float = 0.005,
        refresh_s: float = 0.1,
    ) -> None:
        self.texture_map = texture_map
        self.profile = profile or Profile.preset("paper")
        self.output = output
        self.tracker = tracker or StrokeTracker()
        self.channels = int(getattr(output, "channels", channels) or channels)
        self.splitter = splitter or default_splitter(output)
        self._off = [Drive.off()] * self.channels
        self._running = False  # did we leave the output driven?
        self.resend_rel = float(resend_rel)
        self.refresh_s = float(refresh_s)
        self._sent: tuple[list[Drive], list[Drive]] | None = None  # (requested, applied) last sent
        self._sent_at = 0.0
        self._last = RenderResult(False, False, None, None, self._off, self._off)

    @property
    def last(self) -> RenderResult:
        """The latest result."""
        return self._last

    def set_texture(self, texture_map: Any) -> RenderResult:
        """Show another picture: the stroke restarts and the output stops."""
        self.texture_map = texture_map
        return self.lift()

    def set_profile(self, profile: Profile) -> None:
        """Use other laws from the next sample on."""
        self.profile = profile

    def lift(self) -> RenderResult:
        """The pen left the surface: forget the stroke and stop the output at once."""
        self.tracker.reset()
        self._stop()
        self._last = RenderResult(False, False, None, None, self._off, self._off)
        return self._last

    def feed(self, samples: Iterable[PenSample]) -> RenderResult:
        """Add a batch of samples and drive the output for the newest one."""
        state = self.tracker.extend(samples)
        return self._render(state)

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
        return self._render(self.tracker.state)

    def _stop(self) -> None:
        if self._running and self.output is not None:
            self.output.stop()
        self._running = False
        self._sent = None

    def _render(self, state: StrokeState | None) -> RenderResult:
        if state is None:
            # Every sample so far was rejected: nothing is known about the pen.
            self._stop()
            self._last = RenderResult(True, False, None, None, self._off, self._off)
            return self._last
        feat = self.texture_map.lookup(state.x_m, state.y_m)
        if feat is None:
            self._stop()
            self._last = RenderResult(True, False, state, None, self._off, self._off)
            return self._last
        drive = self.profile.drive(feat, state.speed_m_s, state.direction_rad, state.pressure)
        requested = self.splitter(drive, self.channels, state)
        if all(d.is_off for d in requested):
            self._stop()
            applied = self._off
        elif self.output is not None:
            now = time.monotonic()
            if self._running and self._sent is not None and now - self._sent_at < self.refresh_s and _close(requested, self._sent[0], self.resend_rel):
                # Imperceptibly different from what the output already plays:
                # spare it (and a serial link) the frame.
                applied = self._sent[1]
            else:
                # Marked running first: if apply fails half-way, the next lift still stops it.
                self._running = True
                applied = list(self.output.apply(requested))
                self._sent, self._sent_at = (requested, applied), now
            self._running = True
        else:
            applied = requested
        self._last = RenderResult(True, True, state, feat, requested, applied)
        return self._last

    def close(self) -> None:
        """Stop the output (the renderer does not own it, so it is not closed)."""
        self.lift()


def _close(a: Sequence[Drive], b: Sequence[Drive], rel: float) -> bool:
    """Every channel's frequency, width and amplitude within ``rel`` of the other's."""
    if rel <= 0 or len(a) != len(b):
        return False
    px = py = None
    for x, y in zip(a, b):
        if x is px and y is py:  # the same pair as the previous channel (one drive on both pins)
            continue
        px, py = x, y
        # Spelled out, no tuples: this runs for every pen batch.
        u, v = x.pulse_frequency_hz, y.pulse_frequency_hz
        if abs(u - v) > rel * max(abs(u), abs(v)):
            return False
        u, v = x.pulse_width_s, y.pulse_width_s
        if abs(u - v) > rel * max(abs(u), abs(v)):
            return False
        u, v = x.amplitude, y.amplitude
        if abs(u - v) > rel * max(abs(u), abs(v)):
            return False
    return True


@dataclass
class _Recorder:
    """An output that only records (for tests and the server's last resort)."""

    channels: int = 2
    applied: list[list[Drive]] = field(default_factory=list)
    stops: int = 0

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        drives = list(channels) + [Drive.off()] * (self.channels - len(channels))
        self.applied.append(drives)
        return drives

    def stop(self) -> None:
        self.stops += 1

    def close(self) -> None:
        self.stop()

    def __enter__(self) -> "_Recorder":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
