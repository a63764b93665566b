"""Electro-thermal model of an SMA (NiTi) micro-wire and the safety envelope derived from it.

The wire is a lumped body (one temperature, one martensite fraction), exactly as
written in ``FACTS.md`` section 2::

    rho c V dT/dt = I^2 R(xi) - h A_s (T - T_amb) + rho V L_h dxi/dt

with Liang-Rogers cosine kinetics, minor hysteresis loops that restart from the
last reversal point, a resistance that moves between the martensite and austenite
values with ``xi``, and a contraction ``L eps_L (1 - xi)`` multiplied by the pin's
lever gain.

Integration scheme (why it is fast and exact where it matters)
--------------------------------------------------------------
The current is piecewise constant (pulses), so the integrator walks *segments* of
constant current instead of fixed time steps.  Inside one segment the equation is
an autonomous scalar ODE in ``T`` (``xi`` is a function of ``T`` on the active
branch), so ``T`` is monotone and the heating/cooling branch cannot change within
it; reversals happen only at current edges, exactly where Liang-Rogers restarts.

* Outside the active transformation range the ODE is linear and solved exactly
  (exponential), stopping exactly where the band begins.
* Inside it, Crank-Nicolson on the enthalpy ``C T - rho V L_h xi`` with a Newton
  solve, sub-stepped so that no step moves more than ``max_step_k`` (0.2 K by
  default, 1/20 of the 4 K branch width).  This form conserves energy exactly
  (electrical in = stored + convected + latent, to the Newton tolerance).

A 300 Hz train of 50 us pulses therefore costs a handful of steps per period
whatever the sampling step of the input; pulse edges are exact.  The sampling step
of :func:`simulate` (default :data:`DEFAULT_DT_S` = 5 us) only quantises the edges
of a sampled current: a 50 us pulse is then known to 10 %, 20 us (the shortest the
profiles allow) to 25 %.  :func:`simulate_drive` schedules edges exactly.

Units: SI inside (metres, seconds, amperes, ohms, joules), temperatures in degrees
Celsius (names end in ``_c``).
"""

from __future__ import annotations

import bisect
import dataclasses
import hashlib
import json
import math
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..errors import WireError
from ..mapping import Drive

__all__ = [
    "WireSpec",
    "WireModel",
    "SimulationResult",
    "CycleResult",
    "SafetyEnvelope",
    "simulate",
    "simulate_drive",
    "steady_cycle",
    "build_envelope",
    "wire_names",
    "DEFAULT_DT_S",
    "FOLLOW_THRESHOLD_M",
]

#: Sampling step [s] of :func:`simulate_drive` and the CLI (see the module docstring).
DEFAULT_DT_S = 5e-6
#: A pulse "is followed" when it produces its own displacement peak at least this
#: high [m] (issue 3: 0.01 um).
FOLLOW_THRESHOLD_M = 0.01e-6
#: Bumped whenever the physics changes, so cached envelopes are rebuilt.
MODEL_VERSION = 2
try:
    _SOURCE_HASH = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:12]
except OSError:  # frozen or zipped install: the version alone
    _SOURCE_HASH = ""


# --------------------------------------------------------------------------- the wire


