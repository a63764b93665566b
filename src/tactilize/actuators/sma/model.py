"""The wire's state and its integrator: a lumped body with Liang-Rogers hysteresis.

The wire is one temperature ``T`` and one martensite fraction ``xi``
(docs/references.md, section 2)::

    rho c V dT/dt = s P(R(xi)) - h A_s (T - T_amb) + rho V L_h dxi/dt

where ``P(R)`` is the heat the switched-on circuit puts into a wire of
resistance ``R`` (:meth:`Circuit.power_and_slope`) and ``s`` in [0, 1] the
fraction of time the switch conducts (1 during a full pulse, small for the
chopped standby bias).  ``xi`` follows Liang-Rogers cosine kinetics whose minor
loops restart from the last reversal point; the resistance mixes the two
phases' values with ``xi``; the contraction is ``L eps_L (1 - xi)``.

Integration scheme (why it is fast and exact where it matters)
--------------------------------------------------------------
The switch level is piecewise constant, so the integrator walks *segments* of
constant level instead of fixed time steps.  Inside one segment the equation is
an autonomous scalar ODE in ``T`` (``xi`` is a function of ``T`` on the active
branch), so ``T`` is monotone and the heating/cooling branch cannot change within
it; reversals happen only at segment edges, exactly where Liang-Rogers restarts.

* Outside the active transformation range the ODE is linear and solved exactly
  (exponential), stopping exactly where the band begins.
* Inside it, Crank-Nicolson on the enthalpy ``C T - rho V L_h xi`` with a Newton
  solve, sub-stepped so that no step moves more than ``max_step_k`` (0.2 K by
  default, 1/20 of the 4 K branch width).  This form conserves energy exactly
  (electrical in = stored + convected + latent, to the Newton tolerance).

Units: SI, temperatures in degrees Celsius.
"""

from __future__ import annotations

import math
from typing import Sequence

from ...errors import WireError
from .circuit import Circuit
from .wire import WireSpec

__all__ = ["WireModel", "branch_fraction"]


def branch_fraction(spec: WireSpec, temperature_c: float, branch: int, scale: float) -> tuple[float, float]:
    """Martensite fraction and its slope d xi / dT [1/K] on a Liang-Rogers branch.

    Parameters
    ----------
    spec : WireSpec
        The wire (its transformation temperatures).
    temperature_c : float
        Temperature [deg C].
    branch : int
        +1 heating (martensite -> austenite), -1 cooling.
    scale : float
        The restart factor ``k``: 1 on the major curves.  Heating from a reversal
        at ``xi_r`` follows ``xi = k h(T)`` with ``k = xi_r / h(T_r)``; cooling
        follows ``1 - xi = k g(T)`` with ``k = (1 - xi_r) / g(T_r)``, where ``h``
        and ``g`` are the major curves' cosine shapes.

    Returns
    -------
    (float, float)
        ``xi`` and ``d xi / dT``.
    """
    T, k = temperature_c, scale
    if branch > 0:
        As, Af = spec.austenite_start_c, spec.austenite_finish_c
        if T <= As:
            return k, 0.0
        if T >= Af:
            return 0.0, 0.0
        a = math.pi / (Af - As)
        u = a * (T - As)
        return k * 0.5 * (1 + math.cos(u)), -k * 0.5 * a * math.sin(u)
    Ms, Mf = spec.martensite_start_c, spec.martensite_finish_c
    if T <= Mf:
        return 1.0, 0.0
    if T >= Ms:
        return 1.0 - k, 0.0
    a = math.pi / (Ms - Mf)
    u = a * (T - Mf)
    return 1.0 - k * 0.5 * (1 - math.cos(u)), -k * 0.5 * a * math.sin(u)


def _restart_scale(spec: WireSpec, T: float, xi: float, branch: int) -> float:
    """The factor ``k`` that puts the new branch through the reversal point (T, xi)."""
    major, _ = branch_fraction(spec, T, branch, 1.0)
    if branch > 0:
        return xi / major if major > 1e-12 else 0.0
    g = 1.0 - major
    return (1.0 - xi) / g if g > 1e-12 else 0.0


