"""What a hardware limit lets through at its worst, judged on the wire model.

:mod:`tactilize.actuators.sma.limiter` has the parts (an AC-coupled gate, a
thermal replica) and the limit chosen per circuit preset; here are the two
worst cases a logic with no software behind it can make, and their judge:
:func:`stuck_high_peak_c` (the logic held high for good) and
:func:`runaway_sweep` / :func:`worst_runaway` (a runaway loop toggling it at
any period and duty), each run through the limit into the host's wire model,
latent heat included (:func:`peak_c`).  docs/hardware.md ("Defence in depth")
is their table.

Units: SI (seconds, volts); temperatures in degrees Celsius.

References
----------
.. [1] docs/references.md, section 8 (thermal replica, ac-coupled gate).
"""

from __future__ import annotations

import math
from typing import Sequence

from .circuit import Circuit
from .limiter import HardwareLimit, Schedule, append_segment
from .model import WireModel
from .wire import WireSpec

__all__ = ["peak_c", "stuck_high_peak_c", "runaway_duties", "runaway_sweep", "worst_runaway", "judge_limit"]


def _air_spec(spec: WireSpec, air_c: float) -> WireSpec:
    return spec if spec.ambient_c == air_c else spec.replace(ambient_c=float(air_c))


def peak_c(
    spec: WireSpec,
    circuit: Circuit,
    schedule: Schedule,
    air_c: float,
    *,
    start_c: float | None = None,
) -> float:
    """The hottest the wire model gets [deg C] under a switch schedule in air at ``air_c``.

    Runs :class:`WireModel` (latent heat and minor loops included) from
    ``start_c`` (the air by default).  Inside one segment of constant level the
    temperature is monotone (:mod:`.model`), so the peak is at a segment's end.
    """
    model = WireModel(_air_spec(spec, air_c), circuit, temperature_c=start_c)
    edges: list = []
    model.run(schedule[0], schedule[1], edges=edges)
    return max([model.initial_temperature_c] + [t for t, _ in edges])


def stuck_high_peak_c(
    limit: HardwareLimit | None,
    spec: WireSpec,
    circuit: Circuit,
    air_c: float,
    *,
    duration_s: float = 4.0,
) -> float:
    """Peak [deg C] with the logic stuck high for ``duration_s`` from a wire at rest
    in the air (``limit=None``: no limit, the plain circuit)."""
    logic = ([duration_s], [1.0])
    sched = logic if limit is None else limit.schedule(*logic)
    return peak_c(spec, circuit, sched, air_c)


def _toggle(period_s: float, duty: float, duration_s: float) -> Schedule:
    n = max(1, int(math.ceil(duration_s / period_s)))
    return [period_s * duty, period_s * (1.0 - duty)] * n, [1.0, 0.0] * n


def runaway_duties(limit: HardwareLimit | None) -> list[float]:
    """Duties [0, 1] a runaway sweep tries for a limit: a coarse grid, and just
    under and over the places where the limit changes what it lets through (the
    replica's trip points, the AC-coupled gate's largest toggled duty)."""
    duties = {0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.65, 0.8, 0.9}
    if limit is not None and limit.replica is not None:
        for edge in (limit.replica.lower_fraction, limit.replica.upper_fraction):
            duties.update(edge * f for f in (0.97, 0.99, 0.998, 1.002, 1.01))
    if limit is not None and limit.ac_gate is not None:
        edge = limit.ac_gate.max_toggle_duty()
        duties.update(edge * f for f in (0.9, 0.97, 0.99, 1.01))
    return sorted(d for d in duties if 0.0 < d < 1.0)


#: The toggle periods :func:`worst_runaway` tries by default [s]: from the bias's
#: 20 kHz chopping to slower than the AC-coupled gate's R C and near the wire's
#: time constant.
RUNAWAY_PERIODS_S = (50e-6, 1e-3, 5e-3, 20e-3, 0.1, 0.4)


def runaway_sweep(
    limit: HardwareLimit | None,
    spec: WireSpec,
    circuit: Circuit,
    air_c: float,
    periods_s: Sequence[float] = RUNAWAY_PERIODS_S,
    duties: Sequence[float] | None = None,
    *,
    duration_s: float = 4.0,
    then_stuck_s: float = 0.5,
) -> list[tuple[float, float, float]]:
    """Peaks of a runaway toggling the logic, over toggle periods and duties.

    Each pattern toggles the logic (high for ``duty * period``, then low) for
    ``duration_s``, over seven of the wire's time constants, so it reaches its
    periodic state, then holds it high for ``then_stuck_s``: a crash after a
    runaway.  A period under a millisecond is run as the wire model's chopped
    level (``WireModel.run``: the wire sees the mean heat), once the limit has
    turned it into a conduction schedule.

    Returns
    -------
    list of (float, float, float)
        ``(period [s], duty, peak [deg C])`` per pattern.
    """
    out = []
    for period in periods_s:
        for duty in runaway_duties(limit) if duties is None else duties:
            d, lv = _toggle(period, duty, duration_s)
            d.append(then_stuck_s)
            lv.append(1.0)
            sched = (d, lv) if limit is None else limit.schedule(d, lv)
            if period < 1e-3:
                sched = _chopped(sched, 1e-3)
            out.append((float(period), float(duty), peak_c(spec, circuit, sched, air_c)))
    return out


def _chopped(schedule: Schedule, window_s: float) -> Schedule:
    """A schedule averaged over windows of ``window_s`` [s] (levels become the
    conducting fraction), for toggling far faster than the wire can follow."""
    out: Schedule = ([], [])
    acc_s = on_s = 0.0
    for dur, lev in zip(*schedule):
        rem = dur
        while rem > 0:
            step = min(rem, window_s - acc_s)
            acc_s += step
            on_s += step * lev
            rem -= step
            if acc_s >= window_s * (1 - 1e-12):
                append_segment(out, acc_s, on_s / acc_s)
                acc_s = on_s = 0.0
    if acc_s > 0:
        append_segment(out, acc_s, on_s / acc_s)
    return out


def worst_runaway(
    limit: HardwareLimit | None,
    spec: WireSpec,
    circuit: Circuit,
    air_c: float,
    periods_s: Sequence[float] = RUNAWAY_PERIODS_S,
    duties: Sequence[float] | None = None,
    **kwargs: float,
) -> tuple[float, float, float]:
    """The hottest pattern of :func:`runaway_sweep`: ``(period [s], duty, peak [deg C])``."""
    return max(runaway_sweep(limit, spec, circuit, air_c, periods_s, duties, **kwargs), key=lambda r: r[2])


def judge_limit(
    limit: HardwareLimit | None,
    spec: WireSpec | str | None,
    circuit: Circuit | str | None,
    air_c: float,
) -> dict[str, float]:
    """Both worst cases of a limit, at its parts' most permissive corner, in air at ``air_c``.

    Returns
    -------
    dict
        ``stuck_high_c``: the peak [deg C] with the logic stuck high from a wire
        at rest; ``runaway_c``, ``runaway_period_s``, ``runaway_duty``: the hottest
        pattern of :func:`worst_runaway` (toggling, then stuck high).
        ``limit=None`` judges the plain circuit.
    """
    sp = WireSpec.resolve(spec)
    cir = Circuit.resolve(circuit, sp)
    worst = None if limit is None else limit.worst_corner()
    period, duty, runaway = worst_runaway(worst, sp, cir, air_c)
    return {
        "stuck_high_c": stuck_high_peak_c(worst, sp, cir, air_c),
        "runaway_c": runaway,
        "runaway_period_s": period,
        "runaway_duty": duty,
    }