@dataclass(frozen=True)
class WireSpec:
    """Physical description of one SMA wire actuator and its operating conditions.

    Parameters
    ----------
    name : str
        Label (presets: ``"50um"``, ``"75um"``, ``"100um"``).
    diameter_m : float
        Wire diameter [m]; the paper's is 75 um.
    length_m : float
        Active length [m].  Default 3 mm: a pin actuator in a pen grip is a few mm
        long, and FACTS.md section 2 ("Operating point") is worked out for 3 mm.
    density_kg_m3, specific_heat_j_kg_k, latent_heat_j_kg : float
        6450 kg/m^3, 837 J/(kg K), 24.2 kJ/kg (FACTS.md section 2, datasheet values).
    resistivity_martensite_ohm_m, resistivity_austenite_ohm_m : float
        80 and 100 uOhm cm (FACTS.md section 2).
    convection_w_m2_k : float
        Still-air film coefficient h [W/(m^2 K)]; 190 for 75 um, scaled as
        D^-0.83 for the other presets (FACTS.md section 2).
    austenite_start_c, austenite_finish_c, martensite_start_c, martensite_finish_c : float
        Transformation temperatures [deg C].  The paper gives only T1 = 68 C (back
        to length) and T2 = 73 C (contracted).  Assumption: T2 is the end of the
        heating branch (A_f = 73), T1 the end of the cooling branch (M_f = 68),
        each branch 4 K wide, which leaves 1 K of thermal hysteresis
        (A_s = 69, M_s = 72).
    max_strain : float
        Recoverable strain eps_L (5 %, the paper).
    lever_gain : float
        Pin displacement per metre of wire contraction.  The paper says only that
        the pin makes the stimulus greater; 1.0 reports the wire's own
        contraction, the quantity the paper measured (about 2 um at 50 Hz).
    rated_current_a : float
        Peak pulse current [A] into the relaxed wire at drive amplitude 1.0.
        0.5 A for 75 um puts 5 % duty in the middle of the band where the model
        vibrates (FACTS.md "Operating point": 0.7 .. 0.3 A at 2 .. 10 % duty);
        scaled as D^1.085 for the other presets, which keeps the same duty
        (I^2 R duty = h pi D L dT with h ~ D^-0.83).
    source_resistance_ohm : float
        Output resistance of the driver [ohm].  A current given to the model is
        the pulse current into the *relaxed* (martensite) wire; the source is a
        voltage ``I (R_s + R_M)`` behind ``R_s``, so the real current falls as the
        wire's resistance rises.  Default 0: the paper's controller switches two
        AA cells onto the wire, a voltage source.  ``math.inf`` gives an ideal
        current source.  Why it matters: with FACTS.md's resistivities
        (austenite 25 % above martensite) a current source heats a contracting
        wire *more*, a positive feedback that makes the lumped wire jump across
        its 5 K band (vibrating only in a window about 1 % wide in duty at 50 Hz,
        and not at all at 300 Hz); a voltage source heats it less, a negative
        feedback that holds the mean temperature in the band over a usable
        range of duty.
    ambient_c : float
        Air temperature around the wire [deg C].
    max_temperature_c : float
        Highest temperature the envelope allows [deg C].  Assumption: 90 C,
        17 K above A_f, well below the 100+ C where NiTi loses its training.
    """

    name: str = "75um"
    diameter_m: float = 75e-6
    length_m: float = 3e-3
    density_kg_m3: float = 6450.0
    specific_heat_j_kg_k: float = 837.0
    latent_heat_j_kg: float = 24.2e3
    resistivity_martensite_ohm_m: float = 80e-8
    resistivity_austenite_ohm_m: float = 100e-8
    convection_w_m2_k: float = 190.0
    austenite_start_c: float = 69.0
    austenite_finish_c: float = 73.0
    martensite_start_c: float = 72.0
    martensite_finish_c: float = 68.0
    max_strain: float = 0.05
    lever_gain: float = 1.0
    rated_current_a: float = 0.5
    source_resistance_ohm: float = 0.0
    ambient_c: float = 25.0
    max_temperature_c: float = 90.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name == "name":
                continue
            v = getattr(self, f.name)
            if f.name == "source_resistance_ohm":
                if not isinstance(v, (int, float)) or isinstance(v, bool) or not (v >= 0):
                    raise WireError(f"<wire {self.name}>", f"source_resistance_ohm must be >= 0, got {v!r}")
                continue
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise WireError(f"<wire {self.name}>", f"{f.name} must be a finite number, got {v!r}")
            if f.name not in ("ambient_c", "austenite_start_c", "austenite_finish_c",
                              "martensite_start_c", "martensite_finish_c", "max_temperature_c") and v <= 0:
                raise WireError(f"<wire {self.name}>", f"{f.name} must be > 0, got {v!r}")
        if not (self.austenite_start_c < self.austenite_finish_c and self.martensite_finish_c < self.martensite_start_c):
            raise WireError(f"<wire {self.name}>", "need A_s < A_f and M_f < M_s")
        # The restart curves divide by how much of a branch is left at the reversal
        # point; these orderings keep that bounded away from zero.
        if not (self.martensite_finish_c < self.austenite_start_c and self.martensite_start_c < self.austenite_finish_c):
            raise WireError(f"<wire {self.name}>", "need M_f < A_s and M_s < A_f")
        if not self.max_strain < 1:
            raise WireError(f"<wire {self.name}>", "max_strain must be < 1")
        if not self.max_temperature_c > self.austenite_finish_c:
            raise WireError(f"<wire {self.name}>", "max_temperature_c must be above A_f")
        if not self.ambient_c < self.martensite_finish_c:
            raise WireError(f"<wire {self.name}>", "ambient_c must be below M_f (the wire must be able to relax)")

    # -- presets

    @classmethod
    def preset(cls, name: str, length_m: float | None = None, **changes: Any) -> "WireSpec":
        """A preset wire by name (``"50um"``, ``"75um"``, ``"100um"``), optionally changed."""
        key = str(name).strip().lower().replace("µ", "u")
        if key not in _PRESETS:
            raise WireError(str(name), f"no such wire (known: {', '.join(wire_names())})")
        spec = _PRESETS[key]
        if length_m is not None:
            changes["length_m"] = length_m
        if changes:
            try:
                spec = dataclasses.replace(spec, **changes)
            except TypeError as exc:
                raise WireError(str(name), str(exc)) from None
        return spec

    @classmethod
    def resolve(cls, wire: "WireSpec | str | None") -> "WireSpec":
        """A :class:`WireSpec` from a spec, a preset name, or None (the paper's 75 um)."""
        if wire is None:
            return _PRESETS["75um"]
        if isinstance(wire, WireSpec):
            return wire
        return cls.preset(wire)

    def replace(self, **changes: Any) -> "WireSpec":
        return dataclasses.replace(self, **changes)

    # -- derived quantities (SI)

    @property
    def cross_section_m2(self) -> float:
        return math.pi * self.diameter_m**2 / 4

    @property
    def volume_m3(self) -> float:
        return self.cross_section_m2 * self.length_m

    @property
    def surface_m2(self) -> float:
        """Lateral surface [m^2] (the ends are clamped, not cooled by air)."""
        return math.pi * self.diameter_m * self.length_m

    @property
    def heat_capacity_j_k(self) -> float:
        """rho c V [J/K]."""
        return self.density_kg_m3 * self.specific_heat_j_kg_k * self.volume_m3

    @property
    def conductance_w_k(self) -> float:
        """h A_s [W/K]."""
        return self.convection_w_m2_k * self.surface_m2

    @property
    def latent_j(self) -> float:
        """rho V L_h [J]: heat absorbed by a full martensite -> austenite transformation."""
        return self.density_kg_m3 * self.volume_m3 * self.latent_heat_j_kg

    @property
    def time_constant_s(self) -> float:
        """Thermal time constant rho c V / (h A_s) [s] outside the transformation band."""
        return self.heat_capacity_j_k / self.conductance_w_k

    @property
    def resistance_martensite_ohm(self) -> float:
        return self.resistivity_martensite_ohm_m * self.length_m / self.cross_section_m2

    @property
    def resistance_austenite_ohm(self) -> float:
        return self.resistivity_austenite_ohm_m * self.length_m / self.cross_section_m2

    def resistance_ohm(self, martensite_fraction: float) -> float:
        """Resistance [ohm] at a martensite fraction (linear mix of the phases)."""
        xi = martensite_fraction
        return self.resistance_austenite_ohm + (self.resistance_martensite_ohm - self.resistance_austenite_ohm) * xi

    @property
    def stroke_m(self) -> float:
        """Pin displacement [m] of a full transformation: gain * L * eps_L."""
        return self.lever_gain * self.length_m * self.max_strain

    def displacement_m(self, martensite_fraction: Any) -> Any:
        """Pin displacement [m] (0 when relaxed): gain * L * eps_L * (1 - xi)."""
        return self.stroke_m * (1.0 - martensite_fraction)

    def current_a(self, drive: Drive) -> float:
        """Peak pulse current [A] for a drive: amplitude * rated current."""
        return drive.amplitude * self.rated_current_a

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def key(self) -> str:
        """A short hash of every field, the model version and this module's source (cache key).

        The source is part of it so that an edited model never reuses an
        envelope computed by the old one."""
        text = json.dumps({"v": MODEL_VERSION, "src": _SOURCE_HASH, **self.to_dict()}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _scaled_preset(name: str, diameter_m: float) -> WireSpec:
    ratio = diameter_m / 75e-6
    # FACTS.md section 2: h ~ D^-0.83; current for the same duty ~ D^((3 - 0.83)/2).
    return WireSpec(
        name=name,
        diameter_m=diameter_m,
        convection_w_m2_k=190.0 * ratio**-0.83,
        rated_current_a=0.5 * ratio ** ((3 - 0.83) / 2),
    )


_PRESETS: dict[str, WireSpec] = {
    "50um": _scaled_preset("50um", 50e-6),
    "75um": WireSpec(),
    "100um": _scaled_preset("100um", 100e-6),
}


def wire_names() -> list[str]:
    """Names of the preset wires."""
    return list(_PRESETS)


# --------------------------------------------------------------------------- the model


class WireModel:
    """The wire's state and the segment integrator (see the module docstring).

    Parameters
    ----------
    spec : WireSpec
        The wire.
    temperature_c : float, optional
        Initial temperature [deg C]; ambient by default.
    martensite_fraction : float, optional
        Initial martensite fraction in [0, 1]; by default 1 below A_s (relaxed),
        0 above A_f, and on the major heating curve in between.
    max_step_k : float
        Largest temperature change [K] of one step inside the transformation band.
    max_step_s : float
        Largest step [s] when recording traces (5 ms: linear interpolation of
        a 45 K exponential decay with tau = 0.53 s then errs by < 0.001 K).
        Unrecorded runs use tau / 10.

    Notes
    -----
    Energy accounts [J] accumulate over the model's life: ``electrical_j``
    (int I^2 R dt) and ``convected_j`` (int h A_s (T - T_amb) dt); stored and
    latent follow from the state, so ``electrical = C (T - T0) + convected +
    rho V L_h (xi0 - xi)``.
    """

    def __init__(
        self,
        spec: WireSpec,
        temperature_c: float | None = None,
        martensite_fraction: float | None = None,
        *,
        max_step_k: float = 0.2,
        max_step_s: float = 5e-3,
    ) -> None:
        self.spec = spec
        T = spec.ambient_c if temperature_c is None else float(temperature_c)
        if not math.isfinite(T):
            raise WireError(f"<wire {spec.name}>", f"initial temperature must be finite, got {temperature_c!r}")
        if martensite_fraction is None:
            if T <= spec.austenite_start_c:
                xi = 1.0
            elif T >= spec.austenite_finish_c:
                xi = 0.0
            else:
                xi = 0.5 * (1 + math.cos(math.pi * (T - spec.austenite_start_c) / (spec.austenite_finish_c - spec.austenite_start_c)))
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

    # -- bookkeeping

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
        return self.spec.displacement_m(self.martensite_fraction)

    # -- integration

    def run(
        self,
        durations_s: Sequence[float],
        currents_a: Sequence[float],
        record: list | None = None,
        edges: list | None = None,
    ) -> None:
        """Advance through segments of constant current.

        Parameters
        ----------
        durations_s : sequence of float
            Length of each segment [s].
        currents_a : sequence of float
            Current during each segment [A] (its sign does not matter).
        record : list, optional
            When given, ``(t_s, T_c, xi)`` of every step is appended (one flat
            list, three values per step), for interpolation onto a sample grid.
        edges : list, optional
            When given, ``(T_c, xi)`` at the end of every segment is appended.
        """
        sp = self.spec
        C = sp.heat_capacity_j_k
        hA = sp.conductance_w_k
        Lat = sp.latent_j
        Ta = sp.ambient_c
        RA = sp.resistance_austenite_ohm
        RM = sp.resistance_martensite_ohm
        dR = RM - RA
        Rs = sp.source_resistance_ohm
        vsrc = math.isfinite(Rs)
        As, Af, Ms, Mf = sp.austenite_start_c, sp.austenite_finish_c, sp.martensite_start_c, sp.martensite_finish_c
        aA = math.pi / (Af - As)
        aM = math.pi / (Ms - Mf)
        tau = C / hA
        dt_cap = self.max_step_s if record is not None else tau / 10
        dTmax = self.max_step_k
        cos, sin, exp, log = math.cos, math.sin, math.exp, math.log

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

        for dur, I in zip(durations_s, currents_a):
            if dur <= 0:
                continue
            I2 = I * I
            # V2 is the source voltage squared (see WireSpec.source_resistance_ohm).
            V2 = I2 * (Rs + RM) ** 2 if vsrc else 0.0
            rem = dur
            R = RA + dR * xi
            P = V2 * R / ((Rs + R) * (Rs + R)) if vsrc else I2 * R
            # Direction of this segment (monotone in T, see module docstring).
            F = P - hA * (T - Ta)
            direction = 1 if F > 0 else -1
            if direction != branch:
                # Liang-Rogers restart from the reversal point (T, xi).
                branch = direction
                if branch > 0:
                    if T <= As:
                        h = 1.0
                    elif T >= Af:
                        h = 0.0
                    else:
                        h = 0.5 * (1 + cos(aA * (T - As)))
                    k = xi / h if h > 1e-12 else 0.0
                else:
                    if T <= Mf:
                        g = 0.0
                    elif T >= Ms:
                        g = 1.0
                    else:
                        g = 1.0 - 0.5 * (1 + cos(aM * (T - Mf)))
                    k = (1.0 - xi) / g if g > 1e-12 else 0.0
            while rem > 0:
                R = RA + dR * xi
                P = V2 * R / ((Rs + R) * (Rs + R)) if vsrc else I2 * R
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
                    hit = False
                    if edge is not None and k > 0 and (Tinf - edge) * branch > 0:
                        # The equilibrium lies past the band edge: reach it exactly.
                        t_edge = tau * log((T - Tinf) / (edge - Tinf))
                        if t_edge <= step:
                            step = t_edge if t_edge > 0 else 0.0
                            hit = True
                    e = exp(-step / tau)
                    T1 = Tinf + (T - Tinf) * e
                    if hit:
                        # Just inside the band, so the next step sees it active.
                        T1 = edge + 1e-9 * branch
                    Ein += P * step
                    Econv += hA * ((Tinf - Ta) * step + (T - Tinf) * tau * (1 - e))
                    T = T1
                    t += step
                    rem -= step
                    if rec is not None:
                        rec((t, T, xi))
                    continue
                # Inside the active band: Crank-Nicolson on the enthalpy, Newton.
                if branch > 0:
                    dxi = -k * 0.5 * aA * sin(aA * (T - As))
                else:
                    dxi = -k * 0.5 * aM * sin(aM * (T - Mf))
                Fn = P - hA * (T - Ta)
                Ceff = C - Lat * dxi
                step = rem if rem < dt_cap else dt_cap
                if Fn != 0:
                    lim = dTmax * Ceff / abs(Fn)
                    if lim < step:
                        step = lim
                T0, xi0 = T, xi
                T1 = T0 + step * Fn / Ceff
                P0 = P
                base = C * T0 - Lat * xi0 + step * (0.5 * P0 - hA * (0.5 * T0 - Ta))
                c1 = C + 0.5 * step * hA
                for _ in range(12):
                    if branch > 0:
                        if T1 <= As:
                            x1 = k; d1 = 0.0
                        elif T1 >= Af:
                            x1 = 0.0; d1 = 0.0
                        else:
                            u = aA * (T1 - As)
                            x1 = k * 0.5 * (1 + cos(u)); d1 = -k * 0.5 * aA * sin(u)
                    else:
                        if T1 <= Mf:
                            x1 = 1.0; d1 = 0.0
                        elif T1 >= Ms:
                            x1 = 1.0 - k; d1 = 0.0
                        else:
                            u = aM * (T1 - Mf)
                            x1 = 1.0 - k * (0.5 - 0.5 * cos(u)); d1 = -k * 0.5 * aM * sin(u)
                    # g(T1) = C T1 - Lat x1 + step (hA T1 - P(x1)) / 2 - base, increasing in T1.
                    R1 = RA + dR * x1
                    if vsrc:
                        s1 = Rs + R1
                        P1 = V2 * R1 / (s1 * s1)
                        dP1 = V2 * (Rs - R1) / (s1 * s1 * s1)
                    else:
                        P1 = I2 * R1
                        dP1 = I2
                    gval = c1 * T1 - Lat * x1 - 0.5 * step * P1 - base
                    gp = c1 - Lat * d1 - 0.5 * step * dP1 * dR * d1
                    delta = gval / gp
                    T1 -= delta
                    # 1e-8 K: the energy error per step is below 1e-12 J.
                    if -1e-8 < delta < 1e-8:
                        break
                # x1 is that of the last Newton iterate, within 1e-8 K of T1:
                # recomputing it would change the energy by < 1e-11 J.
                if x1 > 1.0:
                    x1 = 1.0
                elif x1 < 0.0:
                    x1 = 0.0
                R1 = RA + dR * x1
                P1 = V2 * R1 / ((Rs + R1) * (Rs + R1)) if vsrc else I2 * R1
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


# --------------------------------------------------------------------------- simulation


@dataclass(frozen=True)
class SimulationResult:
    """Traces of one simulation, sampled on a uniform grid.

    Attributes
    ----------
    time_s : ndarray, shape (N + 1,)
        Sample instants [s], ``0 .. N dt``.
    current_a : ndarray, shape (N,)
        The commanded current [A]; ``current_a[i]`` flows from ``time_s[i]`` to
        ``time_s[i + 1]`` (into the relaxed wire, see ``WireSpec.source_resistance_ohm``).
    temperature_c, martensite_fraction, displacement_m : ndarray, shape (N + 1,)
        Wire temperature [deg C], martensite fraction, pin displacement [m].
    pulse_starts_s : ndarray
        Onset of every pulse [s] (rising edges of the current).
    electrical_j, stored_j, convected_j, latent_j : float
        Energy accounts over the run [J]: electrical in = stored + convected + latent.
    spec : WireSpec
        The wire simulated.
    """

    time_s: np.ndarray
    current_a: np.ndarray
    temperature_c: np.ndarray
    martensite_fraction: np.ndarray
    displacement_m: np.ndarray
    pulse_starts_s: np.ndarray
    electrical_j: float
    stored_j: float
    convected_j: float
    latent_j: float
    spec: WireSpec = field(repr=False)
    #: per-pulse (start, pulse end, next start) displacement [m], when known exactly
    pulse_edges_m: np.ndarray | None = field(default=None, repr=False)

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1])

    @property
    def energy_balance_error(self) -> float:
        """(electrical - stored - convected - latent) / electrical (dimensionless)."""
        if self.electrical_j == 0:
            return 0.0
        return (self.electrical_j - self.stored_j - self.convected_j - self.latent_j) / self.electrical_j

    def summary(self, settle_s: float | None = None) -> dict[str, Any]:
        """What the CLI reports, measured once settled.

        Parameters
        ----------
        settle_s : float, optional
            Start of the settled window [s]; default: the last third of the run.

        Returns
        -------
        dict
            ``displacement_pp_um`` (peak to peak in the window), ``follows`` (every
            pulse in the window has its own displacement peak of at least
            :data:`FOLLOW_THRESHOLD_M`), ``pulses_followed`` / ``pulses_in_window``,
            ``mean_temperature_c``, ``peak_temperature_c``, ``min_temperature_c``,
            ``mean_martensite_fraction``, and the energy accounts in joules.
        """
        t = self.time_s
        start = t[-1] * 2 / 3 if settle_s is None else float(settle_s)
        i0 = int(np.searchsorted(t, start))
        i0 = min(i0, len(t) - 2)
        T = self.temperature_c[i0:]
        d = self.displacement_m[i0:]
        per = self.per_pulse_rise_m(start)
        swing = self.per_pulse_swing_m(start)
        followed = int(np.count_nonzero(per >= FOLLOW_THRESHOLD_M))
        return {
            "displacement_pp_um": float(np.median(swing) if swing.size else d.max() - d.min()) * 1e6,
            "follows": bool(per.size > 0 and followed == per.size),
            "pulses_followed": followed,
            "pulses_in_window": int(per.size),
            "mean_temperature_c": float(np.mean(T)),
            "peak_temperature_c": float(np.max(self.temperature_c)),
            "settled_peak_temperature_c": float(np.max(T)),
            "min_temperature_c": float(np.min(T)),
            "mean_martensite_fraction": float(np.mean(self.martensite_fraction[i0:])),
            "electrical_j": self.electrical_j,
            "stored_j": self.stored_j,
            "convected_j": self.convected_j,
            "latent_j": self.latent_j,
        }

    def _period_index(self, from_s: float) -> np.ndarray:
        starts = self.pulse_starts_s
        idx = np.searchsorted(self.time_s, starts - 1e-12)
        return idx[starts >= from_s - 1e-12]

    def per_pulse_swing_m(self, from_s: float = 0.0) -> np.ndarray:
        """Peak-to-peak displacement [m] within each complete pulse period from ``from_s``."""
        if self.pulse_edges_m is not None:
            e = self.pulse_edges_m[self.pulse_starts_s[: len(self.pulse_edges_m)] >= from_s - 1e-12]
            return e.max(axis=1) - e.min(axis=1) if len(e) else np.zeros(0)
        idx = self._period_index(from_s)
        if idx.size < 2:
            return np.zeros(0)
        d = self.displacement_m[idx[0] : idx[-1] + 1]
        rel = idx[:-1] - idx[0]
        return np.maximum.reduceat(d, rel) - np.minimum.reduceat(d, rel)

    def per_pulse_rise_m(self, from_s: float = 0.0) -> np.ndarray:
        """For each complete pulse period starting at or after ``from_s``: how far the
        displacement peak stands above both its start and the next pulse's start [m]
        (its own peak; 0 when the wire did not move back and forth)."""
        starts = self.pulse_starts_s
        if self.pulse_edges_m is not None:
            e = self.pulse_edges_m
            keep = starts[: len(e)] >= from_s - 1e-12
            e = e[keep]
            return np.minimum(e[:, 1] - e[:, 0], e[:, 1] - e[:, 2]) if len(e) else np.zeros(0)
        idx = self._period_index(from_s)
        if idx.size < 2:
            return np.zeros(0)
        d = self.displacement_m
        peaks = np.maximum.reduceat(d[idx[0] : idx[-1] + 1], idx[:-1] - idx[0])
        return np.minimum(peaks - d[idx[:-1]], peaks - d[idx[1:]])


