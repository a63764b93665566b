"""A running heat estimate: an upper bound on a wire's temperature that bounds every scheduled pulse.

The envelope's bounds (:mod:`.envelope`) assume a periodic drive: a mean power
and one pulse on top of the period's lowest temperature.  Pulse events along a
stroke have no period, so the simulated output bounds each of them by
:class:`RunningHeat` instead (docs/surfaces.md, "How events replace the steady
Drive"): the lumped heat balance C dT/dt = P - G (T - T_air), run with

* the hottest air the envelope is designed for,
* every piece of current at the circuit's *worst* heat (``max_power_w``),
* no credit for latent heat (absorbing it only cools the real wire while heating),

and re-anchored at A_f whenever the resistance shows at least half martensite
(on both branches of the transformation any martensite left means the wire is
below A_f: :mod:`.controller`).  A pulse may add at most C (T_limit - T_upper),
T_limit the envelope's budget above that air (docs/references.md, section 2
(safety envelope)).

Units: SI; temperatures in degrees Celsius.
"""

from __future__ import annotations

import math

from .envelope import SafetyEnvelope

__all__ = ["RunningHeat", "ANCHOR_MARTENSITE"]

#: A resistance reading with at least this martensite fraction bounds the wire below A_f.
ANCHOR_MARTENSITE = 0.5


class RunningHeat:
    """Upper bound on one wire's temperature [deg C], advanced piece by piece.

    Parameters
    ----------
    envelope : SafetyEnvelope
        The wire, its circuit (worst heat) and the budget.
    start_c : float, optional
        A known upper bound to start from [deg C]; A_f by default (a wire whose
        resistance has not been read yet is treated as possibly that warm).
    """

    def __init__(self, envelope: SafetyEnvelope, start_c: float | None = None) -> None:
        sp = envelope.spec
        self.air_c = max(envelope.design_ambient_c, sp.ambient_c)
        self.limit_c = self.air_c + envelope.budget_k
        self.capacity_j_k = sp.heat_capacity_j_k
        self.conductance_w_k = sp.conductance_w_k
        self.tau_s = sp.time_constant_s
        self.worst_power_w = envelope.max_power_w
        self.af_c = sp.austenite_finish_c
        self.upper_c = self.af_c if start_c is None else float(start_c)
        #: The highest the bound has been [deg C] (for tests and the page).
        self.peak_c = self.upper_c

    def run(self, duration_s: float, level: float) -> None:
        """``duration_s`` [s] of the switch at ``level`` (0 .. 1) at the circuit's worst heat."""
        if duration_s <= 0:
            return
        settle = self.air_c + level * self.worst_power_w / self.conductance_w_k
        self.upper_c = settle + (self.upper_c - settle) * math.exp(-duration_s / self.tau_s)
        self.peak_c = max(self.peak_c, self.upper_c)

    def anchor(self, martensite_fraction: float) -> None:
        """A resistance reading: with enough martensite the wire is below A_f."""
        if martensite_fraction >= ANCHOR_MARTENSITE and self.upper_c > self.af_c:
            self.upper_c = self.af_c

    def max_pulse_j(self) -> float:
        """Most heat [J] one pulse may add now (a pulse is short against the wire's time constant)."""
        return max(0.0, self.capacity_j_k * (self.limit_c - self.upper_c))

    def max_pulse_s(self) -> float:
        """Longest full-on pulse [s] allowed now, at the circuit's worst heat."""
        return self.max_pulse_j() / self.worst_power_w if self.worst_power_w > 0 else math.inf
