"""Figures like the paper's: Fig. 10 (g), 12 (h), 14 (alpha) and 17 (assessment).

The paper shows each experiment's ratings as bars per condition (per item for
the assessment).  Here each bar is the mean over participants with a one-SD
whisker, as the paper discusses means and standard deviations; a diamond marks
the median and the points are the individual participants (per-participant
means over images and repetitions), because with n = 8 .. 10 ordinal ratings a
reader should see the data, not only their summary.

Matplotlib runs with the Agg backend: no display needed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["PAPER_FIGURE", "figure_data", "protocol_figure", "make_figures"]

PAPER_FIGURE = {"g-law": "Fig. 10", "h-law": "Fig. 12", "alpha-law": "Fig. 14", "assessment": "Fig. 17"}


def figure_data(df, protocol_name: str) -> dict[str, Any]:
    """What a protocol's figure plots: groups (x), series (bars) and their values.

    Returns ``{"x": [...], "series": [...], "mean": {series: {x: value}},
    "sd": ..., "median": ..., "points": {series: {x: [values]}}}``.  With one
    condition (the assessment) the x axis is the questions; otherwise it is the
    conditions and each question is a series.
    """
    import numpy as np

    pdf = df[df["protocol"] == protocol_name]
    cell = pdf.groupby(["question", "condition", "participant"], as_index=False, sort=False)["rating"].mean()
    questions = list(dict.fromkeys(pdf["question"]))
    conditions = sorted(pdf["condition"].unique())
    by_item = len(conditions) == 1
    out: dict[str, Any] = {"by_item": by_item, "mean": {}, "sd": {}, "median": {}, "points": {}}
    if by_item:
        out["x"], out["series"] = questions, conditions
    else:
        out["x"], out["series"] = conditions, questions
    for s in out["series"]:
        for key in ("mean", "sd", "median", "points"):
            out[key][s] = {}
        for x in out["x"]:
            q, c = (x, s) if by_item else (s, x)
            v = cell[(cell["question"] == q) & (cell["condition"] == c)]["rating"].to_numpy(float)
            out["points"][s][x] = v.tolist()
            out["mean"][s][x] = float(v.mean()) if v.size else float("nan")
            out["sd"][s][x] = float(v.std(ddof=1)) if v.size > 1 else float("nan")
            out["median"][s][x] = float(np.median(v)) if v.size else float("nan")
    return out


def protocol_figure(df, protocol_name: str, labels: dict[str, str] | None = None):
    """A matplotlib Figure for one protocol, and the data it plots."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import numpy as np

    data = figure_data(df, protocol_name)
    xs, series = data["x"], data["series"]
    n_part = df[df["protocol"] == protocol_name]["participant"].nunique()
    fig, ax = plt.subplots(figsize=(min(10.0, max(4.5, 1.5 + 0.45 * len(xs) * max(1, len(series)))), 3.6), dpi=120)
    width = 0.8 / max(1, len(series))
    rng = np.random.default_rng(0)  # jitter of the points only; fixed so figures are reproducible
    for j, s in enumerate(series):
        pos = np.arange(len(xs)) + (j - (len(series) - 1) / 2) * width
        means = [data["mean"][s][x] for x in xs]
        sds = [data["sd"][s][x] for x in xs]
        label = None if data["by_item"] else s
        ax.bar(pos, means, width * 0.9, yerr=np.nan_to_num(sds), capsize=3, label=label, alpha=0.8,
               gid=f"bar:{s}", error_kw={"elinewidth": 1})
        ax.scatter(pos, [data["median"][s][x] for x in xs], marker="D", s=18, color="k", zorder=3)
        for p, x in zip(pos, xs):
            pts = data["points"][s][x]
            ax.scatter(p + rng.uniform(-width * 0.25, width * 0.25, len(pts)), pts, s=6, color="0.3", alpha=0.6,
                       zorder=2)
    ax.set_xticks(np.arange(len(xs)))
    ax.set_xticklabels([(labels or {}).get(x, x) for x in xs])
    ax.set_ylim(0, 7.5)
    ax.set_yticks(range(1, 8))
    ax.set_ylabel("rating (1..7)")
    ax.set_xlabel("item" if data["by_item"] else "condition")
    fig_no = PAPER_FIGURE.get(protocol_name)
    ax.set_title(f"{protocol_name}{' (cf. paper ' + fig_no + ')' if fig_no else ''}: mean ± SD, ◆ median, n = {n_part}",
                 fontsize=9)
    if not data["by_item"] and len(series) > 1:
        ax.legend(fontsize=8, frameon=False, ncols=min(4, len(series)))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig, data


def make_figures(store_or_df, out_dir: str | Path, protocol_name: str | None = None) -> dict[str, dict[str, str]]:
    """Write ``<protocol>.png`` and ``.svg`` for every protocol with answers.

    The PNG carries the provenance (versions, protocol hash, seeds) in its
    text chunks and the SVG in its metadata, so a figure found later can be
    traced to the data that made it.
    """
    import json

    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from .analysis import tidy_answers
    from .store import provenance

    df = tidy_answers(store_or_df, protocol_name) if hasattr(store_or_df, "answer_rows") else store_or_df
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = {}
    for pname in sorted(df["protocol"].unique()):
        fig, _data = protocol_figure(df, pname)
        pdf = df[df["protocol"] == pname]
        prov = provenance(protocol=pname, protocol_sha256=sorted(set(pdf["protocol_sha256"])),
                          seeds=sorted({int(s) for s in pdf["seed"]}), n_answers=int(len(pdf)))
        png, svg = out / f"{pname}.png", out / f"{pname}.svg"
        fig.savefig(png, metadata={"Software": f"tactilize {prov['tactilize']}",
                                   "Description": json.dumps(prov)})
        fig.savefig(svg, metadata={"Creator": f"tactilize {prov['tactilize']}", "Description": json.dumps(prov)})
        plt.close(fig)
        written[pname] = {"png": str(png), "svg": str(svg)}
    return written
