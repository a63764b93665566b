"""Analysis of 1..7 ratings from within-subject experiments [1]_.

For each protocol and question:

- descriptives per condition: n, median, quartiles and IQR, mean and SD;
- Friedman's test in its F variant (Iman-Davenport style: better calibrated than
  the chi-square approximation at n = 8 .. 10) with Kendall's W, and the
  classic chi-square version beside it;
- pairwise Wilcoxon signed-rank tests with Holm's correction, each with the
  rank-biserial correlation and the common-language effect size.

The tests come from pingouin and scipy, except the signed-rank test's p-value for
tied or zero differences, whose exact permutation distribution is enumerated here
(:func:`signed_rank_test`: the same p-values as scipy's resampling, at once).  Ratings are first averaged per participant and condition (over
images and repetitions), because the tests assume one value per cell;
participants who did not rate every condition are left out of the tests (not of
the descriptives) and the count of those used is reported.

References
----------
.. [1] docs/references.md, section 7 (statistics for ratings).
"""

from __future__ import annotations

import io
import json
import math
from itertools import combinations
from typing import Any

import numpy as np

from .. import __version__
from ..errors import TactilizeError
from ..redact import redact_url
from .demographics import all_answers
from .design_toml import design_from_toml
from .errors import DesignError
from .labdata import excluded_codes, trial_events
from .store import provenance

__all__ = ["tidy_answers", "analyze", "describe", "friedman", "pairwise_wilcoxon", "signed_rank_test", "export_answers",
           "export_strokes", "CSV_COLUMNS", "WILCOXON_METHOD"]

CSV_COLUMNS = [
    "protocol", "protocol_version", "protocol_sha256", "seed", "participant", "participant_number", "simulated",
    "excluded", "session", "trial", "repetition", "condition", "image", "question", "rating", "trial_started_at",
    "answered_at", "response_time_s", "stroke_interrupted", "comment", "tactilize_version",
]


def tidy_answers(store, protocol_name: str | None = None, include_simulated: bool = True,
                 include_practice: bool = False):
    """One row per answer as a pandas DataFrame (columns :data:`CSV_COLUMNS`).

    ``include_simulated=False`` leaves out synthetic participants (the analysis
    and the figures do so unless asked otherwise).  Practice trials (repetition
    -1) are left out unless ``include_practice`` (the exports keep them)."""
    import pandas as pd

    rows = [r for r in store.answer_rows(protocol_name) if (include_simulated or not r["simulated"])
            and (include_practice or r["repetition"] >= 0)]
    df = pd.DataFrame(rows, columns=[c for c in CSV_COLUMNS[:-3] if c != "excluded"])
    gaps, comments, excluded = set(), {}, {}
    if hasattr(store, "Session"):
        excluded = excluded_codes(store)

        for e in trial_events(store):
            if e["kind"] == "interrupted":
                gaps.add((e["session"], e["trial"]))
            elif e["kind"] == "comment":
                comments[(e["session"], e["trial"])] = e["detail"].get("text", "")
    who = list(zip(df["protocol"], df["participant"]))
    df["excluded"] = [k in excluded for k in who]
    # An excluded participant's row of the square went to the next person; report the one they had.
    df["participant_number"] = [excluded.get(k, n) for k, n in zip(who, df["participant_number"])]
    keys = list(zip(df["session"], df["trial"]))
    df["stroke_interrupted"] = [k in gaps for k in keys]
    df["comment"] = [comments.get(k, "") for k in keys]
    df["tactilize_version"] = __version__
    return df[CSV_COLUMNS]


def export_answers(store, fmt: str = "csv", protocol_name: str | None = None) -> str:
    """The answers as CSV (tidy, one row per answer) or JSON (with provenance and sessions)."""
    df = tidy_answers(store, protocol_name, include_practice=True)
    if fmt == "csv":
        buf = io.StringIO()
        df.to_csv(buf, index=False, lineterminator="\n")
        return buf.getvalue()
    if fmt == "json":
        doc = {
            "provenance": provenance(db=_redact(store.url), protocol_filter=protocol_name),
            "protocol_versions": store.protocol_texts(),
            "sessions": store.sessions_overview(protocol_name),
            "demographics": [{"protocol": p, "participant": c, **v} for (p, c), v in _demographics(store).items()
                             if protocol_name is None or p == protocol_name],
            "answers": json.loads(df.to_json(orient="records")),
        }
        return json.dumps(doc, indent=2)
    raise TactilizeError("--format", f"must be csv or json, got {fmt!r}")


