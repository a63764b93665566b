"""Analysis and figures checked against independent computations on a small fixed dataset."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from tactilize.experiments.analysis import analyze
from tactilize.experiments.figures import make_figures, protocol_figure

# Six participants rate three conditions on two questions (1..7).  Rows have no
# ties within a participant for "q1", so every textbook formula applies unchanged.
Q1 = {  # participant: (A, B, C)
    "p1": (2, 5, 6), "p2": (3, 6, 4), "p3": (1, 4, 7), "p4": (2, 3, 5), "p5": (4, 7, 6), "p6": (3, 5, 7),
}
Q2 = {
    "p1": (4, 4, 5), "p2": (5, 3, 4), "p3": (2, 6, 6), "p4": (6, 5, 7), "p5": (3, 4, 7), "p6": (4, 4, 4),
}
CONDS = ("A", "B", "C")


def _tidy():
    rows = []
    for q, table in (("q1", Q1), ("q2", Q2)):
        for p, vals in table.items():
            for c, r in zip(CONDS, vals):
                rows.append({"protocol": "toy", "protocol_sha256": "abc", "seed": 5, "participant": p,
                             "condition": c, "question": q, "rating": r, "image": "img", "trial": CONDS.index(c)})
    return pd.DataFrame(rows)


def _holm(p):
    p = np.asarray(p, float)
    order = np.argsort(p)
    m = len(p)
    adj = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, (m - rank) * p[i])
        adj[i] = min(1.0, running)
    return adj


def _rank_biserial(x, y):
    d = np.asarray(x, float) - np.asarray(y, float)
    d = d[d != 0]
    ranks = stats.rankdata(np.abs(d))
    rp, rm = ranks[d > 0].sum(), ranks[d < 0].sum()
    return (rp - rm) / (rp + rm)


@pytest.fixture(scope="module")
def result():
    return analyze(_tidy())["protocols"]["toy"]


@pytest.mark.parametrize("q, table", [("q1", Q1), ("q2", Q2)])
def test_descriptives_match_numpy(result, q, table):
    desc = result["questions"][q]["descriptives"]
    for j, c in enumerate(CONDS):
        v = np.array([vals[j] for vals in table.values()], float)
        d = desc[c]
        assert d["n"] == 6
        assert d["median"] == pytest.approx(np.median(v))
        assert d["mean"] == pytest.approx(v.mean())
        assert d["sd"] == pytest.approx(np.sqrt(((v - v.mean()) ** 2).sum() / 5))
        lo, hi = np.quantile(v, [0.25, 0.75])
        assert d["iqr"] == pytest.approx(hi - lo)


@pytest.mark.parametrize("q, table", [("q1", Q1), ("q2", Q2)])
def test_friedman_and_kendalls_w_match_scipy_and_hand_ranks(result, q, table):
    fr = result["questions"][q]["friedman"]
    cols = [np.array([vals[j] for vals in table.values()], float) for j in range(3)]
    chi2, p = stats.friedmanchisquare(*cols)
    n, k = 6, 3
    assert fr["n"] == n and fr["k"] == k
    assert fr["Q"] == pytest.approx(chi2)
    assert fr["p_chisq"] == pytest.approx(p)
    if q == "q1":
        # No ties: Kendall's W from the rank sums by hand, W = 12 S / (n^2 (k^3 - k)).
        ranks = np.array([stats.rankdata(row) for row in np.column_stack(cols)])
        r = ranks.sum(axis=0)
        s = ((r - r.mean()) ** 2).sum()
        w = 12 * s / (n**2 * (k**3 - k))
        assert fr["W"] == pytest.approx(w)
        assert chi2 == pytest.approx(n * (k - 1) * w)
    w = fr["W"]
    # The F variant: F = (n - 1) W / (1 - W), df1 = k - 1 - 2/n, df2 = (n - 1) df1.
    df1 = k - 1 - 2 / n
    f = (n - 1) * w / (1 - w)
    assert fr["F"] == pytest.approx(f)
    assert fr["ddof1"] == pytest.approx(df1) and fr["ddof2"] == pytest.approx((n - 1) * df1)
    assert fr["p"] == pytest.approx(stats.f.sf(f, df1, (n - 1) * df1))


def test_pairwise_wilcoxon_holm_and_effect_sizes(result):
    pw = result["questions"]["q1"]["pairwise"]
    assert [(r["a"], r["b"]) for r in pw] == list(itertools.combinations(CONDS, 2))
    raw = []
    for r in pw:
        i, j = CONDS.index(r["a"]), CONDS.index(r["b"])
        x = [v[i] for v in Q1.values()]
        y = [v[j] for v in Q1.values()]
        ref = stats.wilcoxon(x, y)
        assert r["p"] == pytest.approx(ref.pvalue)
        assert r["W"] == pytest.approx(ref.statistic)
        assert r["rbc"] == pytest.approx(_rank_biserial(x, y))
        raw.append(ref.pvalue)
    assert [r["p_holm"] for r in pw] == pytest.approx(list(_holm(raw)))
    # With n = 6 the smallest exact two-sided p is 2 / 2^6:
    # docs/references.md, section 7 (smallest Wilcoxon p).
    assert min(r["p"] for r in pw) == pytest.approx(2 / 2**6)


def test_figures_plot_the_independently_computed_means(tmp_path):
    df = _tidy()
    fig, data = protocol_figure(df, "toy")
    ax = fig.axes[0]
    heights = [[bar.get_height() for bar in cont] for cont in ax.containers if hasattr(cont, "patches")]
    expected = [[np.mean([v[CONDS.index(c)] for v in table.values()]) for c in CONDS] for table in (Q1, Q2)]
    assert heights == [pytest.approx(e) for e in expected]
    assert [t.get_text() for t in ax.get_xticklabels()] == list(CONDS)
    written = make_figures(df, tmp_path)
    png, svg = written["toy"]["png"], written["toy"]["svg"]
    assert open(png, "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    text = open(svg, encoding="utf-8").read()
    assert "<svg" in text and "tactilize" in text  # provenance in the metadata


def test_assessment_figure_is_per_item(tmp_path):
    df = _tidy()
    df = df[df["condition"] == "A"].assign(protocol="assessment")
    _fig, data = protocol_figure(df, "assessment")
    assert data["by_item"] and data["x"] == ["q1", "q2"]
    assert data["mean"]["A"]["q2"] == pytest.approx(np.mean([v[0] for v in Q2.values()]))
    res = analyze(df)["protocols"]["assessment"]["questions"]["q1"]
    assert res["friedman"] is None and res["pairwise"] == []  # one condition: nothing to compare


def test_incomplete_participants_leave_the_tests_not_the_descriptives():
    df = _tidy()
    # p6 stopped after condition A: kept in A's descriptives, dropped from the tests.
    df = df[~((df["participant"] == "p6") & (df["condition"] != "A"))]
    res = analyze(df)["protocols"]["toy"]["questions"]["q1"]
    assert res["descriptives"]["A"]["n"] == 6 and res["descriptives"]["B"]["n"] == 5
    assert res["friedman"]["n"] == 5
    cols = [[Q1[p][j] for p in ("p1", "p2", "p3", "p4", "p5")] for j in range(3)]
    assert res["friedman"]["Q"] == pytest.approx(stats.friedmanchisquare(*cols).statistic)
    assert all(r["n"] == 5 for r in res["pairwise"])
    one = analyze(df[df["participant"] == "p1"])["protocols"]["toy"]["questions"]["q1"]
    assert one["friedman"] is None
    assert all(r["p"] is None and r["p_holm"] is None for r in one["pairwise"])


# Paired ratings of the kinds an experiment gives: distinct differences (exact),
# ties and zeros at n <= 13 (scipy's permutation test), ties at n = 20 (its normal
# approximation).
_RNG = np.random.default_rng(7)
SIGNED_RANK_CASES = {
    "no ties": ([2.1, 3.5, 4.0, 1.2, 6.3, 5.5, 2.9], [1.0, 3.7, 2.0, 1.9, 3.3, 2.6, 2.8]),
    "ties and zeros, n = 10": ([4, 5, 3, 6, 4, 5, 7, 2, 4, 5], [3, 5, 2, 4, 4, 3, 5, 2, 3, 4]),
    "ties, n = 13": (list(_RNG.integers(1, 8, 13)), list(_RNG.integers(1, 8, 13))),
    "half-point means, n = 8": ([3.5, 4.0, 5.5, 2.5, 6.0, 4.5, 3.0, 5.0], [3.0, 4.5, 4.0, 2.5, 4.0, 3.5, 3.5, 4.0]),
    "ties, n = 20": (list(_RNG.integers(1, 8, 20)), list(_RNG.integers(1, 8, 20))),
}


@pytest.mark.parametrize("case", sorted(SIGNED_RANK_CASES))
def test_signed_rank_p_values_are_scipys_without_its_resampling(case, monkeypatch):
    """The p-value of scipy's own choice of method, with scipy's permutation test never run."""
    import scipy.stats

    from tactilize.experiments.analysis import signed_rank_test

    x, y = (np.asarray(v, float) for v in SIGNED_RANK_CASES[case])
    ref = stats.wilcoxon(x, y)  # method="auto", before the permutation test is taken away
    monkeypatch.setattr(scipy.stats, "permutation_test", lambda *a, **k: pytest.fail("permutation_test was called"))
    got = signed_rank_test(x, y)
    assert got["p"] == pytest.approx(ref.pvalue, rel=1e-12)
    assert got["W"] == pytest.approx(ref.statistic)
    assert got["method"] == {"no ties": "exact", "ties, n = 20": "normal approximation"}.get(case, "permutation")


def test_analyze_runs_no_resampling_and_names_its_method(monkeypatch):
    import scipy.stats

    monkeypatch.setattr(scipy.stats, "permutation_test", lambda *a, **k: pytest.fail("permutation_test was called"))
    res = analyze(_tidy())
    pw = res["protocols"]["toy"]["questions"]["q2"]["pairwise"]  # q2 has tied differences
    assert {r["method"] for r in pw if r["p"] is not None} == {"permutation"}
    assert "permutation" in res["provenance"]["wilcoxon"]


def test_a_figure_title_in_parentheses_counts_the_participants_inside_them():
    df = _tidy()
    labels = {"__title__": "Assessment of the tactile pen (six images, four items)"}
    fig, _ = protocol_figure(df, "toy", labels=labels)
    title = " ".join(fig.axes[0].get_title().split())
    assert title == "Assessment of the tactile pen (six images, four items; n = 6)"
    fig, _ = protocol_figure(df, "toy", labels={"__title__": "Speed law"})
    assert " ".join(fig.axes[0].get_title().split()) == "Speed law (n = 6)"
