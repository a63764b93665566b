"""Two channels, the pen's two actuators: phantom sensation and apparent movement.

:func:`pen_channels` places a phantom actuator by the energy model
``A1 = sqrt(1 - beta) Av, A2 = sqrt(beta) Av`` with ``beta`` from the stroke
direction; :class:`PenStream` renders both channels, either as that phantom
(continuous) or as apparent movement: bursts of ``burst_s`` on the leading
channel, then on the other one stimulus-onset-asynchrony ``SOA = 0.32 d + 47.3 ms``
later (:func:`soa_s`), the leading channel chosen by the stroke direction [1]_.

References
----------
.. [1] docs/references.md, section 4 (phantom sensation, apparent movement).
"""

from __future__ import annotations

import math

import numpy as np

from ..drive import Drive
from ..errors import SignalError, check_finite
from .trains import DEFAULT_SAMPLE_RATE_HZ, PulseStream, _check_drive, _check_rate, _round

__all__ = ["PenStream", "pen_channels", "pen_pulse_trains", "phantom_amplitudes", "phantom_beta", "soa_s"]

#: SOA = 0.32 d + 47.3 ms (Israr and Poupyrev 2011): docs/references.md, section 4 (apparent movement).
SOA_SLOPE = 0.32
SOA_OFFSET_S = 47.3e-3

def phantom_amplitudes(beta: float, amplitude: float = 1.0) -> tuple[float, float]:
    """Energy model of the phantom sensation [1]_.

    Parameters
    ----------
    beta : float
        Position of the virtual actuator in [0, 1] (0: on actuator 1, 1: on 2).
    amplitude : float
        Its intensity A_v.

    Returns
    -------
    (A1, A2) : tuple of float
        ``sqrt(1 - beta) A_v`` and ``sqrt(beta) A_v``, so ``A1^2 + A2^2 = A_v^2``.

    References
    ----------
    .. [1] docs/references.md, section 4 (phantom sensation).
    """
    if not math.isfinite(beta) or not 0.0 <= beta <= 1.0:
        raise SignalError("<beta>", f"phantom position must be in [0, 1], got {beta!r}")
    return math.sqrt(1.0 - beta) * amplitude, math.sqrt(beta) * amplitude


def phantom_beta(direction_rad: float, axis_rad: float = 0.0) -> float:
    """Phantom position from a stroke direction [rad]: ``(1 + cos(direction - axis)) / 2``.

    ``axis_rad`` is the direction from actuator 1 to actuator 2 in the same frame
    as the stroke; stroking along it puts the sensation on actuator 2, against
    it on actuator 1, across it halfway.
    """
    if not math.isfinite(direction_rad) or not math.isfinite(axis_rad):
        raise SignalError("<direction>", f"direction must be finite, got {direction_rad!r}")
    return min(1.0, max(0.0, 0.5 * (1.0 + math.cos(direction_rad - axis_rad))))


def soa_s(burst_s: float) -> float:
    """Stimulus onset asynchrony [s] for apparent movement: 0.32 d + 47.3 ms [1]_.

    Validated for bursts of 40 .. 160 ms; outside that range the law is extrapolated.

    References
    ----------
    .. [1] docs/references.md, section 4 (apparent movement).
    """
    check_finite(burst_s, "<burst>", what="burst duration", error=SignalError, above=0.0, unit="s")
    return SOA_SLOPE * burst_s + SOA_OFFSET_S


def pen_channels(drive: Drive, direction_rad: float | None = None, *, axis_rad: float = 0.0) -> list[Drive]:
    """The two actuators' drives for a stroke direction (phantom sensation).

    Parameters
    ----------
    drive : Drive
        The texture's drive; its amplitude is the phantom's intensity A_v.
    direction_rad : float, optional
        Stroke direction [rad].  None (no stroke direction known): both
        actuators get the drive unchanged, as in the paper's pen.
    axis_rad : float
        Direction from actuator 1 to actuator 2 [rad] (see :func:`phantom_beta`).

    Returns
    -------
    list of two Drive
        Same frequency and width; amplitudes by the energy model.
    """
    _check_drive(drive)
    if direction_rad is None:
        return [drive, drive]
    a1, a2 = phantom_amplitudes(phantom_beta(direction_rad, axis_rad), drive.amplitude)
    return [drive.replace(amplitude=min(1.0, a1)), drive.replace(amplitude=min(1.0, a2))]


