"""The page's readouts say what they mean, and docs/serve.md says it too (the surface rendering's words)."""

from __future__ import annotations

import html
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = (ROOT / "src/tactilize/web/static/index.html").read_text("utf-8")


def _title_of(marker: str) -> str:
    m = re.search(r'<(?:th|td)[^>]*title="([^"]*)"[^>]*>' + re.escape(marker), PAGE)
    assert m, marker
    return html.unescape(m.group(1))


def test_each_readout_row_has_a_hint_in_plain_words():
    assert "bumps" in _title_of("pulse frequency") and "not a tone" in _title_of("pulse frequency")
    assert "strength" in _title_of("pulse width")
    clamped = _title_of("clamped by")
    for name in ("late", "cluster", "merged", "rate_only", "max_duty_ratio"):
        assert name in clamped
    hint = re.search(r'data-testid="readout-hint">(.*?)</p>', PAGE, re.S)
    assert hint and "late" in hint.group(1) and "bumps" in hint.group(1)


def test_serve_docs_explain_the_readouts_and_the_surface_profile():
    doc = (ROOT / "docs/serve.md").read_text("utf-8")
    assert "`late` (the bump was" in doc and "it is not a tone" in doc
    assert "profile perceptual)" not in doc  # the --lan sample shows the default, surface
    profile = doc[doc.index("- **Profile**"):doc.index("- **This stroke**")]
    assert "bump" in profile and "`perceptual` (textures a frequency JND apart" in profile


def test_readme_names_the_extra_every_experiment_export_needs():
    readme = (ROOT / "README.md").read_text("utf-8")
    row = next(line for line in readme.splitlines() if line.startswith("| `experiments` |"))
    assert "`experiment export` in every format" in row
    assert "a few seconds)" not in readme  # the first compile's cost is stated, not guessed
