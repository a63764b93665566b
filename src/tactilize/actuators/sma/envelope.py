"""The safety envelope: what a wire may be given, in energy, for the circuit actually configured.

Nothing that can heat a wire gets past :class:`SafetyEnvelope`.  It is computed
from the wire's physics and the circuit's *worst* case, not from a nominal
current: the heat of one pulse is ``E = a w P_hi`` where ``P_hi`` is the most
the switched-on circuit can put into this wire at any of its resistances
(:meth:`Circuit.max_power_w`) and ``a`` the fraction of the pulse the switch
conducts.  Two bounds, both from the lumped heat balance
(docs/references.md, section 2 (safety envelope)):

* the mean temperature in the periodic state is exactly
  ``T_amb + P_mean / (h A_s)`` (over a period the latent heat cancels), with
  ``P_mean = f E + b P_hi`` for a standby bias level ``b``;
* one pulse lifts the wire at most ``E / C`` above the lowest temperature of
  its period (the latent heat can only absorb part of it), and the lowest
  temperature is at most the mean.

So ``T_amb + P_mean / (h A_s) + E / C <= T_max`` bounds the peak of an even
train.  An irregular train (:mod:`tactilize.synthesis`) may bring a pulse ``j``
periods closer to all those before it than an even train would: the heat left
from them is then ``e^(j P / tau)`` times larger, which adds at most ``j E / C``
(docs/references.md, section 2 (jittered trains)), so the per-pulse term is
``(1 + j) E / C``.  The envelope
uses the hottest air it is designed for (:data:`DESIGN_AMBIENT_C`, or the wire's
own ambient when that is hotter) and keeps :data:`ENVELOPE_MARGIN` of the budget
in reserve.  A property test drives the model with whatever the envelope lets
through, over profiles, features, speeds and circuits, and checks the peak.

Units: SI; temperatures in degrees Celsius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ...drive import Drive
from ...synthesis.trains import JITTER_MAX_PERIODS
from .circuit import Circuit
from .wire import WireSpec

__all__ = ["SafetyEnvelope", "build_envelope", "default_envelope", "drive_jitter", "DESIGN_AMBIENT_C", "ENVELOPE_MARGIN"]

#: The hottest air [deg C] the envelope is computed for by default: a warm room
#: (5 K above the wires' nominal 25 C).  Hotter air needs ``design_ambient_c``:
#: the budget is the temperature rise the wire may have above it, and every
#: kelvin of it is heat the controller needs in cold air (at 15 C the 75 um wire
#: needs 7.4 mW to sit in its band, 57 K above the air).
DESIGN_AMBIENT_C = 30.0
#: Fraction of the temperature budget the envelope hands out.
ENVELOPE_MARGIN = 0.95


@dataclass(frozen=True)
class SafetyEnvelope:
    """Largest pulse energy and standby bias a wire may get on a circuit.

    Use :func:`build_envelope`.  Every method is closed-form: checking a drive
    costs a few microseconds.

    Attributes
    ----------
    spec : WireSpec
    circuit : Circuit
    design_ambient_c : float
        Air temperature [deg C] the budget is computed for.
    """

    spec: WireSpec
    circuit: Circuit
    design_ambient_c: float = DESIGN_AMBIENT_C
    max_power_w: float = field(init=False)
    budget_k: float = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "max_power_w", self.circuit.max_power_w(self.spec))
        ambient = max(self.design_ambient_c, self.spec.ambient_c)
        object.__setattr__(self, "budget_k", ENVELOPE_MARGIN * (self.spec.max_temperature_c - ambient))

    # -- the bounds

    def max_bias_level(self, frequency_hz: float = 0.0, pulse_energy_j: float = 0.0) -> float:
        """Largest standby switch level [0, 1] under pulses of ``pulse_energy_j`` [J]
        at ``frequency_hz`` [Hz] (none by default): what is left of the mean-power bound.

        The bias is the controller's own, and the controller keeps it only while
        the wire's resistance shows martensite, which bounds the wire below A_f
        (:mod:`~tactilize.actuators.sma.controller`); the per-pulse rise E / C
        matters above A_f, where the bias is off and only the pulses' own bound
        (:meth:`max_pulse_energy_j`) holds.  So this bound is on the mean only.
        """
        return min(1.0, self.bias_room_w(frequency_hz, pulse_energy_j) / self.max_power_w)

    def bias_room_w(self, frequency_hz: float = 0.0, pulse_energy_j: float = 0.0) -> float:
        """Mean heat [W] a standby bias may add to pulses of ``pulse_energy_j`` [J] at
        ``frequency_hz`` [Hz]: for a controller that measures the heat it delivers."""
        return max(0.0, self.budget_k * self.spec.conductance_w_k - frequency_hz * pulse_energy_j)

    def max_pulse_energy_j(self, frequency_hz: float, bias_level: float = 0.0, jitter_periods: float = 0.0) -> float:
        """Largest heat per pulse [J] at a pulse frequency [Hz] over a standby bias level,
        for a train whose pulses may move ``jitter_periods`` toward each other (0: even)."""
        if frequency_hz <= 0:
            return 0.0
        hA, C = self.spec.conductance_w_k, self.spec.heat_capacity_j_k
        room_k = self.budget_k - bias_level * self.max_power_w / hA
        if room_k <= 0:
            return 0.0
        return room_k / (frequency_hz / hA + (1.0 + jitter_periods) / C)

    def max_pulse_width_s(
        self, frequency_hz: float, amplitude: float = 1.0, bias_level: float = 0.0, jitter_periods: float = 0.0
    ) -> float:
        """Largest pulse width [s] at a frequency [Hz], switch fraction ``amplitude``, bias
        level and jitter depth [periods]."""
        if frequency_hz <= 0 or amplitude <= 0:
            return math.inf
        return self.max_pulse_energy_j(frequency_hz, bias_level, jitter_periods) / (amplitude * self.max_power_w)

    def max_boost_j(self, start_upper_c: float) -> float:
        """Largest heat [J] of one warming burst from a wire known to be at most
        ``start_upper_c`` [deg C]: a single long pulse may lift it ``E / C``."""
        room_k = ENVELOPE_MARGIN * (self.spec.max_temperature_c - start_upper_c)
        return max(0.0, room_k * self.spec.heat_capacity_j_k)

    def peak_bound_c(self, drive: Drive, bias_level: float = 0.0, ambient_c: float | None = None) -> float:
        """The envelope's upper bound on the settled peak temperature [deg C] of a drive."""
        Ta = max(self.design_ambient_c, self.spec.ambient_c) if ambient_c is None else ambient_c
        hA, C = self.spec.conductance_w_k, self.spec.heat_capacity_j_k
        E = 0.0 if drive.is_off else drive.amplitude * drive.pulse_width_s * self.max_power_w
        f = 0.0 if drive.is_off else drive.pulse_frequency_hz
        return Ta + (f * E + bias_level * self.max_power_w) / hA + (1.0 + drive_jitter(drive)) * E / C

    # -- applying it

    def allows(self, drive: Drive, bias_level: float = 0.0) -> bool:
        """True when the envelope would let ``drive`` through unchanged."""
        if drive.is_off:
            return bias_level <= self.max_bias_level() * (1 + 1e-12)
        w = self.max_pulse_width_s(drive.pulse_frequency_hz, drive.amplitude, bias_level, drive_jitter(drive))
        return drive.pulse_width_s <= w * (1 + 1e-12)

    def apply(self, drive: Drive, bias_level: float = 0.0) -> Drive:
        """The drive with its width shortened to the envelope (``"envelope"`` added
        to ``clamped`` when that happened; an off drive when nothing is allowed)."""
        if drive.is_off:
            return drive
        w_max = self.max_pulse_width_s(drive.pulse_frequency_hz, drive.amplitude, bias_level, drive_jitter(drive))
        if drive.pulse_width_s <= w_max:
            return drive
        if w_max <= 0:
            return Drive.off(drive.clamped + ("envelope",) if "envelope" not in drive.clamped else drive.clamped)
        return drive.with_clamp("envelope", pulse_width_s=w_max)

    def to_dict(self, frequencies_hz: tuple[float, ...] = (1, 10, 50, 100, 200, 300)) -> dict[str, Any]:
        """JSON-ready: the circuit, the budget and the largest width per frequency."""
        return {
            "wire": self.spec.to_dict(),
            "circuit": self.circuit.describe(self.spec),
            "design_ambient_c": self.design_ambient_c,
            "margin": ENVELOPE_MARGIN,
            "max_bias_level": self.max_bias_level(),
            "frequencies_hz": list(frequencies_hz),
            "max_pulse_energy_j": [self.max_pulse_energy_j(f) for f in frequencies_hz],
            "max_width_s": [self.max_pulse_width_s(f) for f in frequencies_hz],
        }


def drive_jitter(drive: Drive) -> float:
    """The most a drive's pulses may move toward each other [periods]: 0 for an
    even train, ``JITTER_MAX_PERIODS (1 - regularity)`` for an irregular one
    (the synthesiser may cap it lower, never higher)."""
    regularity = getattr(drive, "regularity", None)
    if drive.is_off or regularity is None or regularity >= 1.0:
        return 0.0
    return JITTER_MAX_PERIODS * (1.0 - max(0.0, regularity))


def build_envelope(
    wire: WireSpec | str | None = None,
    circuit: Circuit | str | None = None,
    *,
    design_ambient_c: float = DESIGN_AMBIENT_C,
) -> SafetyEnvelope:
    """The safety envelope of a wire on a circuit (``aa-resistor`` by default)."""
    spec = WireSpec.resolve(wire)
    return SafetyEnvelope(spec, Circuit.resolve(circuit, spec), float(design_ambient_c))


def default_envelope() -> SafetyEnvelope:
    """The envelope every drive passes before it leaves the host when nothing
    else is configured: the paper's 75 um wire on the ``aa-resistor`` circuit."""
    return build_envelope()