def _check_dt(dt_s: float) -> float:
    if not isinstance(dt_s, (int, float)) or not math.isfinite(dt_s) or dt_s <= 0:
        raise WireError("<dt>", f"time step must be a finite number > 0 s, got {dt_s!r}")
    return float(dt_s)


def simulate(
    current_a: Any,
    dt_s: float,
    wire: WireSpec | str | None = None,
    *,
    initial_temperature_c: float | None = None,
    initial_martensite_fraction: float | None = None,
    max_step_k: float = 0.2,
) -> SimulationResult:
    """Simulate the wire under a sampled current.

    Parameters
    ----------
    current_a : array_like, shape (N,)
        Current [A], held for ``dt_s`` per sample (pulses: the value during a
        pulse, 0 between).  Into the relaxed wire; see ``WireSpec.source_resistance_ohm``.
    dt_s : float
        Sample step [s]; edges are exact at this resolution (:data:`DEFAULT_DT_S`
        resolves 50 us pulses to 10 %).
    wire : WireSpec or str, optional
        The wire, or a preset name; the paper's 75 um by default.
    initial_temperature_c, initial_martensite_fraction : float, optional
        Initial state; ambient and relaxed by default.
    max_step_k : float
        Largest temperature step [K] inside the transformation band.

    Returns
    -------
    SimulationResult
        Sampled at the N + 1 edges of the current samples.
    """
    spec = WireSpec.resolve(wire)
    dt = _check_dt(dt_s)
    try:
        cur = np.asarray(current_a, dtype=float).ravel()
    except (TypeError, ValueError):
        raise WireError("<current>", "current must be an array of numbers") from None
    if cur.size == 0:
        raise WireError("<current>", "current is empty")
    if not np.all(np.isfinite(cur)):
        raise WireError("<current>", "current has NaN or infinite samples")
    n = cur.size
    # Run-length encode: one segment per constant stretch of current.
    change = np.flatnonzero(np.diff(cur)) + 1
    bounds = np.concatenate(([0], change, [n]))
    lengths = np.diff(bounds)
    levels = cur[bounds[:-1]]
    model = WireModel(spec, initial_temperature_c, initial_martensite_fraction, max_step_k=max_step_k, max_step_s=max(dt, 5e-3))
    rec: list[float] = []
    model.run((lengths * dt).tolist(), levels.tolist(), record=rec)
    nodes = np.asarray(rec).reshape(-1, 3)
    t = np.arange(n + 1) * dt
    # Node times are sums of float steps: clamp the last one to the grid end.
    nodes[-1, 0] = t[-1]
    T = np.interp(t, nodes[:, 0], nodes[:, 1])
    xi = np.interp(t, nodes[:, 0], nodes[:, 2])
    # Pulse onsets from the run-length code: a nonzero run after a zero one (or first).
    nonzero = levels != 0
    onset = nonzero & np.concatenate(([True], ~nonzero[:-1]))
    rising = bounds[:-1][onset]
    return SimulationResult(
        time_s=t,
        current_a=cur,
        temperature_c=T,
        martensite_fraction=xi,
        displacement_m=spec.displacement_m(xi),
        pulse_starts_s=rising * dt,
        electrical_j=model.electrical_j,
        stored_j=model.stored_j,
        convected_j=model.convected_j,
        latent_j=model.latent_j,
        spec=spec,
    )


