"""Figures like the paper's: Fig. 10 (g), 12 (h), 14 (alpha) and 17 (assessment).

The paper shows each experiment's ratings as bars per condition (per item for
the assessment).  Here each bar is the mean over participants with a one-SD
whisker, as the paper discusses means and standard deviations; a diamond marks
the median and the points are the individual participants (per-participant
means over images and repetitions), because with n = 8 .. 10 ordinal ratings a
reader should see the data, not only their summary.

Labels come from the protocol, significance brackets from the Holm-corrected
Wilcoxon tests of :func:`.analysis.analyze`; the paper's figure number goes in
the caption (``<protocol>.caption.txt``), not the title.  PNG at 300 dpi, PDF and
SVG as vectors.  Matplotlib runs with the Agg backend: no display needed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["PAPER_FIGURE", "figure_data", "protocol_figure", "make_figures", "caption", "significance_pairs"]

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


def _labels(store_or_df, pnames) -> dict[str, dict[str, str]]:
    """``{protocol: {condition or question id: label}}`` from the stored protocol texts
    (the newest version wins); empty when only a DataFrame is given."""
    out: dict[str, dict[str, str]] = {}
    if not hasattr(store_or_df, "protocol_texts"):
        return out
    from .protocols import ProtocolError, protocol_from_toml

    for pv in store_or_df.protocol_texts():
        if pv["name"] not in pnames:
            continue
        try:
            proto = protocol_from_toml(pv["text"], source=f"stored {pv['name']}")
        except ProtocolError:  # a stored text today's checks refuse: ids stay as they are
            continue
        labels = {c.id: c.label for c in proto.conditions}
        # Items are named by their text, cut to fit under a bar.
        labels.update({q.id: q.text if len(q.text) <= 32 else q.text[:30].rstrip() + "…" for q in proto.questions})
        out[pv["name"]] = {**labels, "__title__": proto.title}
    return out


def significance_pairs(analysis: dict | None, protocol_name: str, question: str) -> list[tuple[str, str, float]]:
    """``(a, b, p_holm)`` of the pairs whose Holm-corrected Wilcoxon p is below 0.05."""
    if not analysis:
        return []
    q = analysis.get("protocols", {}).get(protocol_name, {}).get("questions", {}).get(question)
    if not q:
        return []
    return [(p["a"], p["b"], p["p_holm"]) for p in q["pairwise"]
            if p.get("p_holm") is not None and p["p_holm"] < 0.05]


def stars(p: float) -> str:
    """The usual marks: * p < .05, ** p < .01, *** p < .001."""
    return "***" if p < 0.001 else "**" if p < 0.01 else "*"


def protocol_figure(df, protocol_name: str, labels: dict[str, str] | None = None, analysis: dict | None = None):
    """A matplotlib Figure for one protocol, and the data it plots.

    Conditions (or, for the assessment, items) are labelled from ``labels``
    (the protocol's labels); brackets with stars mark the pairs the
    Holm-corrected Wilcoxon tests of ``analysis`` find different (p < 0.05).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import numpy as np

    labels = labels or {}
    data = figure_data(df, protocol_name)
    xs, series = data["x"], data["series"]
    n_part = df[df["protocol"] == protocol_name]["participant"].nunique()
    fig, ax = plt.subplots(figsize=(min(10.0, max(4.5, 1.5 + 0.6 * len(xs) * max(1, len(series)))), 3.8))
    width = 0.8 / max(1, len(series))
    rng = np.random.default_rng(0)  # jitter of the points only; fixed so figures are reproducible
    top = 7.3
    for j, s in enumerate(series):
        pos = np.arange(len(xs)) + (j - (len(series) - 1) / 2) * width
        means = [data["mean"][s][x] for x in xs]
        sds = [data["sd"][s][x] for x in xs]
        label = None if data["by_item"] else labels.get(s, s)
        ax.bar(pos, means, width * 0.9, yerr=np.nan_to_num(sds), capsize=3, label=label, alpha=0.8,
               gid=f"bar:{s}", error_kw={"elinewidth": 1})
        ax.scatter(pos, [data["median"][s][x] for x in xs], marker="D", s=18, color="k", zorder=3)
        for p, x in zip(pos, xs):
            pts = data["points"][s][x]
            ax.scatter(p + rng.uniform(-width * 0.25, width * 0.25, len(pts)), pts, s=6, color="0.3", alpha=0.6,
                       zorder=2)
        if not data["by_item"]:
            # Brackets from the statistics, never drawn by eye: one per significant pair.
            where = {x: float(p) for p, x in zip(pos, xs)}
            for a, b, p_holm in significance_pairs(analysis, protocol_name, s):
                if a not in where or b not in where:
                    continue
                top += 0.45
                xa, xb = sorted((where[a], where[b]))
                ax.plot([xa, xa, xb, xb], [top - 0.15, top, top, top - 0.15], color="k", lw=0.8, gid=f"sig:{a}:{b}")
                ax.text((xa + xb) / 2, top, stars(p_holm), ha="center", va="bottom", fontsize=8)
    ax.set_xticks(np.arange(len(xs)))
    ax.set_xticklabels([labels.get(x, x) for x in xs], rotation=30 if len(xs) > 5 else 0,
                       ha="right" if len(xs) > 5 else "center", fontsize=8)
    ax.set_ylim(0, max(7.5, top + 0.6))
    ax.set_yticks(range(1, 8))
    ax.set_ylabel("rating (1..7)")
    ax.set_xlabel("item" if data["by_item"] else "condition")
    ax.set_title(f"{labels.get('__title__', protocol_name)} (n = {n_part})", fontsize=9)
    if not data["by_item"] and len(series) > 1:
        ax.legend(fontsize=8, frameon=False, ncols=min(4, len(series)))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig, data


def caption(protocol_name: str, n_part: int, labels: dict[str, str] | None = None) -> str:
    """The figure's caption, with the paper's figure number it corresponds to
    (docs/references.md, section 7 (experiment practice)) -- in the caption, not the title."""
    fig_no = PAPER_FIGURE.get(protocol_name)
    title = (labels or {}).get("__title__", protocol_name)
    return (f"{title}: mean rating per condition (bars) with one SD (whiskers), median (diamonds) and each "
            f"participant's mean (points), n = {n_part}. Brackets: pairs differing in Wilcoxon signed-rank tests "
            "with Holm's correction (* p < .05, ** p < .01, *** p < .001)."
            + (f" Corresponds to the paper's {fig_no}." if fig_no else ""))


def make_figures(store_or_df, out_dir: str | Path, protocol_name: str | None = None,
                 include_simulated: bool = False, dpi: int = 300) -> dict[str, dict[str, str]]:
    """Write ``<protocol>.png`` (``dpi``), ``.pdf`` and ``.svg`` (vector) and a caption file
    for every protocol with answers.

    Simulated participants are left out unless ``include_simulated``.  Every
    file carries the provenance (versions, protocol hash, seeds) in its
    metadata, so a figure found later can be traced to the data that made it.

    Raises
    ------
    TactilizeError
        When ``out_dir`` cannot be created or written (a file in the way...).
    """
    import json

    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from ..errors import TactilizeError
    from .analysis import analyze, tidy_answers
    from .store import provenance

    if hasattr(store_or_df, "answer_rows"):
        df = tidy_answers(store_or_df, protocol_name, include_simulated)
        df = df[~df["excluded"].astype(bool)]
    else:
        df = store_or_df
        if not include_simulated and "simulated" in df:
            df = df[~df["simulated"].astype(bool)]
    analysis = analyze(df, include_simulated=True)  # df is already filtered
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise TactilizeError(str(out_dir), f"cannot create the figure directory ({exc.strerror or exc})") from None
    pnames = sorted(df["protocol"].unique())
    all_labels = _labels(store_or_df, pnames)
    written = {}
    for pname in pnames:
        labels = all_labels.get(pname, {})
        fig, _data = protocol_figure(df, pname, labels, analysis)
        pdf = df[df["protocol"] == pname]
        prov = provenance(protocol=pname, protocol_sha256=sorted(set(pdf["protocol_sha256"])),
                          seeds=sorted({int(s) for s in pdf["seed"]}), n_answers=int(len(pdf)),
                          simulated_participants="included" if include_simulated else "excluded")
        files = {ext: out / f"{pname}.{ext}" for ext in ("png", "pdf", "svg")}
        meta = {"png": {"Software": f"tactilize {prov['tactilize']}", "Description": json.dumps(prov)},
                "pdf": {"Creator": f"tactilize {prov['tactilize']}", "Subject": json.dumps(prov)},
                "svg": {"Creator": f"tactilize {prov['tactilize']}", "Description": json.dumps(prov)}}
        try:
            for ext, path in files.items():
                fig.savefig(path, dpi=dpi, metadata=meta[ext])
            cap = out / f"{pname}.caption.txt"
            cap.write_text(caption(pname, int(pdf["participant"].nunique()), labels) + "\n", "utf-8")
        except OSError as exc:
            raise TactilizeError(str(out_dir), f"cannot write figures ({exc.strerror or exc})") from None
        finally:
            plt.close(fig)
        written[pname] = {**{k: str(v) for k, v in files.items()}, "caption": str(cap)}
    return written
