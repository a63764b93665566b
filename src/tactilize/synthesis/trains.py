"""Pulse trains: one-shot arrays and a streaming, phase-continuous synthesiser.

A pulse train is the paper's drive signal [1]_: rectangular pulses
of width ``p_w`` [s] repeated at ``f_p`` [Hz], height = the drive's amplitude.

Sample resolution, exactly
--------------------------
Pulse ``k`` starts at sample ``floor((phase_s + k / f) * fs + 0.5)`` (rounded
half up) and lasts ``max(1, floor(width * fs + 0.5))`` samples when the width is
nonzero.  So the count of pulses in a buffer and every width are exact at sample
resolution, and the schedule never drifts (positions are computed from the pulse
index, not accumulated).  A width that would make two pulses touch is refused
(:class:`~tactilize.errors.SignalError`): touching pulses would be one long pulse.

Streaming rules (:class:`PulseStream`)
--------------------------------------
``set_drive`` may be called between any two ``render`` calls; a drive equal to
the current one changes nothing (the schedule keeps its phase).  Otherwise:

1. A pulse in progress completes with the width and amplitude it started with:
   never truncated, never stretched.
2. The next pulse starts at ``max(previous start + new period, now,
   previous end + 1 sample)``: never sooner than the new period after the
   previous start (no doubled pulse), never in the past, always with a gap.
   When nothing has pulsed yet it starts now; after an off drive, the same rule
   (so switching off and on quickly cannot double a pulse either).
3. From there the new drive's schedule runs exactly as :func:`pulse_train` would.

Positions are exact (fractional) and rounded half up when a pulse starts, so at
sample resolution two starts are at least ``floor(period * fs)`` samples apart,
the same spacing a steady train has.

Irregular textures
------------------
A drive whose ``regularity`` is below 1 (a noisy, non-periodic surface) has its
pulses moved from their places on the even grid: pulse ``k`` starts at
``(k + j u_k) / f`` with ``u_k`` uniform in [-1/2, 1/2) from a seeded table and
``j = JITTER_MAX_PERIODS (1 - regularity)`` periods (less when the pulses would
otherwise touch).  The positions stay locked to the grid, so the mean frequency is
exactly the drive's and nothing drifts; the intervals between pulses vary with a
coefficient of variation ``j / sqrt(6)`` (0.245 at regularity 0).  The same seed
gives the same train, in one piece or block by block.


References
----------
.. [1] docs/references.md, section 1 (drive signal).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SignalError, check_finite
from ..drive import JITTER_MAX_PERIODS, JITTER_TABLE, Drive, jitter_periods, jitter_table

__all__ = [
    "pulse_train",
    "PulseScheduler",
    "PulseStream",
    "jitter_periods",
    "JITTER_MAX_PERIODS",
    "DEFAULT_SAMPLE_RATE_HZ",
]

#: What sound-card haptics rigs play: docs/references.md, section 6 (WAV at 48 kHz).
DEFAULT_SAMPLE_RATE_HZ = 48_000


_JITTER_TABLE = JITTER_TABLE
_jitter_table = jitter_table  # the one jitter rule lives beside Drive (drive.py)


def _round(x: float) -> int:
    """Round half up (the rule the docstring promises, unlike banker's rounding)."""
    return int(math.floor(x + 0.5))


def _check_rate(sample_rate_hz: float) -> float:
    return check_finite(sample_rate_hz, "<sample rate>", error=SignalError, above=0.0, unit="Hz")


def _check_drive(drive: Drive) -> Drive:
    if not isinstance(drive, Drive):
        raise SignalError("<drive>", f"expected a Drive, got {type(drive).__name__}")
    return drive


def _geometry(drive: Drive, fs: float) -> tuple[float, int]:
    """(period in samples, width in samples) of a drive that is on; refuses touching pulses."""
    period = fs / drive.pulse_frequency_hz
    width = max(1, _round(drive.pulse_width_s * fs))
    if width >= math.floor(period):
        raise SignalError(
            "<drive>",
            f"pulses of {drive.pulse_width_s * 1e3:g} ms at {drive.pulse_frequency_hz:g} Hz leave no gap "
            f"at {fs:g} samples/s (width {width} samples, period {period:.2f} samples)",
        )
    return period, width


def _fill(n: int, starts: np.ndarray, ends: np.ndarray, amplitude: float, out: np.ndarray | None = None) -> np.ndarray:
    """Rectangles [start, end) of one amplitude into a float32 buffer (starts/ends clipped)."""
    width = int(ends[0] - starts[0]) if starts.size else 0
    if starts.size and starts.size * width <= n and bool(np.all(ends - starts == width)):
        # Sparse pulses (the usual case: duty of a few per cent): index the on-samples.
        idx = (starts[:, None] + np.arange(width)).ravel()
        idx = idx[(idx >= 0) & (idx < n)]
        if out is None:
            out = np.zeros(n, dtype=np.float32)
        out[idx] = amplitude
        return out
    s = np.clip(starts, 0, n)
    e = np.clip(ends, 0, n)
    edges = np.bincount(s, minlength=n + 1)[: n + 1].astype(np.int32) - np.bincount(e, minlength=n + 1)[: n + 1]
    on = np.cumsum(edges[:n]) > 0
    if out is None:
        return on.astype(np.float32) * np.float32(amplitude)
    out[on] = amplitude
    return out


def pulse_train(
    drive: Drive,
    duration_s: float,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    *,
    phase_s: float = 0.0,
    seed: int = 0,
) -> np.ndarray:
    """The pulse train of a drive as a sampled signal.

    Parameters
    ----------
    drive : Drive
        Pulse frequency [Hz], width [s] and amplitude (the height, in [0, 1]).
    duration_s : float
        Length [s]; the buffer has ``round(duration_s * sample_rate_hz)`` samples.
    sample_rate_hz : float
        Samples per second [Hz].
    phase_s : float
        Pulse starts are at ``phase_s + k / f`` [s] for every integer ``k``: the
        buffer is a window on an endless train, so a pulse that began before 0
        shows its remaining samples.
    seed : int
        Seed of the jitter of an irregular drive (see "Irregular textures").

    Returns
    -------
    ndarray of float32, shape (N,)
        ``amplitude`` during pulses, 0 elsewhere.
    """
    _check_drive(drive)
    fs = _check_rate(sample_rate_hz)
    check_finite(duration_s, "<duration>", error=SignalError, minimum=0.0, unit="s")
    check_finite(phase_s, "<phase>", error=SignalError, unit="s")
    n = _round(duration_s * fs)
    if drive.is_off or n == 0:
        return np.zeros(n, dtype=np.float32)
    period, width = _geometry(drive, fs)
    offset = phase_s * fs
    k0 = math.floor((-offset - width) / period) - 1
    k1 = math.ceil((n - offset) / period) + 1
    k = np.arange(k0, k1 + 1, dtype=np.int64)
    j = jitter_periods(drive, period, width)
    place = k + j * _jitter_table(seed)[k % _JITTER_TABLE] if j else k.astype(np.float64)
    starts = np.floor(offset + place * period + 0.5).astype(np.int64)
    keep = (starts < n) & (starts + width > 0)
    starts = starts[keep]
    return _fill(n, starts, starts + width, drive.amplitude)


# --------------------------------------------------------------------------- streaming


class PulseScheduler:
    """When pulses start, block by block, under drive changes (rules in the module docstring).

    Time is counted in samples of ``sample_rate_hz``; :class:`PulseStream` turns
    the schedule into audio-rate buffers, the simulated wire uses it at 1 MHz to
    get pulse edges in microseconds.

    Parameters
    ----------
    sample_rate_hz : float
        Resolution of the schedule [Hz].
    seed : int
        Seed of the jitter of irregular drives.
    """

    def __init__(self, sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ, seed: int = 0) -> None:
        self.sample_rate_hz = _check_rate(sample_rate_hz)
        self._table = _jitter_table(int(seed))
        self._j = 0.0  # jitter depth of the current drive [periods]
        # Jitter table index of the current drive's pulse 0: it runs on across drive
        # changes (a pen changes the drive every few pulses), so the pattern does not
        # restart, and repeat, at every change.
        self._base = 0
        self._first_lead = 0.0  # how much of pulse 0's jitter applies (only its delay)
        self.position = 0  # absolute sample index of the next block
        self._drive = Drive.off()
        self._period = math.inf
        self._width = 0
        self._anchor = 0.0  # exact (fractional) sample of schedule pulse 0
        self._k = 0  # index of the next pulse in the schedule
        self._last_start: float | None = None  # exact position of the last pulse start
        self._last_end = -1  # sample after the last pulse

    @property
    def drive(self) -> Drive:
        return self._drive

    def set_drive(self, drive: Drive) -> None:
        """Change the drive from the current position on (takes effect at the next pulse start)."""
        _check_drive(drive)
        if drive == self._drive:
            return
        if drive.is_off:
            self._drive, self._period, self._width = drive, math.inf, 0
            return
        period, width = _geometry(drive, self.sample_rate_hz)
        nxt = float(self.position)
        if self._last_start is not None:
            nxt = max(nxt, self._last_start + period)
        nxt = max(nxt, float(self._last_end + 1) if self._last_start is not None else nxt)
        # Pulse 0 of the new schedule must not move before ``nxt`` (the rule above):
        # its jitter only delays it, and not at all after silence (a touch is felt at once).
        self._first_lead = 0.0 if self._drive.is_off or self._last_start is None else 1.0
        self._drive, self._period, self._width = drive, period, width
        self._j = jitter_periods(drive, period, width)
        self._base += self._k
        self._anchor, self._k = nxt, 0

    def _place(self, k: int) -> float:
        """Pulse ``k``'s place on the current schedule [periods from the anchor]."""
        if not self._j:
            return float(k)
        u = self._table[(self._base + k) % _JITTER_TABLE]
        if k == 0:
            u = max(u, 0.0) * self._first_lead
        return k + self._j * u

    def next_block(self, n: int) -> tuple[np.ndarray | list[int], int, float]:
        """Pulses starting in the next ``n`` samples; advances the position.

        Returns
        -------
        starts : list of int or ndarray of int64
            Start samples relative to the block start (a list when there are
            only a few: small audio blocks must not pay numpy's overhead).
        width : int
            Width of each of them [samples].
        amplitude : float
            Their height.
        """
        pos, end = self.position, self.position + n
        self.position = end
        if self._width == 0 or n <= 0:
            return [], 0, 0.0
        a, P, k, j = self._anchor, self._period, self._k, self._j
        first = math.floor(a + self._place(k) * P + 0.5)
        if first >= end:
            return [], self._width, self._drive.amplitude
        m = int((end - first) / P) + 2
        if m <= 64:
            few = []
            while True:
                place = self._place(k)
                st = math.floor(a + place * P + 0.5)
                if st >= end:
                    break
                few.append(st - pos)
                last = place
                k += 1
            self._k = k
            self._last_start = a + last * P
            self._last_end = few[-1] + pos + self._width
            return few, self._width, self._drive.amplitude
        kk = k + np.arange(m, dtype=np.int64)
        if j:
            places = kk + j * self._table[(self._base + kk) % _JITTER_TABLE]
            if k == 0:
                places[0] = self._place(0)
        else:
            places = kk.astype(np.float64)
        starts = np.floor(a + places * P + 0.5).astype(np.int64)
        keep = starts < end
        starts = starts[keep]
        self._k = k + starts.size
        self._last_start = a + float(places[keep][-1]) * P
        self._last_end = int(starts[-1]) + self._width
        return starts - pos, self._width, self._drive.amplitude


class PulseStream:
    """A phase-continuous pulse-train synthesiser rendered block by block.

    Parameters
    ----------
    sample_rate_hz : float
        Samples per second [Hz].
    drive : Drive, optional
        The initial drive (off by default).

    Examples
    --------
    >>> s = PulseStream(48_000, Drive(100.0, 1e-3))
    >>> block = s.render(480)          # 10 ms: exactly one pulse of 48 samples
    >>> s.set_drive(Drive(200.0, 5e-4))  # from the next pulse start on
    """

    def __init__(self, sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ, drive: Drive | None = None) -> None:
        self._sched = PulseScheduler(sample_rate_hz)
        self._carry = 0  # samples of the current pulse still to play
        self._carry_amp = 0.0
        if drive is not None:
            self.set_drive(drive)

    @property
    def sample_rate_hz(self) -> float:
        return self._sched.sample_rate_hz

    @property
    def position(self) -> int:
        """Samples rendered so far."""
        return self._sched.position

    @property
    def drive(self) -> Drive:
        return self._sched.drive

    def set_drive(self, drive: Drive) -> None:
        """Change the drive; see the streaming rules in the module docstring."""
        self._sched.set_drive(drive)

    def render(self, n_samples: int, out: np.ndarray | None = None) -> np.ndarray:
        """The next ``n_samples`` samples (float32).

        ``out``, when given, is a zeroed 1-D buffer (it may be a strided column
        of a frames array) that receives the samples and is returned.
        """
        n = int(n_samples)
        if n < 0:
            raise SignalError("<block>", f"block length must be >= 0, got {n_samples!r}")
        if out is None:
            out = np.zeros(n, dtype=np.float32)
        if self._carry > 0:
            c = min(self._carry, n)
            out[:c] = self._carry_amp
            self._carry -= c
        starts, width, amp = self._sched.next_block(n)
        if len(starts) == 0:
            return out
        if isinstance(starts, list):
            for st in starts:
                out[st : st + width] = amp
        else:
            _fill(n, starts, starts + width, amp, out)
        tail = int(starts[-1]) + width - n
        if tail > 0:
            self._carry, self._carry_amp = tail, amp
        return out
