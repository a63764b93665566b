"""The host half of the self-sensing loop: the board's measurements into the
host's :class:`~tactilize.actuators.sma.WireController`, its decisions back as
HOLD frames.

The board (``tactilize/firmware/tactile_wire.py``) samples each channel's sense
current and supply rail during its pulses and bias, reports the wire's
resistance and current (SENSE_REPLY), and between host messages keeps the heat
the host last asked for: the pulse width is the host's heat per pulse over the
heat the circuit delivers now (``I^2 R``, measured), the bias likewise.  The
*rules* (felt band, standby bias, the PI loop on the period-mean martensite
fraction, the envelope) stay in one place, :class:`WireController`, closed here
on the board's measurements exactly as the simulated output closes it on the
model's (docs/references.md, section 8 (self-sensing)).

Units: SI (s, J, W, ohm, A).
"""

from __future__ import annotations

from typing import Sequence

from ..drive import Drive
from . import frames as P
from .sma import ControllerState, SafetyEnvelope, WireController

__all__ = ["SensedLoop", "fault_text"]

#: A HOLD is resent when its heat or target moves by more than this fraction.
RESEND_FRACTION = 0.05


class SensedLoop:
    """One :class:`WireController` per channel (closed loop), fed from SENSE replies.

    Parameters
    ----------
    envelope : SafetyEnvelope
        The wire, circuit and envelope of the board.
    channels : int
        Number of channels.
    """

    def __init__(self, envelope: SafetyEnvelope, channels: int = 2) -> None:
        self.controllers = [
            WireController(envelope.spec, envelope.circuit, envelope, closed_loop=True) for _ in range(channels)
        ]
        self._counts: list[int | None] = [None] * channels
        self._seen_s: list[float | None] = [None] * channels
        self._sent: list[tuple[float, float, float] | None] = [None] * channels
        #: the latest SENSE_REPLY
        self.report: P.SenseReport | None = None

    def command(self, drives: Sequence[Drive], now_s: float) -> None:
        """New drives from the host's caller (off: the pen lifted, standby)."""
        for ctrl, d in zip(self.controllers, drives):
            ctrl.command(d, now_s)

    def stop(self) -> None:
        for ctrl in self.controllers:
            ctrl.stop()
        self.forget()

    def forget(self) -> None:
        """The board lost its holds (stop, reconnect): send them all again."""
        self._sent = [None] * len(self.controllers)

    def observe(self, report: P.SenseReport, now_s: float) -> None:
        """A SENSE_REPLY at ``now_s`` [s]: each channel's new measurement, if any."""
        self.report = report
        for i, (ctrl, s) in enumerate(zip(self.controllers, report.channels)):
            last, self._seen_s[i] = self._seen_s[i], now_s
            if s.count == self._counts[i] or s.resistance_ohm <= 0 or s.current_a <= 0:
                continue
            if report.faults is not None and report.faults[i]:
                continue  # the board flags this reading: it describes no wire
            self._counts[i] = s.count
            dt = now_s - last if last is not None else 0.0
            ctrl.observe(s.resistance_ohm, s.current_a, max(dt, 1e-4), now_s)

    def holds(self, now_s: float) -> list[tuple[int, float, float, float]]:
        """Update every controller at ``now_s`` [s]; the HOLD requests
        ``(channel, pulse heat [J], bias heat [W], target resistance [ohm])`` whose
        values changed enough to resend."""
        out = []
        for i, ctrl in enumerate(self.controllers):
            ctrl.update(now_s)
            energy = ctrl.plan(ctrl.drive).energy_j if ctrl.pulses_on else 0.0
            bias_w = ctrl.bias_level * ctrl.on_power_w
            target = ctrl.spec.resistance_at(ctrl.setpoint) if ctrl.state == ControllerState.VIBRATING else 0.0
            if ctrl.state == ControllerState.OFF:
                energy = bias_w = target = 0.0
            # What the board's own energy limit leaves the bias (a warming burst
            # becomes the largest bias the board allows).
            env = ctrl.envelope
            f = ctrl.drive.pulse_frequency_hz if ctrl.pulses_on else 0.0
            room = (env.budget_k - energy / env.spec.heat_capacity_j_k) * env.spec.conductance_w_k - f * energy
            bias_w = min(bias_w, 0.99 * max(0.0, room))
            hold = (energy, bias_w, target)
            if _moved(self._sent[i], hold):
                self._sent[i] = hold
                out.append((i, *hold))
        return out


def fault_text(faults: Sequence[bool] | None) -> str | None:
    """One line naming the channels whose sense path the board flags faulty, or None."""
    if not faults or not any(faults):
        return None
    which = ", ".join(str(i) for i, bad in enumerate(faults) if bad)
    return f"sense fault on channel {which}: the controller limits it with the circuit's worst case"


def _moved(old: tuple[float, ...] | None, new: tuple[float, ...]) -> bool:
    if old is None:
        return True
    return any(abs(a - b) > RESEND_FRACTION * max(abs(a), abs(b)) for a, b in zip(old, new))
