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

import json
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import TactilizeError, check_output_path
from .analysis import analyze, protocol_labels, tidy_answers
from .store import provenance

__all__ = ["COLUMN_WIDTHS_MM", "OKABE_ITO", "PAPER_FIGURE", "figure_data", "protocol_figure", "make_figures", "caption",
           "significance_pairs", "text_boxes"]

PAPER_FIGURE = {"g-law": "Fig. 10", "h-law": "Fig. 12", "alpha-law": "Fig. 14", "assessment": "Fig. 17"}


def figure_data(df, protocol_name: str) -> dict[str, Any]:
    """What a protocol's figure plots: groups (x), series (bars) and their values.

    Returns ``{"x": [...], "series": [...], "mean": {series: {x: value}},
    "sd": ..., "median": ..., "points": {series: {x: [values]}}}``.  With one
    condition (the assessment) the x axis is the questions; otherwise it is the
    conditions and each question is a series.
    """
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


#: Figure widths [mm] of one and of two journal columns (docs/references.md, section 7
#: (Figures for a journal)).
COLUMN_WIDTHS_MM = {"single": 89.0, "double": 183.0}
#: The Okabe-Ito palette, told apart with every common colour-vision deficiency
#: (docs/references.md, section 7 (Colour-blind-safe palette)); black is kept for the medians.
OKABE_ITO = ("#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9", "#F0E442")
_FONT_PT = 8.0
_MM_PER_IN = 25.4


def _wrap(text: str, chars: int) -> str:
    return "\n".join(textwrap.wrap(str(text), max(8, chars), break_long_words=False)) or str(text)


def _chars(width_in: float, font_pt: float = _FONT_PT) -> int:
    """Characters of ``font_pt`` text that fit in ``width_in`` [in] (an average glyph is ~0.55 em)."""
    return int(width_in * 72.0 / (0.55 * font_pt))


def _overlap(a, b, pad: float = 0.0) -> bool:
    return a.x0 < b.x1 + pad and b.x0 < a.x1 + pad and a.y0 < b.y1 + pad and b.y0 < a.y1 + pad


def text_boxes(fig) -> list[tuple[str, Any]]:
    """Every visible, non-empty text of ``fig`` and its box in display pixels
    (drawn first, so that the layout has run)."""
    from matplotlib.text import Text

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    out = []
    for t in fig.findobj(Text):
        if t.get_visible() and t.get_text().strip() and t.figure is not None:
            out.append((t.get_text(), t.get_window_extent(renderer)))
    return out


def figure_title(title: str, n_participants: int) -> str:
    """The figure's title: the protocol's, with the participants counted; a title that
    ends in a parenthesis takes the count inside it ("(six images, four items; n = 10)"),
    not a second parenthesis after it."""
    if title.endswith(")"):
        return f"{title[:-1]}; n = {n_participants})"
    return f"{title} (n = {n_participants})"