def _check_drive_request(drive: Drive, duration_s: float) -> None:
    if not isinstance(drive, Drive):
        raise WireError("<drive>", f"expected a Drive, got {type(drive).__name__}")
    if not isinstance(duration_s, (int, float)) or not math.isfinite(duration_s) or duration_s <= 0:
        raise WireError("<duration>", f"duration must be a finite number > 0 s, got {duration_s!r}")
    if not drive.is_off and drive.pulse_width_s >= drive.period_s:
        raise WireError("<drive>", f"pulse width {drive.pulse_width_s:g} s does not fit in the period {drive.period_s:g} s")


def simulate_drive(
    drive: Drive,
    duration_s: float,
    wire: WireSpec | str | None = None,
    *,
    current_a: float | None = None,
    dt_s: float = DEFAULT_DT_S,
    initial_temperature_c: float | None = None,
    initial_martensite_fraction: float | None = None,
) -> SimulationResult:
    """Simulate a steady pulse drive with exact pulse edges (no sampling of the input).

    Parameters
    ----------
    drive : Drive
        Frequency [Hz] and width [s]; simulated exactly as given (no envelope).
    duration_s : float
        Length of the run [s].
    wire : WireSpec or str, optional
        The wire; the paper's 75 um by default.
    current_a : float, optional
        Peak pulse current [A]; default ``drive.amplitude * wire.rated_current_a``.
    dt_s : float
        Step [s] of the returned traces (the integration itself is adaptive).

    Returns
    -------
    SimulationResult
        ``pulse_edges_m`` holds each period's displacement at pulse start, pulse
        end and next start, taken from the integrator (not from the sampled trace).
    """
    spec = WireSpec.resolve(wire)
    _check_drive_request(drive, duration_s)
    dt = _check_dt(dt_s)
    current = spec.current_a(drive) if current_a is None else float(current_a)
    if not math.isfinite(current) or current < 0:
        raise WireError("<current>", f"current must be a finite number >= 0 A, got {current_a!r}")
    n = max(1, int(math.floor(duration_s / dt + 0.5)))
    total = n * dt
    durations: list[float] = []
    currents: list[float] = []
    starts: list[float] = []
    if drive.is_off or current == 0:
        durations, currents = [total], [0.0]
    else:
        period, width = drive.period_s, drive.pulse_width_s
        full = int(math.floor(total / period + 1e-12))
        durations = [width, period - width] * full
        currents = [current, 0.0] * full
        starts = [k * period for k in range(full)]
        t_last = full * period
        if t_last < total - 1e-15:
            # A last, cut period.
            on = min(width, total - t_last)
            durations += [on, max(0.0, total - t_last - on)]
            currents += [current, 0.0]
            starts.append(t_last)
    model = WireModel(spec, initial_temperature_c, initial_martensite_fraction, max_step_s=max(dt, 5e-3))
    rec: list[float] = []
    edges: list[tuple[float, float]] = []
    model.run(durations, currents, record=rec, edges=edges)
    nodes = np.asarray(rec).reshape(-1, 3)
    t = np.arange(n + 1) * dt
    nodes[-1, 0] = t[-1]
    T = np.interp(t, nodes[:, 0], nodes[:, 1])
    xi = np.interp(t, nodes[:, 0], nodes[:, 2])
    pulse_edges = None
    if starts:
        # xi at each pulse start, pulse end, next start; only complete periods.
        xs = np.concatenate(([model.initial_martensite_fraction], np.asarray(edges)[:, 1]))
        m = (len(xs) - 1) // 2
        offs = np.asarray(durations[1 : 2 * m : 2])
        ci = np.flatnonzero(offs >= drive.period_s - drive.pulse_width_s - 1e-12)
        if ci.size:
            pulse_edges = spec.displacement_m(np.stack([xs[2 * ci], xs[2 * ci + 1], xs[2 * ci + 2]], axis=1))
    # The current on the sample grid: +I at each onset sample, -I at each end, summed.
    steps = np.zeros(n + 1, dtype=np.int32)
    if starts:
        st = np.asarray(starts)
        on_idx = np.minimum(np.floor(st / dt + 0.5).astype(np.int64), n)
        off_idx = np.minimum(np.floor((st + drive.pulse_width_s) / dt + 0.5).astype(np.int64), n)
        steps += np.bincount(on_idx, minlength=n + 1)[: n + 1].astype(np.int32)
        steps -= np.bincount(off_idx, minlength=n + 1)[: n + 1].astype(np.int32)
    cur = np.cumsum(steps[:n]) * current
    return SimulationResult(
        time_s=t,
        current_a=cur,
        temperature_c=T,
        martensite_fraction=xi,
        displacement_m=spec.displacement_m(xi),
        pulse_starts_s=np.asarray(starts[: (len(pulse_edges) if pulse_edges is not None else len(starts))]),
        electrical_j=model.electrical_j,
        stored_j=model.stored_j,
        convected_j=model.convected_j,
        latent_j=model.latent_j,
        spec=spec,
        pulse_edges_m=pulse_edges,
    )