class WireModel:
    """The wire's state and the segment integrator (see the module docstring).

    Parameters
    ----------
    spec : WireSpec
        The wire.
    circuit : Circuit
        What drives it (``Circuit.resolve(None, spec)``: two AA cells and a series
        resistor, by default).
    temperature_c : float, optional
        Initial temperature [deg C]; ambient by default.
    martensite_fraction : float, optional
        Initial martensite fraction in [0, 1]; by default 1 below A_s (relaxed),
        0 above A_f, and on the major heating curve in between.
    max_step_k : float
        Largest temperature change [K] of one step inside the transformation band.
    max_step_s : float
        Largest step [s] when recording traces (5 ms: linear interpolation of a
        45 K exponential decay with tau = 0.53 s then errs by < 0.001 K).
        Unrecorded runs use tau / 10.

    Notes
    -----
    Energy accounts [J] accumulate over the model's life: ``electrical_j``
    (int s I^2 R dt) and ``convected_j`` (int h A_s (T - T_amb) dt); stored and
    latent follow from the state, so ``electrical = C (T - T0) + convected +
    rho V L_h (xi0 - xi)``.
    """

    def __init__(
        self,
        spec: WireSpec,
        circuit: Circuit | None = None,
        temperature_c: float | None = None,
        martensite_fraction: float | None = None,
        *,
        max_step_k: float = 0.2,
        max_step_s: float = 5e-3,
    ) -> None:
        self.spec = spec
        self.circuit = Circuit.resolve(circuit, spec)
        T = spec.ambient_c if temperature_c is None else float(temperature_c)
        if not math.isfinite(T):
            raise WireError(f"<wire {spec.name}>", f"initial temperature must be finite, got {temperature_c!r}")
        if martensite_fraction is None:
            xi = spec.heating_fraction(T)
        else:
            xi = float(martensite_fraction)
            if not 0.0 <= xi <= 1.0:
                raise WireError(f"<wire {spec.name}>", f"martensite fraction must be in [0, 1], got {xi!r}")
        if not (max_step_k > 0 and max_step_s > 0):
            raise WireError(f"<wire {spec.name}>", "max_step_k and max_step_s must be > 0")
        self.temperature_c = T
        self.martensite_fraction = xi
        self.initial_temperature_c = T
        self.initial_martensite_fraction = xi
        self.max_step_k = float(max_step_k)
        self.max_step_s = float(max_step_s)
        self.time_s = 0.0
        self.electrical_j = 0.0
        self.convected_j = 0.0
        # Branch: +1 heating, -1 cooling, 0 none yet; _k scales the restarted curve.
        self._branch = 0
        self._k = 1.0

    # -- reading the state

    @property
    def stored_j(self) -> float:
        """Sensible heat gained since the start [J]: C (T - T0)."""
        return self.spec.heat_capacity_j_k * (self.temperature_c - self.initial_temperature_c)

    @property
    def latent_j(self) -> float:
        """Heat absorbed by the transformation since the start [J]: rho V L_h (xi0 - xi)."""
        return self.spec.latent_j * (self.initial_martensite_fraction - self.martensite_fraction)

    @property
    def displacement_m(self) -> float:
        """Pin displacement now [m]."""
        return self.spec.displacement_m(self.martensite_fraction)

    @property
    def resistance_ohm(self) -> float:
        """The wire's resistance now [ohm] (what a sense resistor measures)."""
        return self.spec.resistance_at(self.martensite_fraction)

    @property
    def current_a(self) -> float:
        """Current [A] that flows while the switch conducts, at today's resistance."""
        return self.circuit.current_at(self.resistance_ohm)

    # -- integration

    def run(
        self,
        durations_s: Sequence[float],
        levels: Sequence[float],
        record: list | None = None,
        edges: list | None = None,
    ) -> None:
        """Advance through segments of constant switch level.

        Parameters
        ----------
        durations_s : sequence of float
            Length of each segment [s].
        levels : sequence of float
            Fraction of the segment's time the switch conducts, in [0, 1]
            (1: a full pulse; chopped at tens of kHz otherwise: the wire gets the
            mean heat).
        record : list, optional
            When given, ``(t_s, T_c, xi)`` of every step is appended (one flat
            list, three values per step), for interpolation onto a sample grid.
        edges : list, optional
            When given, ``(T_c, xi)`` at the end of every segment is appended.
        """
        sp = self.spec
        power = self.circuit.power_and_slope
        C = sp.heat_capacity_j_k
        hA = sp.conductance_w_k
        Lat = sp.latent_j
        Ta = sp.ambient_c
        RA = sp.resistance_austenite_ohm
        dR = sp.resistance_martensite_ohm - RA
        As, Af, Ms, Mf = sp.austenite_start_c, sp.austenite_finish_c, sp.martensite_start_c, sp.martensite_finish_c
        tau = C / hA
        dt_cap = self.max_step_s if record is not None else tau / 10
        dTmax = self.max_step_k
        exp, log = math.exp, math.log

        T = self.temperature_c
        xi = self.martensite_fraction
        t = self.time_s
        Ein = self.electrical_j
        Econv = self.convected_j
        branch = self._branch
        k = self._k
        rec = record.extend if record is not None else None
        if rec is not None and not record:
            rec((t, T, xi))

        for dur, lev in zip(durations_s, levels):
            if dur <= 0:
                continue
            rem = dur
            P = lev * power(RA + dR * xi)[0] if lev > 0 else 0.0
            # Direction of this segment (monotone in T, see the module docstring).
            direction = 1 if P - hA * (T - Ta) > 0 else -1
            if direction != branch:
                branch = direction
                k = _restart_scale(sp, T, xi, branch)
            while rem > 0:
                P = lev * power(RA + dR * xi)[0] if lev > 0 else 0.0
                if branch > 0:
                    active = As < T < Af and k > 0
                    edge = As if T <= As else None
                else:
                    active = Mf < T < Ms and k > 0
                    edge = Ms if T >= Ms else None
                if not active:
                    # Linear ODE, exact: T -> Tinf with time constant tau.
                    Tinf = Ta + P / hA
                    step = rem if rem < dt_cap else dt_cap
                    # Where the step ends when it reaches the band's edge (None: it does not).
                    hit_c: float | None = None
                    if edge is not None and k > 0 and (Tinf - edge) * branch > 0:
                        # The equilibrium lies past the band edge: reach it exactly.
                        t_edge = tau * log((T - Tinf) / (edge - Tinf))
                        if t_edge <= step:
                            step = t_edge if t_edge > 0 else 0.0
                            # Just inside the band, so the next step sees it active.
                            hit_c = edge + 1e-9 * branch
                    e = exp(-step / tau)
                    T1 = Tinf + (T - Tinf) * e if hit_c is None else hit_c
                    Ein += P * step
                    Econv += hA * ((Tinf - Ta) * step + (T - Tinf) * tau * (1 - e))
                    T = T1
                    t += step
                    rem -= step
                    if rec is not None:
                        rec((t, T, xi))
                    continue
                # Inside the active band: Crank-Nicolson on the enthalpy, Newton.
                dxi = branch_fraction(sp, T, branch, k)[1]
                Fn = P - hA * (T - Ta)
                Ceff = C - Lat * dxi
                step = rem if rem < dt_cap else dt_cap
                if Fn != 0:
                    lim = dTmax * Ceff / abs(Fn)
                    if lim < step:
                        step = lim
                T0, xi0, P0 = T, xi, P
                T1 = T0 + step * Fn / Ceff
                base = C * T0 - Lat * xi0 + step * (0.5 * P0 - hA * (0.5 * T0 - Ta))
                c1 = C + 0.5 * step * hA
                for _ in range(12):
                    x1, d1 = branch_fraction(sp, T1, branch, k)
                    if lev > 0:
                        P1, dP1 = power(RA + dR * x1)
                        P1 *= lev
                        dP1 *= lev
                    else:
                        P1 = dP1 = 0.0
                    # G(T1) = C T1 - Lat x1 + step (hA T1 - P(x1)) / 2 - base, increasing in T1.
                    gval = c1 * T1 - Lat * x1 - 0.5 * step * P1 - base
                    gp = c1 - Lat * d1 - 0.5 * step * dP1 * dR * d1
                    delta = gval / gp
                    T1 -= delta
                    # 1e-8 K: the energy error per step is below 1e-12 J.
                    if -1e-8 < delta < 1e-8:
                        break
                # x1 is that of the last Newton iterate, within 1e-8 K of T1:
                # recomputing it would change the energy by < 1e-11 J.
                x1 = 1.0 if x1 > 1.0 else 0.0 if x1 < 0.0 else x1
                P1 = lev * power(RA + dR * x1)[0] if lev > 0 else 0.0
                Ein += step * 0.5 * (P0 + P1)
                Econv += step * hA * (0.5 * (T0 + T1) - Ta)
                T, xi = T1, x1
                t += step
                rem -= step
                if rec is not None:
                    rec((t, T, xi))
            if edges is not None:
                edges.append((T, xi))

        self.temperature_c = T
        self.martensite_fraction = xi
        self.time_s = t
        self.electrical_j = Ein
        self.convected_j = Econv
        self._branch = branch
        self._k = k
