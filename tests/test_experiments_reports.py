"""What a researcher reads and publishes: the protocol list, the analysis printout, the wide
export per protocol, the docs' table of built-ins, and figures ready for a journal."""

from __future__ import annotations

import csv
import io
import itertools
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from tactilize.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _run(*args):
    return CliRunner().invoke(main, ["experiment", *args], catch_exceptions=False)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """Every built-in protocol, 4 synthetic participants each."""
    from tactilize.experiments import builtin_protocols

    db = str(tmp_path_factory.mktemp("reports") / "all.sqlite3")
    for p in builtin_protocols():
        r = _run("simulate", p.name, "--participants", "4", "--seed", "5", "--db", db)
        assert r.exit_code == 0, r.output
    return db


# ----------------------------------------------------------------- the protocol list and the docs


def test_the_protocol_list_lines_up_and_counts_in_words():
    from tactilize.experiments import builtin_protocols

    lines = _run("protocols").output.splitlines()
    assert len(lines) == len(builtin_protocols()) == 5
    # One column each: the version, the counts and n start at the same place on every line.
    for token in (" v1 ", "condition", "image", "question", "trial", "n = "):
        assert len({line.index(token) for line in lines}) == 1, (token, lines)
    assessment = next(line for line in lines if line.startswith("assessment"))
    assert re.search(r"\b1 condition\b", assessment) and "1 conditions" not in assessment
    assert "1 trial " in assessment


def test_the_docs_list_every_built_in():
    from tactilize.experiments import builtin_protocols

    text = (ROOT / "docs" / "experiments.md").read_text()
    names = [p.name for p in builtin_protocols()]
    assert "the four built-ins" not in text and "the five built-ins" in text and len(names) == 5
    table = text[text.index("### The built-ins"):]
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    assert sorted(re.match(r"\| `([^`]+)`", r).group(1) for r in rows) == sorted(names)
    assert all(r.count("|") == 7 for r in rows)  # six cells each, like the header


# ----------------------------------------------------------------- the analysis printout


def test_analyze_prints_each_condition_with_its_label(store):
    from tactilize.experiments import load_protocol

    out = _run("analyze", "--db", store, "--include-simulated", "--protocol", "alpha-law").output
    for c in load_protocol("alpha-law").conditions:
        assert re.search(rf"^\s+{c.id}\s+{re.escape(c.label)}\s+n=", out, re.M), (c.id, c.label, out)


# ----------------------------------------------------------------- the wide table, per protocol


def test_the_wide_export_keeps_protocols_apart(store, tmp_path):
    r = CliRunner().invoke(main, ["experiment", "export", "--db", store, "--format", "wide"])
    assert r.exit_code == 2
    assert "5 protocols" in r.output and "--protocol" in r.output
    out = tmp_path / "wide.csv"
    r = _run("export", "--db", store, "--format", "wide", "-o", str(out))
    assert r.exit_code == 0, r.output
    from tactilize.experiments import builtin_protocols

    for p in builtin_protocols():
        path = tmp_path / f"wide-{p.name}.csv"
        rows = list(csv.DictReader(io.StringIO(path.read_text())))
        assert len(rows) == 4 and {row["protocol"] for row in rows} == {p.name}
        # Only this protocol's conditions and questions, every cell filled.
        rated = [k for k in rows[0] if "_" in k and k.split("_", 1)[0] in {c.id for c in p.conditions}]
        assert len(rated) == len(p.conditions) * len(p.questions)
        assert all(row[k] != "" for row in rows for k in rated)
        assert (tmp_path / f"wide-{p.name}.csv.provenance.json").exists()
    one = _run("export", "--db", store, "--format", "wide", "--protocol", "h-law").output
    assert {row["protocol"] for row in csv.DictReader(io.StringIO(one))} == {"h-law"}


# ----------------------------------------------------------------- figures to publish


def _overlaps(boxes):
    return [(a[0], b[0]) for a, b in itertools.combinations(boxes, 2)
            if a[1].x0 < b[1].x1 - 0.5 and b[1].x0 < a[1].x1 - 0.5 and a[1].y0 < b[1].y1 - 0.5 and b[1].y0 < a[1].y1 - 0.5]


@pytest.mark.parametrize("width", ["single", "double"])
def test_every_figure_is_readable_as_made(store, width):
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    from tactilize.experiments import Store, builtin_protocols
    from tactilize.experiments.analysis import analyze, protocol_labels, tidy_answers
    from tactilize.experiments.figures import COLUMN_WIDTHS_MM, OKABE_ITO, protocol_figure, text_boxes

    st = Store(store, must_exist=True)
    df = tidy_answers(st, None, True)
    result = analyze(df, include_simulated=True)
    protos = builtin_protocols()
    labels = protocol_labels(st, {p.name for p in protos})
    for p in protos:
        fig, _ = protocol_figure(df, p.name, labels[p.name], result, width)
        try:
            assert fig.get_size_inches()[0] * 25.4 == pytest.approx(COLUMN_WIDTHS_MM[width])
            boxes = text_boxes(fig)
            # No two pieces of text overlap, and none leaves the figure.
            assert not _overlaps(boxes), (p.name, width, _overlaps(boxes))
            frame = fig.bbox
            for text, box in boxes:
                assert box.x0 >= -0.5 and box.y0 >= -0.5 and box.x1 <= frame.x1 + 0.5 and box.y1 <= frame.y1 + 0.5, \
                    (p.name, width, text)
            # The legend is whole: every question's full text, inside the figure.
            if len(p.conditions) > 1 and len(p.questions) > 1:
                (legend,) = fig.legends
                shown = [t.get_text().replace("\n", " ") for t in legend.get_texts()]
                assert shown == [q.text for q in p.questions]
                lb = legend.get_window_extent(fig.canvas.get_renderer())
                assert lb.x0 >= 0 and lb.y0 >= 0 and lb.x1 <= frame.x1 and lb.y1 <= frame.y1
            # Every condition (or item) is named on the figure, under its bar or in the key.
            everything = " ".join(t.replace("\n", " ") for t, _ in boxes)
            for c in (p.conditions if len(p.conditions) > 1 else p.questions):
                assert (c.label if len(p.conditions) > 1 else c.text) in everything
            # Colour-blind-safe bars.
            bars = [a for a in fig.axes[0].patches if (a.get_gid() or "").startswith("bar:")]
            assert bars and {to_hex(b.get_facecolor(), keep_alpha=False) for b in bars} <= {c.lower() for c in OKABE_ITO}
        finally:
            plt.close(fig)


def test_figures_are_written_as_vectors_too(store, tmp_path):
    r = _run("analyze", "--db", store, "--include-simulated", "--protocol", "alpha-law", "--figures", str(tmp_path),
             "--figure-width", "single")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "alpha-law.pdf").read_bytes().startswith(b"%PDF")
    svg = (tmp_path / "alpha-law.svg").read_text()
    assert "<svg" in svg and "How well did the strength of the touch follow" in svg  # text kept as text
    from PIL import Image

    with Image.open(tmp_path / "alpha-law.png") as im:
        assert im.size[0] == pytest.approx(89 / 25.4 * 300, abs=2)  # one column at 300 dpi