# --------------------------------------------------------------------------- steady state


@dataclass(frozen=True)
class CycleResult:
    """The settled (periodic) response of the wire to a steady pulse drive.

    Attributes
    ----------
    frequency_hz, pulse_width_s, current_a : float
        The drive [Hz, s, A].
    min_temperature_c, peak_temperature_c, mean_temperature_c : float
        Over the settled period [deg C] (min at pulse onset, peak at pulse end).
    martensite_start, martensite_end : float
        Fraction at pulse onset and pulse end.
    displacement_pp_m : float
        Displacement swing of one settled period [m].
    follows : bool
        The pulse produces its own displacement peak >= :data:`FOLLOW_THRESHOLD_M`.
    held_contracted : bool
        Does not follow and is mostly austenite: the wire stays contracted.
    settled : bool
        Over the last half second (at least) the mean temperature moved less than
        0.01 K and the martensite fraction less than 0.002, after at least three
        time constants.
    """

    frequency_hz: float
    pulse_width_s: float
    current_a: float
    min_temperature_c: float
    peak_temperature_c: float
    mean_temperature_c: float
    martensite_start: float
    martensite_end: float
    displacement_pp_m: float
    follows: bool
    held_contracted: bool
    settled: bool

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def steady_cycle(
    frequency_hz: float,
    pulse_width_s: float,
    current_a: float,
    wire: WireSpec | str | None = None,
    *,
    max_duration_s: float = 30.0,
) -> CycleResult:
    """Run a steady pulse drive until the wire settles and describe one period.

    The run starts from the temperature the mean power would hold with the wire
    relaxed (an energy balance), so it needs a few thermal time constants rather
    than many; it stops when the mean temperature of the last half second moved
    less than 0.01 K from the one before (or at ``max_duration_s``).

    Parameters
    ----------
    frequency_hz, pulse_width_s, current_a : float
        The drive [Hz, s, A]; current into the relaxed wire.
    wire : WireSpec or str, optional
        The wire; the paper's 75 um by default.
    """
    spec = WireSpec.resolve(wire)
    f, w, cur = float(frequency_hz), float(pulse_width_s), float(current_a)
    if not (f > 0 and 0 < w < 1 / f and cur >= 0 and math.isfinite(cur)):
        raise WireError("<drive>", f"need frequency > 0, 0 < width < period and current >= 0 (got {f}, {w}, {cur})")
    period = 1 / f
    duty = w * f
    hA = spec.conductance_w_k
    RM = spec.resistance_martensite_ohm
    T0 = spec.ambient_c + duty * cur * cur * RM / hA
    T0 = min(T0, spec.austenite_start_c - 0.5) if T0 > spec.martensite_finish_c else T0
    model = WireModel(spec, temperature_c=T0, martensite_fraction=1.0)
    per_block = max(1, int(round(0.5 * f)))
    block = [w, period - w] * per_block
    currents = [cur, 0.0] * per_block
    prev_mean = None
    prev_xi = None
    settled = False
    elapsed = 0.0
    mean = T0
    while elapsed < max_duration_s:
        e0, t0 = model.convected_j, model.time_s
        edges: list[tuple[float, float]] = []
        model.run(block, currents, edges=edges)
        elapsed = model.time_s
        mean = spec.ambient_c + (model.convected_j - e0) / (hA * (model.time_s - t0))
        xi_now = model.martensite_fraction
        # The martensite fraction creeps for seconds after the temperature has
        # settled (latent heat), hence the second test.
        if (
            prev_mean is not None
            and abs(mean - prev_mean) < 0.01
            and abs(xi_now - prev_xi) < 0.002
            and elapsed >= 3 * spec.time_constant_s
        ):
            settled = True
            break
        prev_mean, prev_xi = mean, xi_now
    # The last period: edges[-2] is pulse end, edges[-1] next onset, edges[-3] this onset.
    T_on, x_on = edges[-3] if len(edges) >= 3 else (T0, 1.0)
    T_pe, x_pe = edges[-2]
    T_nx, x_nx = edges[-1]
    d = spec.displacement_m
    rise = min(d(x_pe) - d(x_on), d(x_pe) - d(x_nx))
    follows = rise >= FOLLOW_THRESHOLD_M
    return CycleResult(
        frequency_hz=f,
        pulse_width_s=w,
        current_a=cur,
        min_temperature_c=min(T_on, T_nx),
        peak_temperature_c=max(T_pe, T_on, T_nx),
        mean_temperature_c=mean,
        martensite_start=x_on,
        martensite_end=x_pe,
        displacement_pp_m=abs(d(x_pe) - d(x_on)),
        follows=bool(follows),
        held_contracted=bool(not follows and 0.5 * (x_on + x_pe) < 0.5),
        settled=settled,
    )


