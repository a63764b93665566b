"""Simulations of the wire: sampled currents, steady pulse drives, settled cycles.

Every function here builds a :class:`~tactilize.actuators.sma.model.WireModel`,
runs it, and reports what the finger would get: the pin's displacement and
whether each pulse moves it (its own peak of at least :data:`FOLLOW_THRESHOLD_M`).

Units: SI inside, temperatures in degrees Celsius.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import WireError, check_finite
from ...drive import Drive
from .circuit import Circuit
from .model import WireModel
from .wire import WireSpec

__all__ = [
    "SimulationResult",
    "CycleResult",
    "simulate",
    "simulate_drive",
    "steady_cycle",
    "DEFAULT_DT_S",
    "FOLLOW_THRESHOLD_M",
]

#: Sampling step [s] of :func:`simulate_drive` and the CLI.
DEFAULT_DT_S = 5e-6
#: A pulse "is followed" when it produces its own displacement peak at least this
#: high [m]: above the displacement at its start and at the next pulse's start.
#: 0.5 um: the vibrotactile detection threshold of the fingertip in the
#: Pacinian range is a fraction of a micrometre (docs/references.md, section 3
#: (detection threshold)), and the paper's pin amplifies the wire's own motion.
FOLLOW_THRESHOLD_M = 0.5e-6


@dataclass(frozen=True)
class SimulationResult:
    """Traces of one simulation, sampled on a uniform grid.

    Attributes
    ----------
    time_s : ndarray, shape (N + 1,)
        Sample instants [s], ``0 .. N dt``.
    current_a : ndarray, shape (N,)
        The mean current [A] through the wire from ``time_s[i]`` to ``time_s[i + 1]``.
    temperature_c, martensite_fraction, displacement_m : ndarray, shape (N + 1,)
        Wire temperature [deg C], martensite fraction, pin displacement [m].
    pulse_starts_s : ndarray
        Onset of every pulse [s].
    electrical_j, stored_j, convected_j, latent_j : float
        Energy accounts over the run [J]: electrical in = stored + convected + latent.
    spec : WireSpec
        The wire simulated.
    pulse_edges_m : ndarray, shape (P, 3), optional
        Per complete pulse period, the displacement [m] at its start, at the
        pulse's end and at the next start, taken from the integrator.
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
    pulse_edges_m: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def of_run(cls, model: WireModel, time_s: np.ndarray, current_a: np.ndarray, temperature_c: np.ndarray,
               martensite_fraction: np.ndarray, pulse_starts_s: np.ndarray,
               pulse_edges_m: np.ndarray | None = None) -> "SimulationResult":
        """The traces of a run of ``model`` (its wire, displacement and energy accounts)."""
        spec = model.spec
        return cls(time_s, current_a, temperature_c, martensite_fraction, spec.displacement_m(martensite_fraction),
                   pulse_starts_s, model.electrical_j, model.stored_j, model.convected_j, model.latent_j, spec,
                   pulse_edges_m)

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
            ``displacement_pp_um`` (median per-pulse swing in the window),
            ``follows`` (every pulse in the window has its own displacement peak
            of at least :data:`FOLLOW_THRESHOLD_M`), ``pulses_followed`` /
            ``pulses_in_window``, ``mean_temperature_c``, ``peak_temperature_c``,
            ``min_temperature_c``, ``mean_martensite_fraction``, and the energy
            accounts in joules.
        """
        t = self.time_s
        start = t[-1] * 2 / 3 if settle_s is None else float(settle_s)
        i0 = min(int(np.searchsorted(t, start)), len(t) - 2)
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

    def _edges_from(self, from_s: float) -> np.ndarray:
        if self.pulse_edges_m is not None:
            keep = self.pulse_starts_s[: len(self.pulse_edges_m)] >= from_s - 1e-12
            return self.pulse_edges_m[keep]
        # From the sampled trace: start, the period's peak, next start.
        starts = self.pulse_starts_s
        idx = np.searchsorted(self.time_s, starts - 1e-12)
        idx = idx[starts >= from_s - 1e-12]
        if idx.size < 2:
            return np.zeros((0, 3))
        d = self.displacement_m
        peaks = np.maximum.reduceat(d[idx[0] : idx[-1] + 1], idx[:-1] - idx[0])
        return np.stack([d[idx[:-1]], peaks, d[idx[1:]]], axis=1)

    def per_pulse_swing_m(self, from_s: float = 0.0) -> np.ndarray:
        """Peak-to-peak displacement [m] of each complete pulse period from ``from_s``."""
        e = self._edges_from(from_s)
        return e.max(axis=1) - e.min(axis=1) if len(e) else np.zeros(0)

    def per_pulse_rise_m(self, from_s: float = 0.0) -> np.ndarray:
        """For each complete pulse period from ``from_s``: how far its displacement
        peak stands above both its start and the next pulse's start [m]."""
        e = self._edges_from(from_s)
        return np.minimum(e[:, 1] - e[:, 0], e[:, 1] - e[:, 2]) if len(e) else np.zeros(0)


