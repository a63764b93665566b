"""Drive over time: what a stroke made, in the form every export reads.

A :class:`DriveTimeline` is a list of rows, one per rendered pen batch (a
display frame, as on the pen server), each holding the drive every channel got
from then until the next row.  Two drives are kept per row and channel:

``profile``
    What the profile asked for (after the profile's own limits): the texture's
    intended pulse train.  Phone and player formats carry this one, because
    their actuators (LRAs, voice coils) have none of the SMA wire's narrow
    felt band; the wire's width and current would misdescribe the texture there.
``wire``
    What the output applied: on the simulated SMA wire, the operating-point
    controller's pulse width and switch level within the safety envelope
    (:meth:`tactilize.actuators.simulated.SimulatedOutput.apply`).  Exported
    with ``drive="wire"``, for rigs that replay the pen's own wire.

Phone formats sample the timeline on a control grid (:func:`control_points`)
and drop points a straight line already gives (frequency within 0.5 %,
amplitude within 0.01), so every kept point is exact and the round trip holds
to the round-trip tolerances (frequency 1 %, amplitude 2 %).

Intensity and sharpness are as in :mod:`.ahap`: the train's fundamental
relative to a 10 % duty train, and frequency over 65..300 Hz.

References
----------
.. [1] docs/references.md, section 6 (AHAP sharpness and frequency).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..drive import Drive
from ..errors import SignalError
from ..synthesis import PulseScheduler, PulseStream

__all__ = [
    "DriveTimeline",
    "ControlPoint",
    "control_points",
    "intensity_from_drive",
    "sharpness_from_frequency",
    "frequency_from_sharpness",
    "SHARPNESS_LOW_HZ",
    "SHARPNESS_HIGH_HZ",
    "FULL_INTENSITY_DUTY",
    "CONTROL_STEP_S",
    "continuous_spans",
]

#: AHAP sharpness 0..1 is commonly mapped to 65..300 Hz:
#: docs/references.md, section 6 (AHAP sharpness and frequency).
SHARPNESS_LOW_HZ = 65.0
SHARPNESS_HIGH_HZ = 300.0
#: Duty ratio rendered at full intensity (the paper profile's max_duty_ratio).
FULL_INTENSITY_DUTY = 0.10
#: Control grid of the phone formats [s]: Android's shortest envelope segment,
#: docs/references.md, section 6 (Android envelopes).
CONTROL_STEP_S = 0.020


def sharpness_from_frequency(frequency_hz: float) -> float:
    """AHAP sharpness in [0, 1] for a vibration frequency [Hz]: linear over 65..300 Hz, clipped."""
    s = (frequency_hz - SHARPNESS_LOW_HZ) / (SHARPNESS_HIGH_HZ - SHARPNESS_LOW_HZ)
    return min(1.0, max(0.0, s))


def frequency_from_sharpness(sharpness: float) -> float:
    """The inverse of :func:`sharpness_from_frequency` [Hz] (exact inside 65..300 Hz)."""
    return SHARPNESS_LOW_HZ + min(1.0, max(0.0, sharpness)) * (SHARPNESS_HIGH_HZ - SHARPNESS_LOW_HZ)


def intensity_from_drive(drive: Drive) -> float:
    """Intensity in [0, 1]: the fundamental of the pulse train relative to ``FULL_INTENSITY_DUTY``.

    A rectangular train of duty D and height A has a fundamental of amplitude
    (2 A / pi) sin(pi D); an LRA or phone motor passes mostly that.
    """
    if drive.is_off:
        return 0.0
    d = min(drive.duty_ratio, 0.5)
    return min(1.0, drive.amplitude * math.sin(math.pi * d) / math.sin(math.pi * FULL_INTENSITY_DUTY))


@dataclass(frozen=True)
class ControlPoint:
    """One point of a phone format's curves.

    Attributes
    ----------
    t_s : float
        Time from the start [s].
    amplitude : float
        Intensity in [0, 1] (:func:`intensity_from_drive`).
    frequency_hz : float
        Pulse frequency [Hz] (0 when off).
    """

    t_s: float
    amplitude: float
    frequency_hz: float


@dataclass(frozen=True)
class Pulse:
    """One pulse of the train: start [s], width [s], height [0..1], the drive it belongs to."""

    t_s: float
    width_s: float
    amplitude: float
    drive: Drive


@dataclass(frozen=True)
class DriveTimeline:
    """Drives over time, per channel, from a stroke (or one steady drive).

    Attributes
    ----------
    t_s : tuple of float
        Start of each row [s]; the first is 0, strictly increasing.
    end_s : float
        End of the last row [s].
    profile : tuple of tuple of Drive
        ``profile[row][channel]``: the profile's drive (see the module docstring).
    wire : tuple of tuple of Drive
        ``wire[row][channel]``: what the output applied (equal to ``profile``
        when no output ran).
    speed_m_s : tuple of float
        The tracker's speed per row [m/s].
    x_m, y_m : tuple of float
        Pen position per row [m] (y down); NaN for a steady drive.
    meta : dict
        What made it (image, profile, stroke file...), for the documents.
    events : tuple of BumpEvent, or None
        The events the stroke's rendering fired (:func:`.events.fired_events`: a steady
        rendering's regular trains, the surface rendering's bumps); None without a stroke
        (a drive held), where the events are the steady rendering's train of each row's
        drive.  The parametric formats play :func:`.events.timeline_events`, which gives either.
    regular : bool
        The events are the rows' drives' own regular trains (a steady rendering's, a drive
        held), so the rows' pulse trains play them (the WAV); False for the surface
        rendering's bumps.
    """

    t_s: tuple[float, ...]
    end_s: float
    profile: tuple[tuple[Drive, ...], ...]
    wire: tuple[tuple[Drive, ...], ...]
    speed_m_s: tuple[float, ...]
    x_m: tuple[float, ...]
    y_m: tuple[float, ...]
    meta: dict[str, Any] = field(default_factory=dict)
    events: tuple[Any, ...] | None = None
    regular: bool = True

    def __post_init__(self) -> None:
        n = len(self.t_s)
        if n == 0 or any(len(a) != n for a in (self.profile, self.wire, self.speed_m_s, self.x_m, self.y_m)):
            raise SignalError("<timeline>", "needs at least one row and one value per row in every column")
        if self.t_s[0] != 0.0 or any(b <= a for a, b in zip(self.t_s, self.t_s[1:])) or not self.end_s > self.t_s[-1]:
            raise SignalError("<timeline>", "row times must start at 0 s, increase, and end after the last row")

    @classmethod
    def steady(cls, drive: Drive | Sequence[Drive], duration_s: float, **meta: Any) -> "DriveTimeline":
        """One drive per channel held for ``duration_s`` [s]."""
        drives = (drive,) if isinstance(drive, Drive) else tuple(drive)
        if not drives or not all(isinstance(d, Drive) for d in drives):
            raise SignalError("<drive>", "expected a Drive or a list of Drives")
        if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
            raise SignalError("<duration>", f"must be a finite number of seconds > 0, got {duration_s!r}")
        nan = math.nan
        return cls((0.0,), float(duration_s), (drives,), (drives,), (nan,), (nan,), (nan,), dict(meta))

    @property
    def channels(self) -> int:
        return len(self.profile[0])

    @property
    def duration_s(self) -> float:
        return self.end_s

    def drives(self, kind: str = "profile", channel: int = 0) -> list[Drive]:
        """One channel's drive per row; ``kind`` is ``"profile"`` or ``"wire"``."""
        rows = self._rows(kind)
        return [r[channel] for r in rows]

    def _rows(self, kind: str) -> tuple[tuple[Drive, ...], ...]:
        if kind == "profile":
            return self.profile
        if kind == "wire":
            return self.wire
        raise SignalError(str(kind), "unknown drive (use 'profile' or 'wire')")

    def index_at(self, t_s: float) -> int:
        """The row in force at time ``t_s`` [s]."""
        return max(0, bisect.bisect_right(self.t_s, t_s) - 1)

    def at(self, t_s: float, kind: str = "profile", channel: int = 0) -> Drive:
        """The drive in force at ``t_s`` [s]."""
        return self._rows(kind)[self.index_at(t_s)][channel]

    def changes(self, kind: str = "profile") -> list[int]:
        """Indices of the rows where any channel's drive differs from the row before."""
        rows = self._rows(kind)
        return [i for i in range(len(rows)) if i == 0 or rows[i] != rows[i - 1]]

    def pulses(self, kind: str = "profile", channel: int = 0, rate_hz: int = 1_000_000) -> list[Pulse]:
        """Every pulse's start, as the streaming synthesiser schedules it.

        The synthesiser's own scheduler at 1 us (``rate_hz``; docs/signals-and-wire.md,
        Pulse trains): phase-continuous across drive changes, and an irregular texture's
        pulses jitter exactly as they do on the wire and in the WAV.
        """
        rate = int(rate_hz)
        sched = PulseScheduler(rate)
        out: list[Pulse] = []
        drives = self.drives(kind, channel)
        bounds = list(self.t_s[1:]) + [self.end_s]
        edges = [int(round(t * rate)) for t in self.t_s] + [int(round(self.end_s * rate))]
        for i, d in enumerate(drives):
            n = edges[i + 1] - edges[i]
            if n <= 0:
                continue
            if sched.position < edges[i]:
                sched.next_block(edges[i] - sched.position)  # nothing was on: catch up
            sched.set_drive(d)
            starts, _, _ = sched.next_block(n)
            for st in (starts if isinstance(starts, list) else starts.tolist()):
                t = (edges[i] + st) / rate
                if t < bounds[i] - 1e-12:
                    out.append(Pulse(t, d.pulse_width_s, d.amplitude, d))
        return out

    def samples(self, sample_rate_hz: int, kind: str = "profile") -> np.ndarray:
        """The pulse trains (n, channels) in [0, 1], by the streaming synthesiser."""
        n_total = int(round(self.end_s * sample_rate_hz))
        out = np.zeros((n_total, self.channels), dtype=np.float32)
        rows = self._rows(kind)
        starts = [int(round(t * sample_rate_hz)) for t in self.t_s] + [n_total]
        for c in range(self.channels):
            stream = PulseStream(sample_rate_hz)
            for i, row in enumerate(rows):
                n = starts[i + 1] - starts[i]
                if n <= 0:
                    continue
                stream.set_drive(row[c])
                out[starts[i] : starts[i + 1], c] = stream.render(n)
        return out

    def log_rows(self, kind: str = "profile") -> list[dict[str, Any]]:
        """One row per drive change: time [s], speed [m/s], position [m], each channel's drive."""
        rows = self._rows(kind)
        out = []
        for i in self.changes(kind):
            r: dict[str, Any] = {"t_s": self.t_s[i], "speed_m_s": self.speed_m_s[i], "x_m": self.x_m[i], "y_m": self.y_m[i]}
            for c, d in enumerate(rows[i]):
                r[f"ch{c}_pulse_frequency_hz"] = d.pulse_frequency_hz
                r[f"ch{c}_pulse_width_s"] = d.pulse_width_s
                r[f"ch{c}_amplitude"] = d.amplitude
                r[f"ch{c}_strength"] = d.strength
                r[f"ch{c}_clamped"] = " ".join(d.clamped)
            out.append(r)
        return out