# --------------------------------------------------------------------------- safety envelope

#: Frequencies [Hz] and currents (fractions of the rated current) of the envelope grid.
ENVELOPE_FREQUENCIES_HZ = (1.0, 2.0, 5.0, 10.0, 20.0, 35.0, 50.0, 75.0, 100.0, 150.0, 200.0, 300.0, 400.0)
# Few currents suffice: the heating of a short pulse goes with I^2 w, so the
# allowed width scales almost exactly as 1 / I^2, which log-log interpolation
# follows; a finer current grid changed no width by more than 1 %.
ENVELOPE_CURRENT_FRACTIONS = (0.3, 1.0, 2.0)
#: Interpolation between grid points is in log-log; this margin keeps it on the safe side.
ENVELOPE_MARGIN = 0.97
#: Widths are never asked above this duty (the driver needs an off time).
_MAX_SEARCH_DUTY = 0.5


def _allowed(spec: WireSpec, f: float, w: float, cur: float) -> tuple[bool, CycleResult]:
    c = steady_cycle(f, w, cur, spec)
    return (c.peak_temperature_c <= spec.max_temperature_c and not c.held_contracted), c


def _edges_for(spec: WireSpec, f: float, cur: float, rel_tol: float = 0.004) -> tuple[float, float]:
    """(largest allowed width, smallest following width) [s] at one frequency and current."""
    period = 1 / f
    w_hi = _MAX_SEARCH_DUTY * period
    ok, c = _allowed(spec, f, w_hi, cur)
    if ok:
        w_max = w_hi
    else:
        # Energy balance guess: the mean power that holds the wire at A_f.
        R = spec.resistance_martensite_ohm
        p_peak = cur * cur * R if cur > 0 else 0.0
        guess = spec.conductance_w_k * (spec.austenite_finish_c - spec.ambient_c) / (f * p_peak) if p_peak > 0 else w_hi
        lo = min(guess * 0.5, w_hi * 0.5)
        while lo > 1e-7 and not _allowed(spec, f, lo, cur)[0]:
            lo *= 0.5
        if lo <= 1e-7:
            return 0.0, math.nan
        hi = min(max(guess * 2, lo * 2), w_hi)
        while _allowed(spec, f, hi, cur)[0] and hi < w_hi:
            lo, hi = hi, min(hi * 2, w_hi)
        while hi / lo > 1 + rel_tol:
            mid = math.sqrt(lo * hi)
            if _allowed(spec, f, mid, cur)[0]:
                lo = mid
            else:
                hi = mid
        w_max = lo
    # The onset of following below it (the cold side does not follow).
    c = steady_cycle(f, w_max, cur, spec)
    if not c.follows:
        return w_max, math.nan
    lo, hi = w_max * 0.5, w_max
    while lo > w_max * 1e-3 and steady_cycle(f, lo, cur, spec).follows:
        lo, hi = lo * 0.5, lo
    if lo <= w_max * 1e-3:
        return w_max, lo
    while hi / lo > 1 + 4 * rel_tol:
        mid = math.sqrt(lo * hi)
        if steady_cycle(f, mid, cur, spec).follows:
            hi = mid
        else:
            lo = mid
    return w_max, hi