def _check_dt(dt_s: float) -> float:
    return check_finite(dt_s, "<dt>", what="time step", error=WireError, above=0.0, unit="s")


def _sample(model: WireModel, rec: list[float], n: int, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    nodes = np.asarray(rec).reshape(-1, 3)
    t = np.arange(n + 1) * dt
    # Node times are sums of float steps: clamp the last one to the grid end.
    nodes[-1, 0] = t[-1]
    return t, np.interp(t, nodes[:, 0], nodes[:, 1]), np.interp(t, nodes[:, 0], nodes[:, 2])


def simulate(
    current_a: Any,
    dt_s: float,
    wire: WireSpec | str | None = None,
    *,
    initial_temperature_c: float | None = None,
    initial_martensite_fraction: float | None = None,
    max_step_k: float = 0.2,
) -> SimulationResult:
    """Simulate the wire under a sampled current from an ideal current source.

    Parameters
    ----------
    current_a : array_like, shape (N,)
        Current [A] through the wire, held for ``dt_s`` per sample.  An ideal
        source: this current flows whatever the wire's resistance.  For a real
        circuit use :func:`simulate_drive` with a :class:`Circuit`.
    dt_s : float
        Sample step [s]; edges are exact at this resolution.
    wire : WireSpec or str, optional
        The wire, or a preset name; the paper's 75 um by default.
    initial_temperature_c, initial_martensite_fraction : float, optional
        Initial state; ambient and relaxed by default.
    max_step_k : float
        Largest temperature step [K] inside the transformation band.
    """
    spec = WireSpec.resolve(wire)
    dt = _check_dt(dt_s)
    try:
        cur = np.abs(np.asarray(current_a, dtype=float).ravel())
    except (TypeError, ValueError):
        raise WireError("<current>", "current must be an array of numbers") from None
    if cur.size == 0:
        raise WireError("<current>", "current is empty")
    if not np.all(np.isfinite(cur)):
        raise WireError("<current>", "current has NaN or infinite samples")
    n = cur.size
    top = float(cur.max())
    circuit = Circuit.ideal_current(top if top > 0 else 1.0)
    # Run-length encode: one segment per constant stretch of current; the heat
    # of I on an ideal source of I_max is (I / I_max)^2 of the full level.
    change = np.flatnonzero(np.diff(cur)) + 1
    bounds = np.concatenate(([0], change, [n]))
    levels = cur[bounds[:-1]]
    model = WireModel(spec, circuit, initial_temperature_c, initial_martensite_fraction,
                      max_step_k=max_step_k, max_step_s=max(dt, 5e-3))
    rec: list[float] = []
    model.run((np.diff(bounds) * dt).tolist(), ((levels / (top or 1.0)) ** 2).tolist(), record=rec)
    t, T, xi = _sample(model, rec, n, dt)
    nonzero = levels != 0
    onset = nonzero & np.concatenate(([True], ~nonzero[:-1]))
    return SimulationResult.of_run(model, t, cur, T, xi, bounds[:-1][onset] * dt)


def _drive_circuit(spec: WireSpec, circuit: Circuit | str | None, current_a: float | None) -> Circuit:
    if current_a is not None:
        if circuit is not None:
            raise WireError("<current>", "give a circuit or a current, not both")
        return Circuit.ideal_current(current_a)
    return Circuit.resolve(circuit, spec)


def simulate_drive(
    drive: Drive,
    duration_s: float,
    wire: WireSpec | str | None = None,
    *,
    circuit: Circuit | str | None = None,
    current_a: float | None = None,
    bias_level: float = 0.0,
    dt_s: float = DEFAULT_DT_S,
    initial_temperature_c: float | None = None,
    initial_martensite_fraction: float | None = None,
) -> SimulationResult:
    """Simulate a steady pulse drive with exact pulse edges, open loop (no controller, no envelope).

    Parameters
    ----------
    drive : Drive
        Frequency [Hz], width [s] and ``amplitude``: the fraction of each pulse
        the switch conducts (chopped), simulated exactly as given.
    duration_s : float
        Length of the run [s].
    wire : WireSpec or str, optional
        The wire; the paper's 75 um by default.
    circuit : Circuit or str, optional
        The driver; ``aa-resistor`` by default.
    current_a : float, optional
        Instead of a circuit: an ideal current source of this current [A].
    bias_level : float
        Switch level between pulses (a chopped standby bias), in [0, 1].
    dt_s : float
        Step [s] of the returned traces (the integration itself is adaptive).
    """
    spec = WireSpec.resolve(wire)
    if not isinstance(drive, Drive):
        raise WireError("<drive>", f"expected a Drive, got {type(drive).__name__}")
    check_finite(duration_s, "<duration>", what="duration", error=WireError, above=0.0, unit="s")
    if not drive.is_off and drive.pulse_width_s >= drive.period_s:
        raise WireError("<drive>", f"pulse width {drive.pulse_width_s:g} s does not fit in the period {drive.period_s:g} s")
    if not (0.0 <= bias_level <= 1.0):
        raise WireError("<bias>", f"bias level must be in [0, 1], got {bias_level!r}")
    circ = _drive_circuit(spec, circuit, current_a)
    dt = _check_dt(dt_s)
    n = max(1, int(math.floor(duration_s / dt + 0.5)))
    total = n * dt
    starts: list[float] = []
    if drive.is_off:
        durations, levels = [total], [bias_level]
    else:
        period, width, on = drive.period_s, drive.pulse_width_s, drive.amplitude
        full = int(math.floor(total / period + 1e-12))
        durations = [width, period - width] * full
        levels = [on, bias_level] * full
        starts = [k * period for k in range(full)]
        t_last = full * period
        if t_last < total - 1e-15:
            cut = min(width, total - t_last)
            durations += [cut, max(0.0, total - t_last - cut)]
            levels += [on, bias_level]
            starts.append(t_last)
    model = WireModel(spec, circ, initial_temperature_c, initial_martensite_fraction, max_step_s=max(dt, 5e-3))
    rec: list[float] = []
    edges: list[tuple[float, float]] = []
    model.run(durations, levels, record=rec, edges=edges)
    t, T, xi = _sample(model, rec, n, dt)
    pulse_edges = None
    if starts:
        # xi at each pulse start, pulse end, next start; only complete periods.
        xs = np.concatenate(([model.initial_martensite_fraction], np.asarray(edges)[:, 1]))
        m = (len(xs) - 1) // 2
        offs = np.asarray(durations[1 : 2 * m : 2])
        ci = np.flatnonzero(offs >= drive.period_s - drive.pulse_width_s - 1e-12)
        if ci.size:
            pulse_edges = spec.displacement_m(np.stack([xs[2 * ci], xs[2 * ci + 1], xs[2 * ci + 2]], axis=1))
    # The mean current on the sample grid: the switch level times the circuit's current.
    on_grid = np.zeros(n)
    if starts:
        st = np.asarray(starts)
        on_idx = np.minimum(np.floor(st / dt + 0.5).astype(np.int64), n)
        off_idx = np.minimum(np.floor((st + drive.pulse_width_s) / dt + 0.5).astype(np.int64), n)
        steps = np.bincount(on_idx, minlength=n + 1)[: n + 1] - np.bincount(off_idx, minlength=n + 1)[: n + 1]
        on_grid = np.cumsum(steps[:n]).astype(float)
    level_grid = np.where(on_grid > 0, drive.amplitude, bias_level)
    current = level_grid * circ.currents_at(spec.resistance_at(xi[:-1]))
    return SimulationResult.of_run(
        model, t, current, T, xi,
        np.asarray(starts[: (len(pulse_edges) if pulse_edges is not None else len(starts))]), pulse_edges)


@dataclass(frozen=True)
class CycleResult:
    """The settled (periodic) response of the wire to a steady, open-loop pulse drive.

    Attributes
    ----------
    frequency_hz, pulse_width_s : float
        The drive [Hz, s].
    current_a : float
        Pulse current into the relaxed wire [A].
    min_temperature_c, peak_temperature_c, mean_temperature_c : float
        Over the settled period [deg C].
    martensite_start, martensite_end : float
        Fraction at pulse onset and pulse end.
    displacement_pp_m : float
        Displacement swing of one settled period [m].
    follows : bool
        The pulse produces its own displacement peak >= :data:`FOLLOW_THRESHOLD_M`.
    held_contracted : bool
        Does not follow and is mostly austenite: the wire stays contracted.
    settled : bool
        The mean temperature of the last half second moved less than 0.01 K and
        the martensite fraction less than 0.002, after three time constants.
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
    current_a: float | None = None,
    wire: WireSpec | str | None = None,
    *,
    circuit: Circuit | str | None = None,
    bias_level: float = 0.0,
    max_duration_s: float = 30.0,
) -> CycleResult:
    """Run a steady open-loop pulse drive until the wire settles and describe one period.

    The run starts from the temperature the mean power would hold with the wire
    relaxed (an energy balance), so it needs a few time constants, not many.

    Parameters
    ----------
    frequency_hz, pulse_width_s : float
        The drive [Hz, s].
    current_a : float, optional
        An ideal current source of this current [A]; else ``circuit``.
    wire : WireSpec or str, optional
        The wire; the paper's 75 um by default.
    circuit : Circuit or str, optional
        The driver (``aa-resistor`` by default).
    bias_level : float
        Switch level between pulses, in [0, 1].
    """
    spec = WireSpec.resolve(wire)
    circ = _drive_circuit(spec, circuit, current_a)
    f, w = float(frequency_hz), float(pulse_width_s)
    if not (f > 0 and 0 < w < 1 / f):
        raise WireError("<drive>", f"need frequency > 0 and 0 < width < period (got {f}, {w})")
    period = 1 / f
    duty = w * f
    hA = spec.conductance_w_k
    p_relaxed = circ.power_at(spec.resistance_martensite_ohm)
    T0 = spec.ambient_c + (duty + bias_level * (1 - duty)) * p_relaxed / hA
    T0 = min(T0, spec.austenite_start_c - 0.5) if T0 > spec.martensite_finish_c else T0
    model = WireModel(spec, circ, temperature_c=T0, martensite_fraction=1.0)
    per_block = max(1, int(round(0.5 * f)))
    block = [w, period - w] * per_block
    levels = [1.0, bias_level] * per_block
    prev_mean: float | None = None
    prev_xi = 0.0
    settled = False
    mean = T0
    edges: list[tuple[float, float]] = []
    while model.time_s < max_duration_s:
        e0, t0 = model.convected_j, model.time_s
        edges = []
        model.run(block, levels, edges=edges)
        mean = spec.ambient_c + (model.convected_j - e0) / (hA * (model.time_s - t0))
        xi_now = model.martensite_fraction
        # The martensite fraction creeps for seconds after the temperature has
        # settled (latent heat), hence the second test.
        if (
            prev_mean is not None
            and abs(mean - prev_mean) < 0.01
            and abs(xi_now - prev_xi) < 0.002
            and model.time_s >= 3 * spec.time_constant_s
        ):
            settled = True
            break
        prev_mean, prev_xi = mean, xi_now
    T_on, x_on = edges[-3] if len(edges) >= 3 else (T0, 1.0)
    T_pe, x_pe = edges[-2]
    T_nx, x_nx = edges[-1]
    d = spec.displacement_m
    rise = min(d(x_pe) - d(x_on), d(x_pe) - d(x_nx))
    follows = rise >= FOLLOW_THRESHOLD_M
    return CycleResult(
        frequency_hz=f,
        pulse_width_s=w,
        current_a=circ.current_at(spec.resistance_martensite_ohm),
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