def protocol_figure(df, protocol_name: str, labels: dict[str, str] | None = None, analysis: dict | None = None,
                    width: str = "double"):
    """A matplotlib Figure for one protocol, and the data it plots.

    Conditions (or, for the assessment, items) are labelled from ``labels``
    (the protocol's labels), wrapped under their bars; where they still do not
    fit, the bars carry the ids and the axis title a key (``A: k5 = 0.02 ...``).
    The legend names each question by its whole text.  Brackets with stars mark
    the pairs the Holm-corrected Wilcoxon tests of ``analysis`` find different
    (p < 0.05).  ``width`` is ``"single"`` or ``"double"`` (journal columns,
    :data:`COLUMN_WIDTHS_MM`); the height follows the text it must hold.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    if width not in COLUMN_WIDTHS_MM:
        raise TactilizeError("--figure-width", f"must be one of {', '.join(COLUMN_WIDTHS_MM)}, got {width!r}")
    labels = labels or {}
    data = figure_data(df, protocol_name)
    xs, series = data["x"], data["series"]
    n_part = df[df["protocol"] == protocol_name]["participant"].nunique()
    w_in = COLUMN_WIDTHS_MM[width] / _MM_PER_IN
    line_chars = _chars(w_in * 0.92)
    legend = not data["by_item"] and len(series) > 1
    legend_texts = [_wrap(labels.get(s, s), line_chars - 6) for s in series] if legend else []
    legend_lines = sum(t.count("\n") + 1 for t in legend_texts)
    tick_chars = _chars(w_in * 0.85 / max(1, len(xs)))
    names = [str(labels.get(x, x)) for x in xs]
    wrapped = [_wrap(n, tick_chars) for n in names]
    # More than three lines under a bar, or a word wider than its slot: ids and a key.
    keyed = any(w.count("\n") >= 3 or max(len(part) for part in w.split("\n")) > tick_chars for w in wrapped)
    what = "item" if data["by_item"] else "condition"
    if keyed:
        ticks = [str(x) for x in xs]
        # One entry a line, each wrapped: the key reads as a list.
        xlabel = "\n".join([what] + [_wrap(f"{x}: {n}", line_chars) for x, n in zip(xs, names) if n != str(x)])
    else:
        ticks, xlabel = wrapped, what
    tick_lines = max(t.count("\n") + 1 for t in ticks)
    title = _wrap(figure_title(labels.get("__title__", protocol_name), n_part), _chars(w_in * 0.9, 9.0))
    h_in = (2.4 + 0.14 * (tick_lines + xlabel.count("\n") + title.count("\n")) + 0.15 * legend_lines
            + (0.1 if legend else 0.0))
    with plt.rc_context({"font.size": _FONT_PT, "axes.titlesize": 9.0, "legend.fontsize": _FONT_PT,
                         "xtick.labelsize": _FONT_PT, "ytick.labelsize": _FONT_PT}):
        fig, ax = plt.subplots(figsize=(w_in, h_in), layout="constrained")
        bar_w = 0.8 / max(1, len(series))
        rng = np.random.default_rng(0)  # jitter of the points only; fixed so figures are reproducible
        top = 7.3
        handles: list[Any] = []  # bar containers: legend takes them (its stubs say Artist)
        for j, s in enumerate(series):
            pos = np.arange(len(xs)) + (j - (len(series) - 1) / 2) * bar_w
            means = [data["mean"][s][x] for x in xs]
            sds = [data["sd"][s][x] for x in xs]
            bars = ax.bar(pos, means, bar_w * 0.9, yerr=np.nan_to_num(sds), capsize=3,
                          color=OKABE_ITO[j % len(OKABE_ITO)], alpha=0.85, gid=f"bar:{s}",
                          error_kw={"elinewidth": 1})
            handles.append(bars)
            ax.scatter(pos, [data["median"][s][x] for x in xs], marker="D", s=14, color="k", zorder=3)
            for p, x in zip(pos, xs):
                pts = data["points"][s][x]
                ax.scatter(p + rng.uniform(-bar_w * 0.25, bar_w * 0.25, len(pts)), pts, s=5, color="0.3",
                           alpha=0.6, zorder=2)
            if not data["by_item"]:
                # Brackets from the statistics, never drawn by eye: one per significant pair.
                where = {x: float(p) for p, x in zip(pos, xs)}
                for a, b, p_holm in significance_pairs(analysis, protocol_name, s):
                    if a not in where or b not in where:
                        continue
                    top += 0.5
                    xa, xb = sorted((where[a], where[b]))
                    ax.plot([xa, xa, xb, xb], [top - 0.15, top, top, top - 0.15], color="k", lw=0.8,
                            gid=f"sig:{a}:{b}")
                    ax.text((xa + xb) / 2, top - 0.05, stars(p_holm), ha="center", va="bottom", fontsize=7)
        ax.set_xticks(np.arange(len(xs)))
        ax.set_xticklabels(ticks, linespacing=1.0)
        ax.set_ylim(0, max(7.5, top + 0.6))
        ax.set_yticks(range(1, 8))
        ax.set_ylabel("rating (1..7)")
        ax.set_xlabel(xlabel, linespacing=1.1, multialignment="left" if keyed else "center")
        ax.set_title(title, linespacing=1.1)
        if legend:
            fig.legend(handles, legend_texts, loc="outside lower center", ncols=1, frameon=False,
                       handlelength=1.2, borderaxespad=0.2)
        ax.grid(axis="y", alpha=0.3)
        ax.set_axisbelow(True)
        fig.canvas.draw()  # the layout runs here, inside the fonts' context
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
                 include_simulated: bool = False, dpi: int = 300, width: str = "double") -> dict[str, dict[str, str]]:
    """Write ``<protocol>.png`` (``dpi``), ``.pdf`` and ``.svg`` (vector) and a caption file
    for every protocol with answers, ``width`` one (``"single"``) or two (``"double"``)
    journal columns wide.

    Simulated participants are left out unless ``include_simulated``.  Every
    file carries the provenance (versions, protocol hash, seeds) in its
    metadata, so a figure found later can be traced to the data that made it.

    Raises
    ------
    TactilizeError
        When ``out_dir`` cannot be created or written (a file in the way...).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if hasattr(store_or_df, "answer_rows"):
        df = tidy_answers(store_or_df, protocol_name, include_simulated)
        df = df[~df["excluded"].astype(bool)]
    else:
        df = store_or_df
        if not include_simulated and "simulated" in df:
            df = df[~df["simulated"].astype(bool)]
    analysis = analyze(df, include_simulated=True)  # df is already filtered
    out = check_output_path(out_dir, folder=True)
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise TactilizeError(str(out_dir), f"cannot create the figure directory ({exc.strerror or exc})") from None
    pnames = sorted(df["protocol"].unique())
    all_labels = protocol_labels(store_or_df, pnames)
    written = {}
    for pname in pnames:
        labels = all_labels.get(pname, {})
        fig, _data = protocol_figure(df, pname, labels, analysis, width)
        pdf = df[df["protocol"] == pname]
        prov = provenance(protocol=pname, protocol_sha256=sorted(set(pdf["protocol_sha256"])),
                          seeds=sorted({int(s) for s in pdf["seed"]}), n_answers=int(len(pdf)),
                          simulated_participants="included" if include_simulated else "excluded")
        files = {ext: out / f"{pname}.{ext}" for ext in ("png", "pdf", "svg")}
        meta = {"png": {"Software": f"tactilize {prov['tactilize']}", "Description": json.dumps(prov)},
                "pdf": {"Creator": f"tactilize {prov['tactilize']}", "Subject": json.dumps(prov)},
                "svg": {"Creator": f"tactilize {prov['tactilize']}", "Description": json.dumps(prov)}}
        try:
            # Text stays text in the vector files (editable, searchable; TrueType in the PDF).
            with plt.rc_context({"svg.fonttype": "none", "pdf.fonttype": 42}):
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
