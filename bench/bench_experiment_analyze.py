"""Benchmark of `experiment analyze`: the signed-rank tests, scipy's resampling against the enumeration.

Simulates ``--participants`` synthetic participants (seed ``--seed``) on the
g-law, h-law and alpha-law protocols into a scratch SQLite file, then runs
:func:`tactilize.experiments.analysis.analyze` on it twice in the same process:

- before: every pairwise test through ``pingouin.wilcoxon`` (scipy's
  ``method="auto"``, which for tied or zero differences of up to 13 participants
  runs ``scipy.stats.permutation_test``, calling the statistic once per sign pattern);
- after: :func:`tactilize.experiments.analysis.signed_rank_test` (the same p-value,
  its permutation distribution enumerated at once; docs/experiments.md, "Statistics").

Prints each run's time, the ratio, and how far apart the two runs' W, p, Holm p,
RBC and CLES are (the largest absolute difference of each, over every pair).

Usage::

    python bench/bench_experiment_analyze.py                  # ~1 minute
    python bench/bench_experiment_analyze.py --participants 12

No assertion on wall-clock time: figures and ratios are printed.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

PROTOCOLS = ("g-law", "h-law", "alpha-law")
KEYS = ("W", "p", "p_holm", "rbc", "cles")


def _pingouin_test(x, y) -> dict:
    """The pairwise test as the analysis made it before: pingouin.wilcoxon with its defaults."""
    import pingouin as pg

    r = pg.wilcoxon(x, y).iloc[0]
    return {"W": float(r["W_val"] if "W_val" in r.index else r["W-val"]),
            "p": float(r["p_val"] if "p_val" in r.index else r["p-val"]),
            "rbc": float(r["RBC"]), "cles": float(r["CLES"]), "method": "pingouin"}


def _pairs(result: dict) -> list[dict]:
    return [row for pr in result["protocols"].values() for q in pr["questions"].values() for row in q["pairwise"]]


def _timed(store, test) -> tuple[float, dict]:
    from tactilize.experiments import analysis

    saved = analysis.signed_rank_test
    analysis.signed_rank_test = test
    try:
        t0 = time.perf_counter()
        result = analysis.analyze(store, include_simulated=True)
        return time.perf_counter() - t0, result
    finally:
        analysis.signed_rank_test = saved


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    from tactilize.experiments import analysis
    from tactilize.experiments.simulate import simulate
    from tactilize.experiments.store import Store

    with tempfile.TemporaryDirectory() as tmp:
        db = str(Path(tmp) / "bench.sqlite3")
        for name in PROTOCOLS:
            simulate(name, args.participants, args.seed, db)
        store = Store(db)
        analysis.analyze(store, include_simulated=True)  # imports and the first query, outside both timings
        t_old, old = _timed(store, _pingouin_test)
        t_new, new = _timed(store, analysis.signed_rank_test)
    a, b = _pairs(old), _pairs(new)
    methods: dict[str, int] = {}
    for row in b:
        methods[row.get("method", "-")] = methods.get(row.get("method", "-"), 0) + 1
    print(f"{len(PROTOCOLS)} protocols, {args.participants} simulated participants each, {len(b)} pairwise tests "
          f"({', '.join(f'{n} {m}' for m, n in sorted(methods.items()))})")
    print(f"  before (pingouin.wilcoxon, scipy method='auto'): {t_old:8.2f} s")
    print(f"  after  (signed_rank_test):                        {t_new:8.2f} s   ratio {t_old / t_new:6.1f}x")
    for key in KEYS:
        diffs = [abs(x[key] - y[key]) for x, y in zip(a, b)
                 if x.get(key) is not None and y.get(key) is not None and not math.isnan(x[key])]
        print(f"  largest |before - after| of {key:7s} {max(diffs, default=0.0):.3g}  ({len(diffs)} pairs)")
    same = sum(x["significant_0_05"] == y["significant_0_05"] for x, y in zip(a, b))
    print(f"  same Holm decision at 0.05: {same} of {len(a)}; p median {np.median([r['p'] for r in b if r['p'] is not None]):.3g}")


if __name__ == "__main__":
    main()