@dataclass(frozen=True)
class SafetyEnvelope:
    """The largest pulse width [s] a wire tolerates, per pulse frequency and current.

    For each grid point the width is the largest that keeps the settled wire
    vibrating (not held contracted) and its peak temperature at or below
    ``spec.max_temperature_c``; the paper's Fig. 11 constraint.  Widths where the
    wire is too cold to move are allowed (harmless).  ``min_follow_width_s`` is
    the onset of following, so ``[min_follow_width_s, max_width_s]`` is the band
    where every pulse is felt.

    Use :func:`build_envelope` (cached) rather than the constructor.

    Attributes
    ----------
    spec : WireSpec
    frequencies_hz : tuple of float
        Grid frequencies [Hz], increasing.
    currents_a : tuple of float
        Grid currents [A], increasing.
    max_width_s : tuple of tuple of float
        ``max_width_s[i][j]`` for ``frequencies_hz[i]``, ``currents_a[j]`` [s].
    min_follow_width_s : tuple of tuple of float
        Same layout; NaN where no width follows.
    """

    spec: WireSpec
    frequencies_hz: tuple[float, ...]
    currents_a: tuple[float, ...]
    max_width_s: tuple[tuple[float, ...], ...]
    min_follow_width_s: tuple[tuple[float, ...], ...]
    _log_f: tuple[float, ...] = field(init=False, repr=False, compare=False)
    _log_i: tuple[float, ...] = field(init=False, repr=False, compare=False)
    _log_w: tuple[tuple[float, ...], ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_log_f", tuple(math.log(f) for f in self.frequencies_hz))
        object.__setattr__(self, "_log_i", tuple(math.log(i) for i in self.currents_a))
        object.__setattr__(
            self, "_log_w", tuple(tuple(math.log(max(w, 1e-12)) for w in row) for row in self.max_width_s)
        )

    @staticmethod
    def _locate(axis: tuple[float, ...], x: float) -> tuple[int, float]:
        j = bisect.bisect_right(axis, x) - 1
        j = min(max(j, 0), len(axis) - 2)
        u = (x - axis[j]) / (axis[j + 1] - axis[j])
        return j, min(max(u, 0.0), 1.0)

    def max_pulse_width_s(self, frequency_hz: float, current_a: float) -> float:
        """Largest allowed pulse width [s] at a frequency [Hz] and peak current [A].

        Bilinear in log-log between grid points, times :data:`ENVELOPE_MARGIN`.
        Beyond the grid: below the lowest frequency or current the edge value (a
        lower frequency or current allows at least as much); above the highest
        frequency the same duty; above the highest current the same pulse
        energy (width ~ 1 / I^2).
        """
        if frequency_hz <= 0:
            return math.inf
        if current_a <= 0:
            return math.inf
        f_top, i_top = self.frequencies_hz[-1], self.currents_a[-1]
        scale = 1.0
        f, cur = frequency_hz, current_a
        if f > f_top:
            scale *= f_top / f
            f = f_top
        if cur > i_top:
            scale *= (i_top / cur) ** 2
            cur = i_top
        i, u = self._locate(self._log_f, math.log(max(f, self.frequencies_hz[0])))
        j, v = self._locate(self._log_i, math.log(max(cur, self.currents_a[0])))
        lw = self._log_w
        a = lw[i][j] * (1 - v) + lw[i][j + 1] * v
        b = lw[i + 1][j] * (1 - v) + lw[i + 1][j + 1] * v
        w = math.exp(a * (1 - u) + b * u)
        if w < 1e-11:
            return 0.0
        return w * scale * ENVELOPE_MARGIN

    def follow_band_s(self, frequency_hz: float, current_a: float) -> tuple[float, float]:
        """(onset of following, largest allowed) pulse width [s]; onset NaN when none follows.

        Interpolated linearly in log f and log I like :meth:`max_pulse_width_s`
        (without the margin on the onset)."""
        hi = self.max_pulse_width_s(frequency_hz, current_a)
        f = min(max(frequency_hz, self.frequencies_hz[0]), self.frequencies_hz[-1])
        cur = min(max(current_a, self.currents_a[0]), self.currents_a[-1])
        i, u = self._locate(self._log_f, math.log(f))
        j, v = self._locate(self._log_i, math.log(cur))
        m = self.min_follow_width_s
        corners = (m[i][j], m[i][j + 1], m[i + 1][j], m[i + 1][j + 1])
        if any(not math.isfinite(c) or c <= 0 for c in corners):
            return math.nan, hi
        lg = [math.log(c) for c in corners]
        a = lg[0] * (1 - v) + lg[1] * v
        b = lg[2] * (1 - v) + lg[3] * v
        lo = math.exp(a * (1 - u) + b * u)
        if frequency_hz > self.frequencies_hz[-1]:
            # same duty above the grid, as for the largest width
            lo *= f / frequency_hz
        return lo, hi

    def allows(self, drive: Drive, current_a: float | None = None) -> bool:
        """True when the envelope would let ``drive`` through unchanged."""
        if drive.is_off:
            return True
        cur = self.spec.current_a(drive) if current_a is None else current_a
        return drive.pulse_width_s <= self.max_pulse_width_s(drive.pulse_frequency_hz, cur) * (1 + 1e-12)

    def apply(self, drive: Drive) -> Drive:
        """The drive with its width shortened to the envelope (``"envelope"`` added
        to ``clamped`` when that happened).  Current = amplitude * rated current."""
        if drive.is_off:
            return drive
        w_max = self.max_pulse_width_s(drive.pulse_frequency_hz, drive.amplitude * self.spec.rated_current_a)
        if drive.pulse_width_s <= w_max:
            return drive
        clamped = drive.clamped if "envelope" in drive.clamped else drive.clamped + ("envelope",)
        if w_max <= 0:
            return Drive.off(clamped)
        # w_max is finite and positive here (below a valid drive's width).
        return Drive._trusted(drive.pulse_frequency_hz, w_max, drive.amplitude, clamped)

    def to_dict(self) -> dict[str, Any]:
        return {
            "wire": self.spec.to_dict(),
            "frequencies_hz": list(self.frequencies_hz),
            "currents_a": list(self.currents_a),
            "max_width_s": [list(r) for r in self.max_width_s],
            "min_follow_width_s": [[None if not math.isfinite(x) else x for x in r] for r in self.min_follow_width_s],
            "margin": ENVELOPE_MARGIN,
            "model_version": MODEL_VERSION,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], spec: WireSpec) -> "SafetyEnvelope":
        return cls(
            spec=spec,
            frequencies_hz=tuple(float(x) for x in data["frequencies_hz"]),
            currents_a=tuple(float(x) for x in data["currents_a"]),
            max_width_s=tuple(tuple(float(x) for x in r) for r in data["max_width_s"]),
            min_follow_width_s=tuple(
                tuple(math.nan if x is None else float(x) for x in r) for r in data["min_follow_width_s"]
            ),
        )