def _value(d: Drive) -> tuple[float, float]:
    return intensity_from_drive(d), (0.0 if d.is_off else d.pulse_frequency_hz)


def control_points(
    tl: DriveTimeline,
    kind: str = "profile",
    channel: int = 0,
    step_s: float = CONTROL_STEP_S,
    *,
    start_s: float = 0.0,
    end_s: float | None = None,
    freq_rel: float = 0.005,
    amp_abs: float = 0.01,
    max_gap_s: float = 1.0,
) -> list[ControlPoint]:
    """The drive sampled on a grid of ``step_s`` [s], without the points a line already gives.

    Grid times are whole multiples of ``step_s`` from ``start_s``, plus the end;
    a last interval shorter than ``step_s`` is merged into the one before, so
    every interval is at least ``step_s`` (when the span allows) and at most
    ``max_gap_s``.  A point is dropped when the line between its kept
    neighbours gives its frequency within ``freq_rel`` and its amplitude within
    ``amp_abs``, and every dropped point between them too.
    """
    end = tl.end_s if end_s is None else end_s
    n = max(1, int(math.floor((end - start_s) / step_s + 1e-9)))
    times = [start_s + k * step_s for k in range(n)] + [end]
    if len(times) > 2 and times[-1] - times[-2] < step_s - 1e-9:
        del times[-2]
    drives = [tl.at(min(t, end - 1e-9), kind, channel) for t in times]
    pts = [ControlPoint(t, *_value(d)) for t, d in zip(times, drives)]
    return _simplify(pts, freq_rel, amp_abs, max_gap_s)


