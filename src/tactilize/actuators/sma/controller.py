"""The operating-point controller: every stroke felt, at once, whatever the cells and the air do.

A 75 um wire moves only while its mean temperature sits in a band a few kelvin
wide, and the heat that keeps it there (about 6 mW for 3 mm in still air)
must come from somewhere.  The paper's drive gives it all through the texture
pulses, so slow strokes (few, short pulses) leave the wire cold and still, and
the wire needs most of a second to warm after the pen touches.  The paper says
the height H and duty W/L "should be determined based on the calories
exchanged"; this module does that (docs/references.md, sections 2 and 8).

What it decides, per channel
----------------------------
* The pulse *frequency* is the profile's, exactly.
* The heat of each pulse is a position inside the wire's **felt band** at that
  frequency (:meth:`WireController.band_j`): from the least heat that moves the
  pin :data:`~tactilize.actuators.sma.simulate.FOLLOW_THRESHOLD_M` every pulse,
  to the most that still leaves the rest of the holding heat to the bias (so the
  wire cannot run hot and stay contracted).  The drive's ``strength`` (from the
  profile's width law, :meth:`Profile.drive`) times its ``amplitude`` is that
  position, spaced geometrically: amplitude discrimination goes in decibels
  (docs/references.md, section 3 (amplitude discrimination)).  A drive without a strength is placed where
  its own heat falls, clipped into the band.
* A **standby bias** (the switch chopped at tens of kHz, far too fast for the
  wire to follow) supplies the rest of the holding heat.  While the pen is down
  or hovering, and for ``standby_s`` after it lifts, the bias holds the wire
  just below A_s; texture pulses ride on top.  Then the output goes fully off.
* **Warming**: when a drive arrives and the resistance says the wire is still
  martensite, the switch stays on until the resistance says the band is
  reached (a few milliseconds from standby); the first texture pulse follows at
  once.  Each burst is short and starts from a wire the resistance bounds below
  A_f, so the envelope's per-burst bound holds (:meth:`SafetyEnvelope.max_boost_j`).
* **Closed loop**: the wire's resistance (and the current, from the sense
  resistor) measured during each pulse give its martensite fraction and the heat
  actually delivered; a PI loop on the period-mean martensite fraction sets the
  holding heat, so the band holds when the cells sag and when the air is 15 or
  35 C.  Open loop (``closed_loop=False``) trusts the nominal circuit and air,
  and loses the band when either changes.

Everything it asks of the circuit passes the :class:`SafetyEnvelope` first.

Units: SI (W, J, s, ohm, A); temperatures in degrees Celsius.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import StrEnum

from ...drive import Drive
from .circuit import Circuit
from .envelope import SafetyEnvelope, build_envelope, drive_jitter
from .simulate import FOLLOW_THRESHOLD_M
from .wire import WireSpec

__all__ = ["WireController", "PulsePlan", "ControllerState", "STATES"]


class ControllerState(StrEnum):
    """Where a channel's operating point is.

    A :class:`~enum.StrEnum`: each member is its name on the wire and on the page
    (``"off"``, ...), so traces, JSON and the page's strings are unchanged.
    """

    #: nothing flows; the wire cools to ambient
    OFF = "off"
    #: held just below A_s by the bias: at rest, ready for the next touch
    STANDBY = "standby"
    #: a burst brings the wire up to the setpoint before the first pulse
    WARMING = "warming"
    #: at the setpoint, the pulses move the pin
    VIBRATING = "vibrating"


#: The controller's states, as the page shows them (in this order: the traces' state codes).
STATES = tuple(s.value for s in ControllerState)

#: Martensite fraction the loop holds while vibrating.  0.8 sits 1.2 K into the
#: heating branch: steep enough that a small pulse moves the pin, close enough
#: to A_s that warming from standby needs only about 0.5 mJ.
SETPOINT_MARTENSITE = 0.8
#: Standby holds the wire this far below A_s [K]: out of the band, so the pin
#: is at rest, and close enough that warming takes a few milliseconds.
STANDBY_BELOW_AS_K = 0.3
#: The felt band's floor is this many times the heat that, on the analytic
#: small-signal model below, moves the pin exactly FOLLOW_THRESHOLD_M.
FLOOR_MARGIN = 2.5
#: Below this pulse frequency [Hz] the band's floor rises as 1 / sqrt(f).
FLOOR_KNEE_HZ = 60.0
#: Share of the holding heat the pulses may take at most; the rest stays with
#: the bias, so the loop can always lower the heat.
PULSE_SHARE = 0.85
#: The loop's natural frequency [rad/s], critically damped, against the plant's
#: d xi / dt = -(s / C_eff) dP (s = |d xi / dT| at the setpoint).  6 rad/s (a
#: time constant of about 0.17 s) is still an order of magnitude faster than the
#: wire's own drift in the band (a few seconds) and the instability a stiff
#: source adds (about 0.5 /s on the 75 um wire).
LOOP_RATE_RAD_S = 6.0
#: ...but slower than the one-period mean it reads can follow: rate <= this / period.
LOOP_RATE_PER_WINDOW = 1.0
#: The most one pulse may move the martensite fraction (small-signal): a
#: stronger pulse would run through the whole band and leave the wire contracted
#: for the rest of its period.
MAX_SWING = 0.35
#: The bias (and any warming burst) is cut while the resistance shows less
#: martensite than this: only then can the wire be above A_f, where the
#: envelope's per-pulse bound is the one that must hold.
BIAS_NEEDS_MARTENSITE = 0.05
#: Warming ends when the martensite fraction is within this of the setpoint.
WARM_DONE = 0.03
#: A burst is allowed only while the resistance says the wire is at least this
#: martensitic.  On both Liang-Rogers branches any martensite left means the
#: wire is below A_f; half is a wide margin for a noisy measurement.
WARM_ALLOWED_ABOVE = 0.5


@dataclass(frozen=True)
class PulsePlan:
    """One pulse as the controller plans it.

    Attributes
    ----------
    pulse_width_s : float
        Width [s] at switch level ``level``.
    level : float
        Fraction of the pulse the switch conducts (1: fully on).
    energy_j : float
        Heat the pulse puts into the wire [J] at the measured resistance.
    band_j : (float, float)
        The felt band at this frequency [J].
    position : float
        Where in the band, 0 .. 1.
    clamped : tuple of str
        ``"band"`` when a drive without a strength asked for heat outside the
        band, ``"envelope"`` when the envelope shortened the pulse.
    """

    pulse_width_s: float
    level: float
    energy_j: float
    band_j: tuple[float, float]
    position: float
    clamped: tuple[str, ...] = ()


class WireController:
    """One channel's operating point: state, felt band, standby bias, closed loop.

    Parameters
    ----------
    wire : WireSpec or str
        The wire as configured (its nominal ambient is the open loop's guess).
    circuit : Circuit or str
        The circuit as configured.
    envelope : SafetyEnvelope, optional
        Default: :func:`build_envelope` of the wire and circuit.
    closed_loop : bool
        Use the measured resistance and current (True) or trust the nominal
        circuit and air (False).
    standby_s : float
        How long the bias holds the wire after the pen lifts or hovers [s].
    setpoint : float
        Martensite fraction held while vibrating.
    """

    def __init__(
        self,
        wire: WireSpec | str | None = None,
        circuit: Circuit | str | None = None,
        envelope: SafetyEnvelope | None = None,
        *,
        closed_loop: bool = True,
        standby_s: float = 10.0,
        setpoint: float = SETPOINT_MARTENSITE,
    ) -> None:
        self.spec = WireSpec.resolve(wire)
        self.circuit = Circuit.resolve(circuit, self.spec)
        self.envelope = envelope if envelope is not None else build_envelope(self.spec, self.circuit)
        self.closed_loop = bool(closed_loop)
        self.standby_s = float(standby_s)
        self.setpoint = float(setpoint)
        sp = self.spec
        self.operating_c = sp.heating_temperature_c(self.setpoint)
        self.standby_c = sp.austenite_start_c - STANDBY_BELOW_AS_K
        # The heat that holds the setpoint [W]: a guess from the nominal air, then learnt.
        self.hold_w = sp.conductance_w_k * (self.operating_c - sp.ambient_c)
        self._nominal_hold_w = self.hold_w
        self.state: ControllerState = ControllerState.OFF
        self.drive = Drive.off()
        self._standby_until = -math.inf
        # Latest measurements: resistance [ohm] and heat while on [W].
        self.resistance_ohm = sp.resistance_martensite_ohm
        self.on_power_w = self.circuit.power_at(self.resistance_ohm)
        # Recent measurements (end time [s], xi * dt, dt) for the period mean.
        self._seen: deque[tuple[float, float, float]] = deque()
        self._seen_sum = [0.0, 0.0]
        self._clock_s = 0.0
        self.bias_level = 0.0
        # Small-signal plant at the setpoint: in the band a heat dE changes the
        # martensite fraction by dE s / (C + L s), s = |d xi / dT| of the heating curve.
        a = math.pi / (sp.austenite_finish_c - sp.austenite_start_c)
        s = 0.5 * a * math.sin(a * (self.operating_c - sp.austenite_start_c))
        self._plant_gain = s / (sp.heat_capacity_j_k + sp.latent_j * s)  # [1/J]
        #: Least pulse heat [J] that moves the pin FOLLOW_THRESHOLD_M, with margin.
        self._floor_j = FLOOR_MARGIN * FOLLOW_THRESHOLD_M / sp.stroke_m / self._plant_gain

    # -- the felt band

    def band_j(self, frequency_hz: float) -> tuple[float, float]:
        """The felt band (least, most heat per pulse [J]) at a pulse frequency [Hz]."""
        hi = min(PULSE_SHARE * self.hold_w / frequency_hz, MAX_SWING / self._plant_gain)
        hi = min(hi, self.envelope.max_pulse_energy_j(frequency_hz))
        # Below about 40 .. 60 Hz the skin needs more displacement to feel a pulse (the
        # flutter channel's threshold rises as the frequency falls), and between
        # rare pulses the loop's slow drift must not swamp the pulse's own rise.
        lo = self._floor_j * max(1.0, FLOOR_KNEE_HZ / frequency_hz) ** 0.5
        return min(lo, hi), hi

    def position(self, drive: Drive) -> tuple[float, bool]:
        """Where a drive sits in its band, 0 .. 1 (see the module docstring), and
        whether a drive without a strength had to be brought into the band."""
        return self._position(drive, *self.band_j(drive.pulse_frequency_hz))

    def _position(self, drive: Drive, lo: float, hi: float) -> tuple[float, bool]:
        strength = getattr(drive, "strength", None)
        if strength is not None:
            return min(1.0, max(0.0, strength * drive.amplitude)), False
        own = drive.amplitude * drive.pulse_width_s * self.circuit.power_at(self.spec.resistance_martensite_ohm)
        if own <= 0:
            return 0.0, True
        if hi <= lo:
            return 1.0, abs(own - hi) > 1e-3 * hi
        raw = math.log(own / lo) / math.log(hi / lo)
        return min(1.0, max(0.0, raw)), not (-1e-9 <= raw <= 1 + 1e-9)

    def plan(self, drive: Drive) -> PulsePlan:
        """The next pulse of ``drive``: width and switch level from the band and the
        heat the circuit delivers now (measured in closed loop, nominal otherwise)."""
        f = drive.pulse_frequency_hz
        lo, hi = self.band_j(f)
        pos, outside = self._position(drive, lo, hi)
        clamped: tuple[str, ...] = ("band",) if outside else ()
        energy = lo * (hi / lo) ** pos if hi > lo > 0 else hi
        power = self.on_power_w if self.closed_loop else self.circuit.power_at(self.spec.resistance_martensite_ohm)
        # The pulse must leave room in its period for the wire to cool.
        width = min(energy / power, 0.5 / f)
        # And what the envelope allows (the bias is then cut to what is left): in
        # closed loop the heat is measured, open loop assumes the circuit's worst.
        w_env = self.envelope.max_pulse_energy_j(f, jitter_periods=drive_jitter(drive)) / self._bound_power_w()
        if width > w_env:
            width = w_env
            clamped += ("envelope",)
        return PulsePlan(width, 1.0, width * power, (lo, hi), pos, clamped)

    # -- commands from the host

    def command(self, drive: Drive, now_s: float) -> None:
        """A new drive from the host: off means the pen lifted (standby for a while)."""
        if drive.is_off:
            if self.state in (ControllerState.WARMING, ControllerState.VIBRATING):
                self._enter_standby(now_s)
            self.drive = drive
            return
        self.drive = drive
        if self.state in (ControllerState.OFF, ControllerState.STANDBY):
            self.state = ControllerState.WARMING

    def standby(self, now_s: float) -> None:
        """Texture off, the wire held ready for ``standby_s`` from now (the pen
        lifted, or hovers, or rests with nothing to render)."""
        self.drive = Drive.off()
        self._enter_standby(now_s)

    def _enter_standby(self, now_s: float) -> None:
        self.state = ControllerState.STANDBY
        self._standby_until = now_s + self.standby_s

    def stop(self) -> None:
        """Everything off at once."""
        self.state = ControllerState.OFF
        self.drive = Drive.off()
        self.bias_level = 0.0

    # -- the loop

    def observe(self, resistance_ohm: float, current_a: float, duration_s: float, now_s: float) -> None:
        """A measurement over the ``duration_s`` [s] of current flow ending at ``now_s``
        [s]: the wire's resistance [ohm] and the current [A] (from the sense resistor)."""
        if current_a <= 0:
            return
        self.resistance_ohm = resistance_ohm
        self.on_power_w = current_a * current_a * resistance_ohm
        xi = self.spec.martensite_from_resistance(resistance_ohm)
        self._seen.append((now_s, xi * duration_s, duration_s))
        self._seen_sum[0] += xi * duration_s
        self._seen_sum[1] += duration_s

    def _period_mean(self, now_s: float, window_s: float) -> float:
        """Mean martensite fraction over the last ``window_s`` [s]: over one pulse
        period it cancels the vibration and keeps only the drift the loop corrects."""
        seen, acc = self._seen, self._seen_sum
        while seen and seen[0][0] < now_s - window_s:
            _, a, b = seen.popleft()
            acc[0] -= a
            acc[1] -= b
        if not seen or acc[1] <= 0:
            return self.martensite_fraction
        return acc[0] / acc[1]

    @property
    def martensite_fraction(self) -> float:
        """The martensite fraction the latest resistance means."""
        return self.spec.martensite_from_resistance(self.resistance_ohm)

    def update(self, now_s: float) -> None:
        """Close the loop at ``now_s`` [s]: at each pulse start, and at least every
        few milliseconds (the output calls it)."""
        dt = max(0.0, now_s - self._clock_s)
        self._clock_s = now_s
        period_s = 1.0 / self.drive.pulse_frequency_hz if self.pulses_on else 0.0
        window = max(period_s, 2e-3)
        xi_avg = self._period_mean(now_s, window)
        if self.state == ControllerState.STANDBY and now_s > self._standby_until:
            self.stop()
        if self.state == ControllerState.WARMING and self.martensite_fraction <= self.setpoint + WARM_DONE:
            self.state = ControllerState.VIBRATING
            # The burst's readings say nothing about the band the wire is now in.
            self._seen.clear()
            self._seen_sum = [0.0, 0.0]
        gain_p = gain_i = 0.0
        if self.closed_loop:
            # A one-period mean lags half a period: keep the loop well below that.
            rate = min(LOOP_RATE_RAD_S, LOOP_RATE_PER_WINDOW / window)
            gain_p = 2 * rate / self._plant_gain
            gain_i = rate * rate / self._plant_gain
            if self.state == ControllerState.VIBRATING:
                self.hold_w += gain_i * (xi_avg - self.setpoint) * dt
            elif self.state == ControllerState.STANDBY and xi_avg < 0.995:
                # Blind below A_s, but the resistance moving says the wire is warmer
                # than meant (hot air): lower the holding heat until it stops.
                self.hold_w += gain_i * (xi_avg - 0.995) * dt
            self.hold_w = min(max(self.hold_w, 0.0), 4 * self._nominal_hold_w)
        self.bias_level = self._bias(xi_avg, gain_p)

    def _bias(self, xi_avg: float, gain_p: float) -> float:
        sp = self.spec
        power = self.on_power_w if self.closed_loop else self.circuit.power_at(sp.resistance_martensite_ohm)
        if self.state == ControllerState.OFF or power <= 0 or self.martensite_fraction < BIAS_NEEDS_MARTENSITE:
            return 0.0
        if self.state == ControllerState.WARMING:
            return 1.0
        f = energy = 0.0
        if self.state == ControllerState.STANDBY:
            want = self.hold_w - sp.conductance_w_k * (self.operating_c - self.standby_c)
        else:
            d = self.drive
            want = self.hold_w
            if not d.is_off:
                f = d.pulse_frequency_hz
                plan = self.plan(d)
                energy = plan.pulse_width_s * self._bound_power_w()
                want -= f * plan.energy_j
            if self.closed_loop:
                want += gain_p * (xi_avg - self.setpoint)
        room = self.envelope.bias_room_w(f, energy) / self._bound_power_w()
        return min(max(want / power, 0.0), room, 1.0)

    def _bound_power_w(self) -> float:
        """Heat while on [W] that the envelope's bounds are held to: measured in
        closed loop (the sense resistor), the circuit's worst case open loop."""
        return self.on_power_w if self.closed_loop else self.envelope.max_power_w

    def burst_s(self) -> float:
        """Longest warming burst [s] before the resistance must be read again: the
        heat the envelope allows one burst from a wire bounded below A_f, at the
        heat the circuit delivers (measured in closed loop, its worst open loop)."""
        return self.envelope.max_boost_j(self.spec.austenite_finish_c) / self._bound_power_w()

    def warming_allowed(self) -> bool:
        """A full-on burst is safe only while the resistance bounds the wire below A_f."""
        return self.martensite_fraction >= WARM_ALLOWED_ABOVE and self.envelope.max_boost_j(
            self.spec.austenite_finish_c
        ) > 0

    @property
    def pulses_on(self) -> bool:
        """Texture pulses play only once the wire is in its band."""
        return self.state == ControllerState.VIBRATING and not self.drive.is_off
