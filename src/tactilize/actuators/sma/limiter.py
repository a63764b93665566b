"""Hardware limits on a wire's heat that hold with the gate's logic stuck high.

The firmware's heat gate keeps a wire under its maximum only while the
firmware runs.  A crash with a pulse pin left high, a reset mid-pulse or a
runaway loop toggling the pin would heat the wire without bound: the
``aa-resistor`` circuit switched on for good settles 1170 K above the air.  The
parts here sit between the logic that asks for current (the OR of pulse and
bias, docs/hardware.md, U1) and the MOSFET, and need no software:

:class:`AcCoupledGate`
    A series capacitor into the gate, whose resistor to ground discharges it:
    a logic level held high gives one gate pulse that decays below the
    MOSFET's threshold after ``t_on = R C ln(V_drive / V_th)``.  It bounds a
    stuck pin to one pulse, but a pin toggled fast keeps the capacitor near its
    mean and passes duty up to ``1 - V_th / V_drive`` (80 % on 3.3 V logic):
    it cannot bound a runaway toggle on its own.
:class:`ThermalReplica`
    An RC whose time constant is at least the wire's, charged by the logic
    (before anything blocks it), and a comparator that blocks the logic (an AND
    gate in front of the gate drive) while the replica is above a threshold.
    The replica is the lumped heat balance without latent heat, scaled: at the
    circuit's most heat into the wire its voltage over the logic level is the
    wire's rise over what that heat would hold it at.  It bounds every pattern
    of the logic, stuck or toggled: a logic stuck high, or toggled at a duty
    above the trip point, charges it past the trip point for good.

Each turns the logic's schedule (segments of constant level, as
:meth:`WireModel.run` takes them) into the schedule the MOSFET conducts, and
:func:`preset_limit` is the limit chosen for each circuit preset.  What a
limit lets through at its worst (stuck high, a runaway toggle), judged on the
host's wire model, is :mod:`tactilize.actuators.sma.limiter_worst`;
docs/hardware.md ("Defence in depth") is their table.

Units: SI (seconds, ohms, farads, volts); temperatures in degrees Celsius.

References
----------
.. [1] docs/references.md, section 8 (gate threshold, ac-coupled gate, thermal replica, board heat estimate).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Iterable, Sequence

from ...errors import WireError
from .circuit import Circuit
from .envelope import DESIGN_AMBIENT_C
from .wire import WireSpec

__all__ = [
    "AcCoupledGate",
    "ThermalReplica",
    "HardwareLimit",
    "Schedule",
    "LOGIC_V",
    "GATE_THRESHOLD_MIN_V",
    "GATE_THRESHOLD_MAX_V",
    "GATE_THRESHOLD_WORST_V",
    "COMPARATOR_OFFSET_V",
    "COMPARATOR_HYSTERESIS_V",
    "replica_for",
    "preset_limit",
    "e96_at_or_below",
    "e96_at_or_above",
]

#: The logic level into the limiter [V]: a 74LVC gate from the Pico's 3V3.
LOGIC_V = 3.3
#: AO3400A gate threshold [V] at 25 C, least and most (docs/references.md, section 8 (gate threshold)).
GATE_THRESHOLD_MIN_V = 0.65
GATE_THRESHOLD_MAX_V = 1.45
#: The threshold the worst cases are judged at [V]: below the datasheet's least,
#: because a warm junction conducts at a lower gate voltage; a margin chosen here.
GATE_THRESHOLD_WORST_V = 0.5
#: MCP6541 comparator: largest input offset and typical hysteresis [V]
#: (docs/references.md, section 8 (thermal replica)).
COMPARATOR_OFFSET_V = 7e-3
COMPARATOR_HYSTERESIS_V = 3.3e-3
#: The hysteresis's upper end [V], its trip point above the threshold being half of it.
COMPARATOR_HYSTERESIS_MAX_V = 5e-3
#: Tolerances: 1 % resistors, 5 % C0G capacitor (AC gate), 2 % PPS film capacitor (replica).
RESISTOR_TOL = 0.01
C0G_TOL = 0.05
FILM_TOL = 0.02

#: A schedule: segment lengths [s] and switch levels in [0, 1].
Schedule = tuple[list[float], list[float]]

_E96 = (
    100, 102, 105, 107, 110, 113, 115, 118, 121, 124, 127, 130, 133, 137, 140, 143, 147, 150, 154, 158, 162, 165,
    169, 174, 178, 182, 187, 191, 196, 200, 205, 210, 215, 221, 226, 232, 237, 243, 249, 255, 261, 267, 274, 280,
    287, 294, 301, 309, 316, 324, 332, 340, 348, 357, 365, 374, 383, 392, 402, 412, 422, 432, 442, 453, 464, 475,
    487, 499, 511, 523, 536, 549, 562, 576, 590, 604, 619, 634, 649, 665, 681, 698, 715, 732, 750, 768, 787, 806,
    825, 845, 866, 887, 909, 931, 953, 976,
)


def _e96_values(value: float) -> list[float]:
    decade = 10 ** math.floor(math.log10(value))
    # Three decades around the value, so both neighbours exist at a decade's edge.
    return [round(m * d / 100, 9) for d in (decade / 10, decade, decade * 10) for m in _E96]


def e96_at_or_below(value: float) -> float:
    """The largest E96 (1 %) value not above ``value``."""
    return max(v for v in _e96_values(value) if v <= value * (1 + 1e-12))


def e96_at_or_above(value: float) -> float:
    """The smallest E96 (1 %) value not below ``value``."""
    return min(v for v in _e96_values(value) if v >= value * (1 - 1e-12))


def append_segment(out: Schedule, duration_s: float, level: float) -> None:
    """Add a segment, merging it into the last one when the level is the same."""
    if duration_s <= 0:
        return
    durations, levels = out
    if levels and levels[-1] == level:
        durations[-1] += duration_s
    else:
        durations.append(duration_s)
        levels.append(level)


def _check_logic(levels: Iterable[float]) -> None:
    for lev in levels:
        if lev not in (0, 1):
            raise WireError("<limiter>", f"a logic schedule is 0 or 1 per segment, got {lev!r}")


@dataclass(frozen=True)
class AcCoupledGate:
    """A series capacitor into the MOSFET's gate and a resistor from gate to ground.

    Parameters
    ----------
    capacitor_f : float
        The series capacitor [F] between the logic and the gate.
    resistor_ohm : float
        Gate to ground [ohm] (the board's R4).
    drive_v : float
        The logic's high level [V].
    threshold_v : float
        Gate voltage [V] below which the MOSFET is taken as off.

    Notes
    -----
    While the logic is high the gate is ``V_drive - V_c`` and the capacitor's
    voltage ``V_c`` charges toward ``V_drive`` through the resistor; while it is
    low the gate is ``-V_c`` (off) and ``V_c`` discharges toward 0 through the
    same resistor.  The MOSFET is counted as fully on while the gate is above
    ``threshold_v``: near the threshold it conducts less, so this overstates
    the heat.  The MOSFET's own gate capacitance (630 pF) divides the first
    step by under 1 % and only shortens the pulse; it is left out.
    """

    capacitor_f: float = 68e-9
    resistor_ohm: float = 100e3
    drive_v: float = LOGIC_V
    threshold_v: float = GATE_THRESHOLD_MIN_V

    @property
    def time_constant_s(self) -> float:
        """R C [s]."""
        return self.resistor_ohm * self.capacitor_f

    def on_time_s(self, charged_v: float = 0.0) -> float:
        """How long [s] the MOSFET conducts when the logic goes high and stays high.

        Parameters
        ----------
        charged_v : float
            The capacitor's voltage [V] when the logic goes high (0: fully re-armed).

        Returns
        -------
        float
            ``R C ln((V_drive - V_c) / V_th)``, 0 when the first step is already
            below the threshold.

        References
        ----------
        .. [1] docs/references.md, section 8 (ac-coupled gate).
        """
        step_v = self.drive_v - charged_v
        if step_v <= self.threshold_v:
            return 0.0
        return self.time_constant_s * math.log(step_v / self.threshold_v)

    def max_toggle_duty(self) -> float:
        """The conducting fraction [0, 1] a logic toggled much faster than R C passes:
        the capacitor sits at the mean ``d V_drive``, so the gate's high level is
        ``(1 - d) V_drive``, above the threshold for every ``d < 1 - V_th / V_drive``."""
        return max(0.0, 1.0 - self.threshold_v / self.drive_v)

    def worst_corner(self) -> "AcCoupledGate":
        """The same part at its longest on-time: R and C at the top of their
        tolerances (1 %, 5 % C0G) and the threshold at :data:`GATE_THRESHOLD_WORST_V`."""
        return dataclasses.replace(
            self,
            capacitor_f=self.capacitor_f * (1 + C0G_TOL),
            resistor_ohm=self.resistor_ohm * (1 + RESISTOR_TOL),
            threshold_v=min(self.threshold_v, GATE_THRESHOLD_WORST_V),
        )

    def schedule(self, durations_s: Sequence[float], levels: Sequence[float], charged_v: float = 0.0) -> Schedule:
        """The MOSFET's conduction for a logic schedule.

        Parameters
        ----------
        durations_s : sequence of float
            Segment lengths [s] of the logic.
        levels : sequence of {0, 1}
            The logic's level per segment.
        charged_v : float
            The capacitor's voltage [V] at the start.

        Returns
        -------
        (list of float, list of float)
            Segment lengths [s] and switch levels (1 conducting, 0 off).
        """
        _check_logic(levels)
        rc = self.time_constant_s
        vd = self.drive_v
        vc = float(charged_v)
        out: Schedule = ([], [])
        for dur, lev in zip(durations_s, levels):
            if dur <= 0:
                continue
            decay = math.exp(-dur / rc)
            if lev:
                on = min(dur, self.on_time_s(vc))
                append_segment(out, on, 1.0)
                append_segment(out, dur - on, 0.0)
                vc = vd - (vd - vc) * decay
            else:
                append_segment(out, dur, 0.0)
                vc *= decay
        return out


@dataclass(frozen=True)
class ThermalReplica:
    """An RC model of the wire's heat that blocks the gate's logic while it is too hot.

    Parameters
    ----------
    resistor_ohm, capacitor_f : float
        The replica's R [ohm] and C [F], charged from the logic that asks for
        current (U1's output); ``R C`` at least the wire's time constant.
    threshold_fraction : float
        The comparator's trip point as a fraction of the logic level (a divider
        from the same 3V3, so the comparison is ratiometric).
    hysteresis_fraction : float
        Trip-down minus trip-up point, as a fraction of the logic level.

    Notes
    -----
    With the replica's ``y`` (its voltage over the logic level) the AND gate
    passes the logic while the comparator is high: it goes low when ``y``
    reaches the upper trip point and high again when ``y`` falls to the lower.
    The wire's rise is bounded by ``k y (P_max / hA)`` at the last instant the
    switch conducted (``k``: how much slower the replica is than the wire), and
    ``y`` was below the upper trip point then (docs/references.md, section 8
    (thermal replica)).
    The comparator's 4 us delay lets through at most 0.7 uJ more per trip
    (0.01 K on the 75 um wire); it is left out.
    """

    resistor_ohm: float
    capacitor_f: float
    threshold_fraction: float
    hysteresis_fraction: float = COMPARATOR_HYSTERESIS_V / LOGIC_V

    @property
    def time_constant_s(self) -> float:
        """R C [s]."""
        return self.resistor_ohm * self.capacitor_f

    @property
    def upper_fraction(self) -> float:
        """Where the comparator blocks the logic [fraction of the logic level]."""
        return self.threshold_fraction + 0.5 * self.hysteresis_fraction

    @property
    def lower_fraction(self) -> float:
        """Where it lets the logic through again [fraction of the logic level]."""
        return max(1e-9, self.threshold_fraction - 0.5 * self.hysteresis_fraction)

    def worst_corner(self) -> "ThermalReplica":
        """The same part at its most permissive: R C at the top of its tolerances
        (1 % resistor, 2 % film; a slower replica lags the wire's rise), the trip
        point raised by the divider's 2 %, the comparator's largest offset and its
        largest hysteresis."""
        return dataclasses.replace(
            self,
            capacitor_f=self.capacitor_f * (1 + FILM_TOL),
            resistor_ohm=self.resistor_ohm * (1 + RESISTOR_TOL),
            threshold_fraction=self.threshold_fraction * (1 + 2 * RESISTOR_TOL) + COMPARATOR_OFFSET_V / LOGIC_V,
            hysteresis_fraction=COMPARATOR_HYSTERESIS_MAX_V / LOGIC_V,
        )

    def mask(self, durations_s: Sequence[float], levels: Sequence[float], start_fraction: float = 0.0) -> Schedule:
        """When the comparator lets the gate conduct, for a logic schedule.

        The replica is charged by the logic itself, not by what the clamp lets
        through, so a logic stuck high charges it past the trip point and the
        clamp stays on for good.

        Parameters
        ----------
        durations_s : sequence of float
            Segment lengths [s] of the logic.
        levels : sequence of {0, 1}
            Its level per segment.
        start_fraction : float
            The replica's voltage at the start, over the logic level.

        Returns
        -------
        (list of float, list of float)
            Segment lengths [s] and 1 where the gate may conduct, 0 where the
            comparator clamps it.
        """
        _check_logic(levels)
        tau = self.time_constant_s
        hi, lo = self.upper_fraction, self.lower_fraction
        y = float(start_fraction)
        passing = y < hi
        out: Schedule = ([], [])
        for dur, lev in zip(durations_s, levels):
            rem = float(dur)
            while rem > 0:
                # Within a segment y moves monotonically toward the logic level;
                # the comparator flips where it crosses its trip point.
                if passing and lev:
                    cross = tau * math.log((1.0 - y) / (1.0 - hi)) if y < hi else 0.0
                elif not passing and not lev:
                    cross = tau * math.log(y / lo) if y > lo else 0.0
                else:
                    cross = math.inf
                step = min(rem, cross)
                append_segment(out, step, 1.0 if passing else 0.0)
                y = lev + (y - lev) * math.exp(-step / tau)
                if step == cross:
                    passing = not passing
                rem -= step
        return out


def _both(a: Schedule, b: Schedule) -> Schedule:
    """The product of two schedules over the same span (conducting only where both do)."""
    out: Schedule = ([], [])
    i = j = 0
    ra = a[0][0] if a[0] else 0.0
    rb = b[0][0] if b[0] else 0.0
    while i < len(a[0]) and j < len(b[0]):
        step = min(ra, rb)
        append_segment(out, step, a[1][i] * b[1][j])
        ra -= step
        rb -= step
        # A remainder under 1 ns is float rounding of the two sums of segments.
        if ra <= 1e-12:
            i += 1
            ra = a[0][i] if i < len(a[0]) else 0.0
        if rb <= 1e-12:
            j += 1
            rb = b[0][j] if j < len(b[0]) else 0.0
    return out


def replica_for(
    spec: WireSpec | str | None = None,
    circuit: Circuit | str | None = None,
    *,
    design_air_c: float = DESIGN_AMBIENT_C,
    capacitor_f: float = 1e-6,
    divider_top_ohm: float = 1e6,
) -> tuple[ThermalReplica, float]:
    """Size a :class:`ThermalReplica` for a wire on a circuit, with E96 resistors.

    The replica's R is the smallest E96 value whose ``R C`` at the bottom of
    the tolerances is still the wire's time constant or more.  In the lumped
    balance without latent heat a replica ``k`` times slower than the wire bounds
    the wire's rise by ``k`` times its own reading, whatever the logic does
    (docs/references.md, section 8 (thermal replica)); so the divider's lower
    resistor is the largest E96 value whose trip point at the top of every
    tolerance keeps ``k_max y (P_max / hA)`` within ``T_max - T_air``.

    Parameters
    ----------
    spec, circuit
        The wire and its circuit (``P_max`` is :meth:`Circuit.max_power_w`).
    design_air_c : float
        The air the limit is sized for [deg C].
    capacitor_f : float
        The replica's capacitor [F] (PPS film, 2 %).
    divider_top_ohm : float
        The threshold divider's upper resistor [ohm], from 3V3.

    Returns
    -------
    (ThermalReplica, float)
        The replica, and the divider's lower resistor [ohm] (0 when no E96
        value fits: the threshold would sit inside the comparator's offset).
    """
    sp = WireSpec.resolve(spec)
    cir = Circuit.resolve(circuit, sp)
    tau_w = sp.time_constant_s
    r = e96_at_or_above(tau_w / (capacitor_f * (1 - RESISTOR_TOL) * (1 - FILM_TOL)))
    slow_max = r * capacitor_f * (1 + RESISTOR_TOL) * (1 + FILM_TOL) / tau_w
    # The trip point the wire's budget allows at the top of every tolerance.
    allowed = (sp.max_temperature_c - design_air_c) * sp.conductance_w_k / (cir.max_power_w(sp) * slow_max)
    room = allowed - (COMPARATOR_OFFSET_V + 0.5 * COMPARATOR_HYSTERESIS_MAX_V) / LOGIC_V
    ratio = room / (1 + 2 * RESISTOR_TOL)
    if ratio <= 0:
        return ThermalReplica(r, capacitor_f, 0.0), 0.0
    bottom = e96_at_or_below(divider_top_ohm * ratio / (1 - ratio))
    fraction = bottom / (divider_top_ohm + bottom)
    return ThermalReplica(r, capacitor_f, fraction), bottom


@dataclass(frozen=True)
class HardwareLimit:
    """The hardware limit of one circuit preset: the parts in the gate's path, in order.

    Parameters
    ----------
    circuit : str
        The preset's name.
    replica : ThermalReplica or None
        The thermal replica, charged by the logic, and the AND gate it drives, if any.
    ac_gate : AcCoupledGate or None
        The AC-coupled gate after the AND gate, if any.
    safe : bool
        Whether the limit holds the wire under its maximum in the design air.
    note : str
        What the limit does, or why the preset cannot be made safe this way.
    """

    circuit: str
    replica: ThermalReplica | None = None
    ac_gate: AcCoupledGate | None = None
    safe: bool = True
    note: str = ""

    def worst_corner(self) -> "HardwareLimit":
        """Every part at its most permissive tolerance corner."""
        return dataclasses.replace(
            self,
            replica=None if self.replica is None else self.replica.worst_corner(),
            ac_gate=None if self.ac_gate is None else self.ac_gate.worst_corner(),
        )

    def schedule(self, durations_s: Sequence[float], levels: Sequence[float]) -> Schedule:
        """What the MOSFET conducts for a logic schedule (segments [s], levels 0 or 1),
        starting from discharged capacitors."""
        sched: Schedule = (list(durations_s), list(levels))
        _check_logic(sched[1])
        if self.replica is not None:
            sched = _both(sched, self.replica.mask(*sched))
        if self.ac_gate is not None:
            sched = self.ac_gate.schedule(*sched)
        return sched


def preset_limit(name: str, wire: WireSpec | str | None = None, *, design_air_c: float = DESIGN_AMBIENT_C) -> HardwareLimit:
    """The hardware limit chosen for a circuit preset of docs/hardware.md.

    ``aa-resistor``, ``usb-resistor``: a thermal replica blocking the logic, then
    an AC-coupled gate (68 nF into Q1's gate, the existing 100 kOhm R4 to
    ground: a stuck pin gives one pulse of 5.6 .. 11 ms, longer than the
    firmware's 5 ms pulses).  ``aa-sink``: the replica only, blocking the
    sink's set point (an AC-coupled set point would shrink the current along
    every pulse instead of cutting it).  ``aa-direct``: none that works (the
    replica's trip point would be 4 mV, inside the comparator's offset); its
    note says so.
    """
    spec = WireSpec.resolve(wire)
    key = str(name).strip().lower()
    circuit = Circuit.preset(key, spec)
    replica, bottom_ohm = replica_for(spec, circuit, design_air_c=design_air_c)
    if bottom_ohm <= 0:
        allowed_v = LOGIC_V * (spec.max_temperature_c - design_air_c) * spec.conductance_w_k / circuit.max_power_w(spec)
        return HardwareLimit(
            key,
            ac_gate=AcCoupledGate(),
            safe=False,
            note=(
                f"cannot be made safe by these parts: the replica's trip point would be {allowed_v * 1e3:.1f} mV, "
                f"inside the comparator's {COMPARATOR_OFFSET_V * 1e3:.0f} mV offset; the AC-coupled gate alone "
                "still lets one full pulse through"
            ),
        )
    if circuit.kind == "current":
        return HardwareLimit(key, replica=replica, note="replica blocks the sink's set point")
    return HardwareLimit(key, replica=replica, ac_gate=AcCoupledGate(), note="replica, then AC-coupled gate")