_ENVELOPES: dict[WireSpec, SafetyEnvelope] = {}
_ENVELOPE_LOCK = threading.Lock()


def _cache_path(spec: WireSpec) -> Path | None:
    try:
        import platformdirs

        return Path(platformdirs.user_cache_dir("tactilize")) / f"envelope-{spec.name}-{spec.key()}.json"
    except Exception:  # no platformdirs or no home: compute every time
        return None


def build_envelope(
    wire: WireSpec | str | None = None,
    *,
    frequencies_hz: Sequence[float] = ENVELOPE_FREQUENCIES_HZ,
    current_fractions: Sequence[float] = ENVELOPE_CURRENT_FRACTIONS,
    use_cache: bool = True,
) -> SafetyEnvelope:
    """The safety envelope of a wire, computed from the model (a few seconds) and cached.

    The cache is in memory and on disk (the user cache directory, keyed by every
    field of the wire and the model version), so it is computed once per wire.

    Parameters
    ----------
    wire : WireSpec or str, optional
        The wire; the paper's 75 um by default.
    frequencies_hz : sequence of float
        Grid frequencies [Hz].
    current_fractions : sequence of float
        Grid currents as fractions of ``wire.rated_current_a``.
    use_cache : bool
        Read and write the caches (only for the default grid).
    """
    spec = WireSpec.resolve(wire)
    default_grid = tuple(frequencies_hz) == ENVELOPE_FREQUENCIES_HZ and tuple(current_fractions) == ENVELOPE_CURRENT_FRACTIONS
    caching = use_cache and default_grid
    with _ENVELOPE_LOCK:
        if caching and spec in _ENVELOPES:
            return _ENVELOPES[spec]
        path = _cache_path(spec) if caching else None
        if path is not None and path.exists():
            try:
                env = SafetyEnvelope.from_dict(json.loads(path.read_text("utf-8")), spec)
                _ENVELOPES[spec] = env
                return env
            except (OSError, ValueError, KeyError, TypeError):
                pass  # a damaged cache is rebuilt
        freqs = tuple(sorted(float(f) for f in frequencies_hz))
        currents = tuple(sorted(float(c) * spec.rated_current_a for c in current_fractions))
        rows_max, rows_min = [], []
        for f in freqs:
            rmax, rmin = [], []
            for cur in currents:
                w_max, w_on = _edges_for(spec, f, cur, rel_tol=0.008)
                rmax.append(w_max)
                rmin.append(w_on)
            rows_max.append(tuple(rmax))
            rows_min.append(tuple(rmin))
        env = SafetyEnvelope(spec, freqs, currents, tuple(rows_max), tuple(rows_min))
        if caching:
            _ENVELOPES[spec] = env
            if path is not None:
                try:
                    path.parent.mkdir(parents=True, exist_ok=True)
                    tmp = path.with_suffix(".tmp")
                    tmp.write_text(json.dumps(env.to_dict()), "utf-8")
                    tmp.replace(path)
                except OSError:
                    pass
        return env