def _simplify(pts: list[ControlPoint], freq_rel: float, amp_abs: float, max_gap_s: float) -> list[ControlPoint]:
    if len(pts) <= 2:
        return pts
    kept = [pts[0]]
    anchor = 0
    i = 2
    while i < len(pts):
        a, b = pts[anchor], pts[i]
        ok = b.t_s - a.t_s <= max_gap_s + 1e-9
        if ok:
            for m in pts[anchor + 1 : i]:
                u = (m.t_s - a.t_s) / (b.t_s - a.t_s)
                amp = a.amplitude + u * (b.amplitude - a.amplitude)
                fr = a.frequency_hz + u * (b.frequency_hz - a.frequency_hz)
                if abs(amp - m.amplitude) > amp_abs or abs(fr - m.frequency_hz) > freq_rel * max(m.frequency_hz, 1e-9):
                    ok = False
                    break
        if not ok:
            anchor = i - 1
            kept.append(pts[anchor])
        i += 1
    kept.append(pts[-1])
    return kept


def continuous_spans(tl: DriveTimeline, kind: str = "profile", channel: int = 0) -> list[tuple[float, float]]:
    """``(start, end)`` [s] of the runs of rows whose drive is on at 65 Hz or more."""
    drives = tl.drives(kind, channel)
    bounds = list(tl.t_s[1:]) + [tl.end_s]
    spans: list[tuple[float, float]] = []
    for t0, t1, d in zip(tl.t_s, bounds, drives):
        if d.is_off or d.pulse_frequency_hz < SHARPNESS_LOW_HZ:
            continue
        if spans and spans[-1][1] == t0:
            spans[-1] = (spans[-1][0], t1)
        else:
            spans.append((t0, t1))
    return spans
