"""The default output: two simulated SMA wires running in real time on their own thread.

Every drive passes through the wire's safety envelope in :meth:`SimulatedOutput.apply`.
A background thread advances the wire model (:mod:`tactilize.actuators.sma`) by the
wall-clock time elapsed, every ``tick_s``; pulses are scheduled by the same
phase-continuous rules as the audio synthesiser (:class:`~tactilize.synthesis.PulseScheduler`,
here at 1 us resolution), so a drive change never truncates or doubles a pulse.

Recent traces (decimated to ``trace_rate_hz``) stay in ring buffers for the web page:
:meth:`SimulatedOutput.traces` returns plain lists.  The model integrates whole
pulse segments (a few steps per pulse), so two channels at 300 Hz cost well under
1 % of a core.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any, Callable, Sequence

import numpy as np

from ..errors import OutputError
from ..mapping import Drive
from ..synthesis import PulseScheduler
from .base import OutputBase
from .sma import SafetyEnvelope, WireModel, WireSpec, build_envelope

__all__ = ["SimulatedOutput"]

_SCHEDULE_RATE_HZ = 1_000_000  # pulse edges at 1 us


class SimulatedOutput(OutputBase):
    """Simulated SMA wires as an :class:`~tactilize.actuators.base.Output`.

    Parameters
    ----------
    wire : WireSpec or str
        The wire of every channel (a preset name or a spec); the paper's 75 um.
    channels : int
        Number of actuators (the pen has 2).
    envelope : SafetyEnvelope, optional
        Default: :func:`~tactilize.actuators.sma.build_envelope` of the wire.
    trace_seconds : float
        Length of the kept traces [s].
    trace_rate_hz : float
        Trace points per second [Hz]; a pulse shorter than a trace step still
        marks its step with its current (the drive trace is a max, not a mean).
    tick_s : float
        How often the thread advances the model [s]; up to half a tick later
        when it waits for the gap after a pen batch (:meth:`after_batch`).
    start : bool
        Start the real-time thread now; with False, call :meth:`advance` yourself
        (deterministic, for tests and offline use).
    clock : callable
        Monotonic clock in seconds (``time.monotonic``).
    """

    #: amplitude is the wire's pulse current, not felt intensity: scaling it
    #: (e.g. for a phantom sensation) takes the wire out of its vibrating band
    amplitude_is_intensity = False

    def __init__(
        self,
        wire: WireSpec | str | None = None,
        *,
        channels: int = 2,
        envelope: SafetyEnvelope | None = None,
        trace_seconds: float = 5.0,
        trace_rate_hz: float = 2000.0,
        tick_s: float = 0.02,
        start: bool = True,
        clock: Callable[[], float] = time.monotonic,
        **_ignored: Any,
    ) -> None:
        self.spec = WireSpec.resolve(wire)
        if not isinstance(channels, int) or channels < 1:
            raise OutputError("<simulated>", f"channels must be a positive integer, got {channels!r}")
        for name, v in (("trace_seconds", trace_seconds), ("trace_rate_hz", trace_rate_hz), ("tick_s", tick_s)):
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise OutputError("<simulated>", f"{name} must be a finite number > 0, got {v!r}")
        self.channels = channels
        self.envelope = envelope if envelope is not None else build_envelope(self.spec)
        self.tick_s = float(tick_s)
        # Trace steps are whole microseconds so bin edges are exact integers.
        self._bin_us = max(1, int(round(_SCHEDULE_RATE_HZ / trace_rate_hz)))
        self.trace_rate_hz = _SCHEDULE_RATE_HZ / self._bin_us
        self._bin_s = self._bin_us * 1e-6
        self._models = [WireModel(self.spec) for _ in range(channels)]
        self._scheds = [PulseScheduler(_SCHEDULE_RATE_HZ) for _ in range(channels)]
        self._carry_us = [0] * channels
        self._carry_a = [0.0] * channels
        self._drives = [Drive.off()] * channels
        self._lock = threading.RLock()
        self._pending_lock = threading.Lock()  # held for microseconds only
        self._pending: list[Drive] | None = None
        self._t_us = 0  # simulated time [us]
        size = max(2, int(round(trace_seconds * self.trace_rate_hz)))
        self._size = size
        self._count = 0
        self._buf_t = np.zeros(size)
        self._buf = np.zeros((channels, 3, size))  # current, temperature, displacement
        self._clock = clock
        # Set by after_batch(): a time-critical caller just finished (see _loop).
        self._quiet = threading.Event()
        self._running = False
        self._thread: threading.Thread | None = None
        self._closed = False
        if start:
            self.start()

    # -- the Output protocol

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Set every channel's drive (after the envelope); returns the drives applied."""
        if self._closed:
            raise OutputError("<simulated>", "output is closed")
        drives = self._check(channels)
        applied = [d if d.is_off else self.envelope.apply(d) for d in drives]
        self._hand_over(applied)
        return applied

    def stop(self) -> None:
        """Turn every channel off (pulses in progress complete, as on real hardware)."""
        self._hand_over([Drive.off()] * self.channels)

    def _hand_over(self, drives: list[Drive]) -> None:
        # The caller (a pen batch) must never wait for a simulation tick to finish:
        # the drives wait here and the next advance takes them at the simulated
        # instant it starts from, the same instant as if we had waited.
        with self._pending_lock:
            self._pending = drives
            self._drives = list(drives)

    def _take_pending(self) -> None:
        with self._pending_lock:
            pending, self._pending = self._pending, None
        if pending is not None:
            for c, d in enumerate(pending):
                self._scheds[c].set_drive(d)

    def close(self) -> None:
        """Stop, end the thread and wait for it."""
        self.stop()
        self._running = False
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout=5.0)
        self._thread = None
        self._closed = True

    # -- running

    def start(self) -> None:
        """Start the real-time thread (once)."""
        if self._thread is not None:
            return
        self._running = True
        self._thread = threading.Thread(target=self._loop, name="tactilize-simulated-wire", daemon=True)
        self._thread.start()

    def after_batch(self) -> None:
        """Tell the simulation thread that a time-critical step just ended.

        The pen server calls this when a batch's drive has been sent.  The
        thread, once its tick is due, steps the model right then (waiting at
        most half a tick more for it): a step takes a fraction of a millisecond of
        Python, and done in the gap before the next batch it does not hold the
        GIL while a batch is being handled.  Cheap; safe from any thread.
        """
        self._quiet.set()

    def _loop(self) -> None:
        last = self._clock()
        while self._running:
            time.sleep(self.tick_s)
            # Due now; step at the next quiet moment if one comes within half a
            # tick (a longer step integrates exactly as well).
            self._quiet.clear()
            self._quiet.wait(0.5 * self.tick_s)
            now = self._clock()
            # After a stall (suspended laptop) do not try to catch up minutes.
            self.advance(min(now - last, 1.0))
            last = now

    def advance(self, duration_s: float) -> None:
        """Advance every channel by ``duration_s`` [s] of simulated time."""
        n = int(round(duration_s * _SCHEDULE_RATE_HZ))
        if n <= 0:
            return
        with self._lock:
            self._take_pending()
            t0_us = self._t_us
            first = t0_us // self._bin_us + 1
            last = (t0_us + n) // self._bin_us
            bins_t = np.arange(first, last + 1) * self._bin_s
            cols = []
            for c in range(self.channels):
                durations, currents, intervals = self._segments(c, n)
                model = self._models[c]
                rec: list[float] = [model.time_s, model.temperature_c, model.martensite_fraction]
                model.run(durations, currents, record=rec)
                if bins_t.size:
                    nodes = np.asarray(rec).reshape(-1, 3)
                    T = np.interp(bins_t, nodes[:, 0], nodes[:, 1])
                    xi = np.interp(bins_t, nodes[:, 0], nodes[:, 2])
                    cur = np.zeros(bins_t.size)
                    for s_us, e_us, amp in intervals:
                        # Mark every trace step the pulse overlaps.
                        b0 = max(0, (t0_us + s_us) // self._bin_us + 1 - first)
                        b1 = min(bins_t.size - 1, (t0_us + e_us) // self._bin_us + 1 - first)
                        if b1 >= b0:
                            cur[b0 : b1 + 1] = np.maximum(cur[b0 : b1 + 1], amp)
                    cols.append((cur, T, self.spec.displacement_m(xi)))
            self._t_us += n
            if bins_t.size:
                self._push(bins_t, cols)

    def _segments(self, c: int, n: int) -> tuple[list[float], list[float], list[tuple[int, int, float]]]:
        """Constant-current segments [s, A] for the next n us of channel c, and the pulse intervals [us]."""
        durations: list[float] = []
        currents: list[float] = []
        intervals: list[tuple[int, int, float]] = []
        cursor = 0
        if self._carry_us[c] > 0:
            on = min(self._carry_us[c], n)
            durations.append(on * 1e-6)
            currents.append(self._carry_a[c])
            intervals.append((0, on, self._carry_a[c]))
            self._carry_us[c] -= on
            cursor = on
        starts, width, amp = self._scheds[c].next_block(n)
        current = amp * self.spec.rated_current_a
        for s in (starts if isinstance(starts, list) else starts.tolist()):
            if s > cursor:
                durations.append((s - cursor) * 1e-6)
                currents.append(0.0)
            on = min(width, n - s)
            durations.append(on * 1e-6)
            currents.append(current)
            intervals.append((s, s + on, current))
            cursor = s + on
            if s + width > n:
                self._carry_us[c], self._carry_a[c] = s + width - n, current
        if n > cursor:
            durations.append((n - cursor) * 1e-6)
            currents.append(0.0)
        return durations, currents, intervals

    def _push(self, t: np.ndarray, cols: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> None:
        m = t.size
        if m >= self._size:
            t = t[-self._size :]
            cols = [tuple(a[-self._size :] for a in col) for col in cols]
            m = self._size
        idx = (self._count + np.arange(m)) % self._size
        self._buf_t[idx] = t
        for c, (cur, T, d) in enumerate(cols):
            self._buf[c, 0, idx] = cur
            self._buf[c, 1, idx] = T
            self._buf[c, 2, idx] = d
        self._count += m

    # -- reading

    @property
    def time_s(self) -> float:
        """Simulated time so far [s]."""
        return self._t_us * 1e-6

    def traces(self, seconds: float = 2.0) -> dict[str, Any]:
        """The last ``seconds`` of traces as plain lists (JSON-ready).

        Returns
        -------
        dict
            ``time_s`` (simulated time [s]) and ``channels``: one dict per channel
            with ``current_a`` [A] (max over each trace step), ``temperature_c``
            [deg C] and ``displacement_um`` [um], plus ``drive`` (the drive applied).
        """
        with self._lock:
            m = min(self._count, self._size, max(0, int(round(seconds * self.trace_rate_hz))))
            idx = (self._count - m + np.arange(m)) % self._size
            out: dict[str, Any] = {"time_s": self._buf_t[idx].tolist(), "channels": []}
            for c in range(self.channels):
                out["channels"].append(
                    {
                        "current_a": self._buf[c, 0, idx].tolist(),
                        "temperature_c": self._buf[c, 1, idx].tolist(),
                        "displacement_um": (self._buf[c, 2, idx] * 1e6).tolist(),
                        "drive": self._drives[c].to_dict(),
                    }
                )
            return out

    def state(self) -> list[dict[str, Any]]:
        """Each channel's present wire state (temperature [deg C], martensite, displacement [um], drive)."""
        with self._lock:
            return [
                {
                    "temperature_c": m.temperature_c,
                    "martensite_fraction": m.martensite_fraction,
                    "displacement_um": m.displacement_m * 1e6,
                    "drive": d.to_dict(),
                }
                for m, d in zip(self._models, self._drives)
            ]