def export_strokes(store, fmt: str = "csv", protocol_name: str | None = None) -> str:
    """The stroke log: one row per pen sample with the drive it produced (SI units)."""
    import pandas as pd

    sessions = {s["session"]: s for s in store.sessions_overview(protocol_name)}
    rows = [dict(r, participant=sessions[r["session"]]["participant"], protocol=sessions[r["session"]]["protocol"])
            for r in store.stroke_rows() if r["session"] in sessions]
    cols = ["protocol", "participant", "session", "trial", "condition", "image", "t_s", "x_m", "y_m", "pressure", "speed_m_s",
            "pulse_frequency_hz", "pulse_width_s", "amplitude", "received_at"]
    df = pd.DataFrame(rows, columns=cols)
    if fmt == "csv":
        buf = io.StringIO()
        df.to_csv(buf, index=False, lineterminator="\n")
        return buf.getvalue()
    if fmt == "json":
        return json.dumps({"provenance": provenance(db=_redact(store.url)), "strokes": json.loads(df.to_json(orient="records"))},
                          indent=2)
    raise TactilizeError("--format", f"must be csv or json, got {fmt!r}")


def _demographics(store) -> dict:
    return all_answers(store)


def _redact(url: str) -> str:
    # The one rule for every database URL shown or written (tactilize.redact).
    return redact_url(url)


def _f(x: Any) -> float | None:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _col(row, *names):
    # pingouin renamed columns across versions ("p-unc" -> "p_unc", "W-val" -> "W_val").
    for n in names:
        if n in row.index:
            return row[n]
    return float("nan")


