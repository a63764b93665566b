"""Benchmark: the SMA wire model, x real time, at the sampling step chosen for 300 Hz pulses.

The step: the integrator walks constant-current segments (exact exponentials
outside the transformation band, Crank-Nicolson steps of at most 0.2 K inside),
so its cost does not depend on a time step; the current's sampling step only
places pulse edges.  ``DEFAULT_DT_S`` = 5 us puts a 50 us pulse (the shortest
the paper's 300 Hz drives use) on 10 samples, 10 % resolution.

Measured, for 300 Hz / 150 us pulses at the rated current (the densest drive):

* ``WireModel.run`` over the pulse segments, no traces;
* ``simulate_drive`` (exact edges, traces sampled at 5 us);
* ``simulate`` of a sampled current at 5 us (run-length encoding + traces);
* ``SimulatedOutput.advance`` of two channels in 20 ms ticks with 2 kHz traces,
  each under its operating-point controller (a piece of current per pulse and
  per gap, the resistance read after each, the loop closed per pulse);

against references measured in the same run: a pure-Python forward-Euler loop at
the same 5 us step (what a naive integrator costs; run for 0.2 s and scaled), and
``np.interp`` of one trace onto the 5 us grid (the floor cost of returning traces).
Goal: >= 100 x real time.  Also prints the cost of ``envelope.apply``
(closed-form since the envelope is in energy: nothing to build or cache).

Run: python bench/bench_sma.py [--seconds S]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

import tactilize as tz
from tactilize.actuators.sma import DEFAULT_DT_S, Circuit, WireModel, WireSpec, build_envelope, simulate, simulate_drive
from tactilize.actuators.simulated import SimulatedOutput


def timed(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def euler_loop(spec: WireSpec, seconds: float, dt: float, f: float, w: float, cur: float) -> float:
    """Forward Euler with the same physics, one Python iteration per step (the reference)."""
    C, hA, Lat, Ta = spec.heat_capacity_j_k, spec.conductance_w_k, spec.latent_j, spec.ambient_c
    RA, RM = spec.resistance_austenite_ohm, spec.resistance_martensite_ohm
    As, Af = spec.austenite_start_c, spec.austenite_finish_c
    aA = math.pi / (Af - As)
    T, xi = 70.0, 0.5
    period = 1 / f
    V2 = (cur * RM) ** 2
    for i in range(int(seconds / dt)):
        on = (i * dt) % period < w
        R = RA + (RM - RA) * xi
        F = (V2 / R if on else 0.0) - hA * (T - Ta)
        s = -0.5 * aA * math.sin(aA * (T - As)) if As < T < Af else 0.0
        T += dt * F / (C - Lat * s)
        xi = 0.5 * (1 + math.cos(aA * (T - As))) if As < T < Af else (1.0 if T <= As else 0.0)
    return T


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    secs = args.seconds
    spec = WireSpec.preset("75um")
    f, w, cur = 300.0, 150e-6, spec.rated_current_a
    dt = DEFAULT_DT_S
    n_periods = int(secs * f)

    def run_model():
        WireModel(spec, Circuit.ideal_current(cur)).run([w, 1 / f - w] * n_periods, [1.0, 0.0] * n_periods)

    drive = tz.Drive(f, w)
    current = tz.pulse_train(drive, secs, 1 / dt) * cur

    t_model = timed(run_model)
    t_drive = timed(lambda: simulate_drive(drive, secs, spec, current_a=cur, dt_s=dt))
    t_sim = timed(lambda: simulate(current, dt, spec))

    env = build_envelope(spec)
    out = SimulatedOutput(spec, envelope=env, start=False)
    out.apply([tz.Drive(f, w, 1.0, (), 0.5)] * 2)

    def advance():
        for _ in range(int(secs / 0.02)):
            out.advance(0.02)

    t_out = timed(advance, repeat=1)
    out.close()

    euler_s = 0.2
    t_euler = timed(lambda: euler_loop(spec, euler_s, dt, f, w, cur), repeat=1) * secs / euler_s
    grid = np.arange(int(secs / dt) + 1) * dt
    xp = np.linspace(0, secs, 4 * n_periods)
    fp = np.sin(xp)
    t_interp = timed(lambda: np.interp(grid, xp, fp))

    print(f"75 um wire, {f:g} Hz, {w * 1e6:g} us pulses at {cur * 1e3:g} mA, {secs:g} s simulated, step {dt * 1e6:g} us")
    print(f"  {'what':44} {'x real time':>12} {'vs Euler':>9}")
    rows = [
        ("reference: pure-Python Euler at the step", t_euler),
        ("reference: np.interp of one trace", t_interp),
        ("WireModel.run (segments, no traces)", t_model),
        ("simulate_drive (exact edges, 5 us traces)", t_drive),
        ("simulate (sampled current, 5 us traces)", t_sim),
        ("SimulatedOutput.advance, 2 channels, 2 kHz", t_out),
    ]
    for name, t in rows:
        print(f"  {name:44} {secs / t:12.0f} {t_euler / t:9.0f}")

    d = tz.Drive(120.0, 0.9e-3)
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        env.apply(d)
    t_apply = (time.perf_counter() - t0) / n
    print(f"  envelope.apply: {t_apply * 1e6:.1f} us")


if __name__ == "__main__":
    main()
