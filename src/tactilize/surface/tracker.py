"""Stroke speed and direction from the pen samples' own timestamps.

Directions are counter-clockwise from +x with y pointing *up* (the frame of
``TextureFeatures.orientation_deg`` and ``Profile.drive``), so a stroke moving
up the screen has direction +pi/2; positions keep the samples' y-down frame.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import deque
from itertools import islice
from operator import attrgetter, mul
from typing import Iterable, NamedTuple

from .samples import PenSample, is_trackable

__all__ = ["StrokeState", "StrokeTracker"]

_time = attrgetter("t_s")


def _dot(a: list[float], b: list[float]) -> float:
    """Sum of the products a[i] * b[i], in order (a 1 kHz pen puts ~30 samples in the fit)."""
    return sum(map(mul, a, b), 0.0)


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
    (published texture renderers budget ~40 ms end to end: docs/references.md,
    section 3).

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
        # The accepted samples of the current stroke, oldest first; timestamps
        # increase strictly (add() drops the rest).
        self._buf: deque[PenSample] = deque(maxlen=int(max_samples))
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
        if not is_trackable(sample):
            self.counts["invalid"] += 1
            return False
        buf = self._buf
        if not buf:
            self._start(sample)
            return True
        t_s = sample.t_s
        cand = self._candidate
        last = cand if cand is not None else buf[-1]
        dt = t_s - last.t_s
        if dt <= 0:
            if dt == 0 and sample.x_m == last.x_m and sample.y_m == last.y_m:
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
        if self._speed_between(buf[-1], sample) > self.max_speed_m_s:
            self._candidate = sample
            return False
        return self._append(sample)

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
        """Begin a new stroke at ``sample``."""
        self._buf.clear()
        self._candidate = None
        self._buf.append(sample)
        self.counts["accepted"] += 1
        self._dirty = False
        self._state = StrokeState(sample.t_s, sample.x_m, sample.y_m, 0.0, None, sample.pressure, 1)

    def _append(self, sample: PenSample) -> bool:
        """Add ``sample`` to the current stroke (its time and speed were checked)."""
        self._buf.append(sample)
        self.counts["accepted"] += 1
        self._dirty = True
        return True

    def _fit(self) -> StrokeState:
        """Least-squares velocity through the window's samples."""
        buf = self._buf
        newest = buf[-1]
        window = list(islice(buf, self._window_start(), len(buf)))
        m = len(window)
        # Relative to the newest sample: the subtraction stays exact for
        # timestamps of any origin (a page's clock runs for days), and a pen
        # that stays on one pixel has all its positions exactly 0: speed 0.
        ts = [s.t_s - newest.t_s for s in window]
        t_mean = sum(ts) / m
        dts = [t - t_mean for t in ts]
        stt = _dot(dts, dts)
        if stt > 0:
            vx = _dot(dts, [s.x_m - newest.x_m for s in window]) / stt
            vy = _dot(dts, [s.y_m - newest.y_m for s in window]) / stt
        else:  # one sample: no velocity yet
            vx = vy = 0.0
        speed = math.hypot(vx, vy)
        # y is down on screen, up in the direction frame: flip its sign.
        direction = math.atan2(-vy, vx) if speed > self.still_speed_m_s else None
        return StrokeState(newest.t_s, newest.x_m, newest.y_m, speed, direction, newest.pressure, m)

    def _window_start(self) -> int:
        """Index in the stroke of the first sample to fit."""
        buf = self._buf
        newest = buf[-1]
        n = len(buf)
        # The samples of the last window_s (timestamps increase within a stroke)...
        start = bisect_left(buf, newest.t_s - self.window_s, key=_time)
        # ...but at least min_samples (all of this stroke)...
        start = max(0, min(start, n - self.min_samples))
        # ...and on a slow stroke more, until they span min_travel_m (up to max_window_s).
        while start > 0 and buf[start - 1].t_s >= newest.t_s - self.max_window_s:
            first = buf[start]
            if abs(newest.x_m - first.x_m) + abs(newest.y_m - first.y_m) >= self.min_travel_m:
                break
            start -= 1
        return start
