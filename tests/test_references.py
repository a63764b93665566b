"""Citations point into the repository: docs/references.md, by section and label.

The code once cited a fact sheet that lived outside the repository, which no
installed user could open.  These tests keep every citation followable: no file
under ``src/`` or ``docs/`` (nor the README) names that sheet, and every
``docs/references.md, section N (label)`` names a section, and a labelled fact in
it, that exist.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCES = ROOT / "docs" / "references.md"
TEXT_SUFFIXES = {".py", ".pyi", ".md", ".toml", ".js", ".mjs", ".html", ".css", ".txt", ".json", ".cfg", ".ini"}

#: The nine sections, numbered as citations use them; renumbering breaks citations.
SECTIONS = {
    1: "The paper's laws and its spectral intensity",
    2: "The SMA micro-wire",
    3: "Touch perception",
    4: "Two actuators: phantom sensation and apparent movement",
    5: "Pen input in the browser",
    6: "Haptic file formats",
    7: "Experiment practice",
    8: "Driving a real wire (electrical)",
    9: "Latency and stroking speed",
    10: "The chip model",
    11: "Materials",
}

#: "docs/references.md, section 2 (operating point)", "..., sections 1 and 7", "..., sections 4, 5".
CITATION = re.compile(
    r"docs/references\.md,\s+sections?\s+(?P<numbers>\d+(?:\s*(?:,|and)\s*\d+)*)(?:[ \t]+\((?P<labels>[^()\n]*)\))?"
)
HEADING = re.compile(r"^## (\d+)\. (.+)$", re.MULTILINE)
LABEL = re.compile(r"\*\*([^*]+?)\.?\*\*")
OLD_SHEET = "FACTS.md"


def _cited_files(include_docs: bool = True) -> list[Path]:
    files = [p for p in (ROOT / "src").rglob("*") if p.is_file() and p.suffix in TEXT_SUFFIXES
             and "__pycache__" not in p.parts]
    if include_docs:
        files += sorted((ROOT / "docs").rglob("*.md"))
        files.append(ROOT / "README.md")
    return sorted(p for p in files if p.is_file())


def _read(path: Path) -> str:
    return path.read_text(encoding="utf-8", errors="replace")


def _sections() -> dict[int, str]:
    """Section number -> its text (heading included), from docs/references.md."""
    text = _read(REFERENCES)
    heads = list(HEADING.finditer(text))
    out = {}
    for i, m in enumerate(heads):
        end = heads[i + 1].start() if i + 1 < len(heads) else len(text)
        out[int(m.group(1))] = text[m.start():end]
    return out


def _labels(section_text: str) -> set[str]:
    """The bold labels of a section's facts, and its title, lower-cased."""
    title = HEADING.match(section_text).group(2)
    return {m.group(1).strip().lower() for m in LABEL.finditer(section_text)} | {title.strip().lower()}


def _citations(include_docs: bool = True):
    for path in _cited_files(include_docs):
        text = _read(path)
        for m in CITATION.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            numbers = [int(n) for n in re.findall(r"\d+", m.group("numbers"))]
            yield path.relative_to(ROOT), line, numbers, m.group("labels")


def test_references_has_its_numbered_sections():
    found = {n: HEADING.match(t).group(2) for n, t in _sections().items()}
    assert found == SECTIONS


def test_every_fact_has_a_label():
    # Each bullet of a section body opens with its bold label, so code can cite it by name.
    # (The list after "Sources for this section" holds citations, not facts.)
    for n, text in _sections().items():
        facts = text.split("Sources for this section")[0]
        for bullet in re.findall(r"^- (.*)$", facts, re.MULTILINE):
            assert LABEL.match(bullet), f"section {n}: a fact without a bold label: {bullet[:60]!r}"


def test_nothing_cites_the_old_fact_sheet():
    """No file under src/ or docs/, nor the README, may cite a fact sheet outside the repository.

    Lists every file still naming it; cite docs/references.md, section N (label) instead.
    """
    still = [str(p.relative_to(ROOT)) for p in _cited_files() if OLD_SHEET in _read(p)]
    assert not still, f"{len(still)} file(s) still cite {OLD_SHEET}: " + ", ".join(still)


def test_cited_sections_exist():
    sections = _sections()
    citations = list(_citations())
    assert any(str(path).startswith("src") for path, *_ in citations), "no citation found in src/ at all"
    bad = [f"{path}:{line}: section {n}" for path, line, numbers, _ in citations for n in numbers
           if n not in sections]
    assert not bad, "citations of sections that docs/references.md does not have:\n" + "\n".join(bad)


def test_cited_labels_exist():
    # A label given after a single section must be one of that section's bold labels (or its title);
    # several facts may be named, separated by commas.
    sections = _sections()
    bad = []
    for path, line, numbers, labels in _citations():
        if labels is None or len(numbers) != 1 or numbers[0] not in sections:
            continue
        known = _labels(sections[numbers[0]])
        for label in (part.strip().lower() for part in labels.split(",")):
            if label not in known:
                bad.append(f"{path}:{line}: section {numbers[0]} has no fact labelled {label!r}")
    assert not bad, "\n".join(bad) + "\n(labels are the bold words that open each fact in docs/references.md)"