def describe(values) -> dict[str, Any]:
    """n, median, q1, q3, IQR, mean, SD (ddof = 1) of one condition's ratings."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0, "median": None, "q1": None, "q3": None, "iqr": None, "mean": None, "sd": None}
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return {
        "n": int(v.size),
        "median": float(med),
        "q1": float(q1),
        "q3": float(q3),
        "iqr": float(q3 - q1),
        "mean": float(v.mean()),
        "sd": _f(v.std(ddof=1)) if v.size > 1 else None,
    }


def _wide(cell):
    """participants x conditions, complete cases only."""
    wide = cell.pivot(index="participant", columns="condition", values="rating")
    return wide.dropna(axis=0, how="any")


def friedman(cell) -> dict[str, Any] | None:
    """Friedman's test (F and chi-square variants) with Kendall's W, via pingouin.

    ``cell``: long DataFrame with participant, condition, rating (one row per cell).
    None when there are fewer than 2 conditions or 2 complete participants.
    """
    import pingouin as pg

    wide = _wide(cell)
    if wide.shape[1] < 2 or wide.shape[0] < 2:
        return None
    long = wide.reset_index().melt(id_vars="participant", var_name="condition", value_name="rating")
    if long["rating"].nunique() < 2:
        return {"n": int(wide.shape[0]), "k": int(wide.shape[1]), "F": None, "ddof1": None, "ddof2": None,
                "p": 1.0, "W": 0.0, "Q": 0.0, "p_chisq": 1.0, "note": "all ratings identical"}
    f = pg.friedman(long, dv="rating", within="condition", subject="participant", method="f").iloc[0]
    c = pg.friedman(long, dv="rating", within="condition", subject="participant", method="chisq").iloc[0]
    return {
        "n": int(wide.shape[0]),
        "k": int(wide.shape[1]),
        "F": _f(f["F"]),
        "ddof1": _f(f["ddof1"]),
        "ddof2": _f(f["ddof2"]),
        "p": _f(_col(f, "p_unc", "p-unc")),
        "W": _f(f["W"]),
        "Q": _f(c["Q"]),
        "p_chisq": _f(_col(c, "p_unc", "p-unc")),
    }


#: Sign patterns enumerated at most for the permutation p-value: 2 ** 13, the
#: sample size up to which scipy's own choice for tied or zero differences is a
#: complete permutation test (beyond it, its normal approximation), kept so that the
#: p-values are scipy's and pingouin's.
_PERMUTATION_MAX_N = 13
#: What :func:`signed_rank_test` does, for the provenance of every analysis.
WILCOXON_METHOD = (
    "two-sided Wilcoxon signed-rank test, zeros dropped (Wilcoxon's method): without ties or zeros scipy's exact "
    "distribution (n <= 50); with ties or zeros and n <= 13 the exact permutation distribution of the signed-rank "
    "sum over all 2^n sign patterns; otherwise the normal approximation with the tie correction and no continuity "
    "correction (scipy.stats.wilcoxon's defaults)"
)


def signed_rank_test(x, y) -> dict[str, Any]:
    """Two-sided Wilcoxon signed-rank test of paired differences, with its effect sizes.

    The same p-value as ``scipy.stats.wilcoxon(d)`` (and so ``pingouin.wilcoxon``)
    with their default ``method="auto"``, which for tied or zero differences of a
    small sample runs a resampling permutation test (thousands of calls of the
    statistic); here that case enumerates the 2^n sign patterns at once.  The
    method is :data:`WILCOXON_METHOD`.

    Parameters
    ----------
    x, y : array_like of float
        Paired ratings (one per participant), their differences not all zero.

    Returns
    -------
    dict
        ``W`` (the smaller of the positive and negative rank sums), ``p``,
        ``rbc`` (matched-pairs rank-biserial correlation, (R+ - R-) / (R+ + R-)),
        ``cles`` (the common-language effect size: the share of all pairs (x_i, y_j)
        with x_i > y_j, ties counting a half, as pingouin gives it) and
        ``method`` ("exact", "permutation" or "normal approximation").
    """
    from scipy.stats import rankdata, wilcoxon

    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    d = x - y
    nz = d[d != 0]
    r = rankdata(np.abs(nz))
    r_plus, r_minus = float(r[nz > 0].sum()), float(r[nz < 0].sum())
    tied = np.unique(np.abs(nz)).size < nz.size
    n = d.size
    if not tied and nz.size == n and n <= 50:
        method, p = "exact", float(wilcoxon(d, method="exact").pvalue)
    elif n <= _PERMUTATION_MAX_N:
        # Every assignment of signs to the ranks is equally likely under the null;
        # a zero difference's sign changes nothing, so its patterns are left out.
        signs = (np.arange(1 << nz.size)[:, None] >> np.arange(nz.size)) & 1
        null = signs @ r
        tol = 1e-9 * max(1.0, r_plus)  # rank sums are multiples of 0.5: equal means equal
        p_less, p_greater = float(np.mean(null <= r_plus + tol)), float(np.mean(null >= r_plus - tol))
        method, p = "permutation", min(1.0, 2.0 * min(p_less, p_greater))
    else:
        method, p = "normal approximation", float(wilcoxon(d, method="asymptotic").pvalue)
    return {"W": min(r_plus, r_minus), "p": _f(p), "rbc": _f((r_plus - r_minus) / (r_plus + r_minus)),
            "cles": _f(np.where(x[:, None] == y, 0.5, x[:, None] > y).mean()), "method": method}


def pairwise_wilcoxon(cell) -> list[dict[str, Any]]:
    """Wilcoxon signed-rank tests for every pair of conditions (:func:`signed_rank_test`),
    Holm-corrected (pingouin)."""
    import pingouin as pg

    wide = _wide(cell)
    out = []
    for a, b in combinations(list(wide.columns), 2):
        x, y = wide[a].to_numpy(float), wide[b].to_numpy(float)
        d = x - y
        row = {"a": str(a), "b": str(b), "n": int(len(d)), "median_diff": _f(np.median(d)) if len(d) else None}
        if len(d) < 2:
            row.update({"W": None, "p": None, "rbc": None, "cles": None, "note": "fewer than 2 complete participants"})
        elif np.all(d == 0):
            # Every participant rated both the same: nothing differs (scipy would refuse).
            row.update({"W": 0.0, "p": 1.0, "rbc": 0.0, "cles": 0.5, "note": "no non-zero differences"})
        else:
            row.update(signed_rank_test(x, y))
        out.append(row)
    tested = [r for r in out if r["p"] is not None]
    for r in out:
        r["p_holm"], r["significant_0_05"] = None, False
    if tested:
        # Holm over the pairs that could be tested; untested pairs do not dilute it.
        reject, corrected = pg.multicomp([r["p"] for r in tested], method="holm")
        for r, pc, rej in zip(tested, corrected, reject):
            r["p_holm"] = _f(pc)
            r["significant_0_05"] = bool(rej)
    return out


def protocol_labels(store_or_df, pnames) -> dict[str, dict[str, str]]:
    """``{protocol: {condition or question id: label}, "__title__": title}`` from the
    stored protocol texts (the newest version wins), the question's whole text as its
    label; empty when only a DataFrame is given."""
    out: dict[str, dict[str, str]] = {}
    if not hasattr(store_or_df, "protocol_texts"):
        return out
    for pv in store_or_df.protocol_texts():
        if pv["name"] not in pnames:
            continue
        try:
            proto = design_from_toml(pv["text"], source=f"stored {pv['name']}")
        except DesignError:  # a stored text today's checks refuse: ids stay as they are
            continue
        labels = {c.id: c.label for c in proto.conditions}
        labels.update({q.id: q.text for q in proto.questions})
        out[pv["name"]] = {**labels, "__title__": proto.title}
    return out


def analyze(store_or_df, protocol_name: str | None = None, include_simulated: bool = False) -> dict[str, Any]:
    """Analyse every protocol in the store (or a tidy DataFrame).

    Simulated participants are left out unless ``include_simulated`` is true
    (the provenance block says which).

    Returns
    -------
    dict
        ``{"provenance": ..., "protocols": {name: {"n_participants", "questions":
        {qid: {"descriptives": {condition: {...}}, "friedman": {...} | None,
        "pairwise": [...]}}, "condition_labels": {condition: label}}}}``.  Values
        are plain floats (None for undefined); the labels are the protocol's (the ids
        themselves when only a DataFrame is given).
    """
    if hasattr(store_or_df, "answer_rows"):
        df = tidy_answers(store_or_df, protocol_name, include_simulated)
        df = df[~df["excluded"].astype(bool)]  # excluded by the experimenter's decision (labdata.exclude)
        prov = provenance(db=_redact(store_or_df.url))
    else:
        df = store_or_df if protocol_name is None else store_or_df[store_or_df["protocol"] == protocol_name]
        if not include_simulated and "simulated" in df:
            df = df[~df["simulated"].astype(bool)]
        prov = provenance()
    prov["simulated_participants"] = "included" if include_simulated else "excluded"
    import pingouin
    import scipy

    prov.update({"pingouin": pingouin.__version__, "scipy": scipy.__version__,
                 "aggregation": "mean rating per participant and condition (over images and repetitions)",
                 "wilcoxon": WILCOXON_METHOD})
    result: dict[str, Any] = {"provenance": prov, "protocols": {}}
    labels = protocol_labels(store_or_df, set(df["protocol"]))
    for pname, pdf in df.groupby("protocol", sort=True):
        pres: dict[str, Any] = {
            "n_participants": int(pdf["participant"].nunique()),
            "n_answers": int(len(pdf)),
            "seeds": sorted({int(s) for s in pdf["seed"]}),
            "protocol_sha256": sorted(set(pdf["protocol_sha256"])),
            "conditions": list(dict.fromkeys(sorted(pdf["condition"].unique()))),
            "questions": {},
        }
        plabels = labels.get(str(pname), {})
        pres["condition_labels"] = {str(c): plabels.get(str(c), str(c)) for c in pres["conditions"]}
        for qid, qdf in pdf.groupby("question", sort=False):
            cell = qdf.groupby(["participant", "condition"], as_index=False)["rating"].mean()
            desc = {str(c): describe(g["rating"]) for c, g in cell.groupby("condition", sort=True)}
            pres["questions"][str(qid)] = {
                "descriptives": desc,
                "friedman": friedman(cell),
                "pairwise": pairwise_wilcoxon(cell) if cell["condition"].nunique() > 1 else [],
            }
        result["protocols"][str(pname)] = pres
    return result