class PenStream:
    """Two phase-continuous channels for the pen's two actuators.

    Parameters
    ----------
    sample_rate_hz : float
        Samples per second [Hz].
    mode : {"phantom", "movement"}
        ``phantom``: both channels play continuously with amplitudes from
        :func:`pen_channels`.  ``movement``: apparent movement: each channel plays
        bursts of ``burst_s`` at the full drive; the trailing channel's burst
        starts :func:`soa_s` after the leading one's; one cycle lasts SOA + burst.
        The leading channel is actuator 1 when the stroke goes along ``axis_rad``
        (cos >= 0), actuator 2 otherwise; with no direction, actuator 1 leads.
    burst_s : float
        Burst duration d [s] for ``movement`` (the SOA law holds for 40 .. 160 ms).
    axis_rad : float
        Direction from actuator 1 to actuator 2 [rad].
    """

    def __init__(
        self,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        *,
        mode: str = "phantom",
        burst_s: float = 0.1,
        axis_rad: float = 0.0,
    ) -> None:
        if mode not in ("phantom", "movement"):
            raise SignalError("<mode>", f"two-channel mode must be 'phantom' or 'movement', got {mode!r}")
        self.mode = mode
        self.burst_s = float(burst_s)
        self.soa_s = soa_s(self.burst_s)
        self.axis_rad = float(axis_rad)
        self.streams = [PulseStream(sample_rate_hz), PulseStream(sample_rate_hz)]
        fs = self.streams[0].sample_rate_hz
        self._burst = max(1, _round(self.burst_s * fs))
        self._soa = _round(self.soa_s * fs)
        self._cycle = self._soa + self._burst
        self._drive = Drive.off()
        self._lead = 0

    @property
    def sample_rate_hz(self) -> float:
        return self.streams[0].sample_rate_hz

    @property
    def position(self) -> int:
        return self.streams[0].position

    def set_drive(self, drive: Drive, direction_rad: float | None = None) -> list[Drive]:
        """Set the texture drive and stroke direction; returns the per-channel drives
        (for ``movement``: the drive each channel plays during its bursts)."""
        _check_drive(drive)
        if self.mode == "phantom":
            chans = pen_channels(drive, direction_rad, axis_rad=self.axis_rad)
            for s, d in zip(self.streams, chans):
                s.set_drive(d)
            return chans
        self._drive = drive
        if direction_rad is not None:
            self._lead = 0 if math.cos(direction_rad - self.axis_rad) >= 0 else 1
        self._apply_gates(self.position)
        return [drive, drive]

    def _gate(self, channel: int, pos: int) -> bool:
        offset = 0 if channel == self._lead else self._soa
        return (pos - offset) % self._cycle < self._burst

    def _apply_gates(self, pos: int) -> None:
        for c, s in enumerate(self.streams):
            s.set_drive(self._drive if self._gate(c, pos) else Drive.off())

    def render(self, n_samples: int) -> np.ndarray:
        """The next ``n_samples`` frames, shape (n, 2), float32."""
        n = int(n_samples)
        if n < 0:
            raise SignalError("<block>", f"block length must be >= 0, got {n_samples!r}")
        out = np.zeros((n, 2), dtype=np.float32)
        if self.mode == "phantom":
            # Write each channel straight into its column: no interleaving copy.
            self.streams[0].render(n, out[:, 0])
            self.streams[1].render(n, out[:, 1])
            return out
        done = 0
        while done < n:
            pos = self.position
            # Split the block at the next gate edge of either channel.
            step = n - done
            for c in (0, 1):
                offset = 0 if c == self._lead else self._soa
                phase = (pos - offset) % self._cycle
                to_edge = self._burst - phase if phase < self._burst else self._cycle - phase
                step = min(step, to_edge)
            self._apply_gates(pos)
            self.streams[0].render(step, out[done : done + step, 0])
            self.streams[1].render(step, out[done : done + step, 1])
            done += step
        return out


def pen_pulse_trains(
    drive: Drive,
    duration_s: float,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    direction_rad: float | None = None,
    *,
    mode: str = "phantom",
    burst_s: float = 0.1,
    axis_rad: float = 0.0,
) -> np.ndarray:
    """Both channels of the pen for a steady drive, shape (N, 2) float32 (see :class:`PenStream`)."""
    fs = _check_rate(sample_rate_hz)
    check_finite(duration_s, "<duration>", error=SignalError, minimum=0.0, unit="s")
    s = PenStream(fs, mode=mode, burst_s=burst_s, axis_rad=axis_rad)
    s.set_drive(drive, direction_rad)
    return s.render(_round(duration_s * fs))
