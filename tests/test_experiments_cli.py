"""``tactilize experiment ...``: JSON output, exports, figures, calibration, one-line errors."""

from __future__ import annotations

import csv
import io
import json

from click.testing import CliRunner

from tactilize.cli import main


def _run(*args):
    result = CliRunner().invoke(main, ["experiment", *args], catch_exceptions=False)
    return result


def test_protocols_json_lists_the_builtins():
    r = _run("protocols", "--json")
    assert r.exit_code == 0
    doc = json.loads(r.output)
    assert [p["name"] for p in doc] == ["alpha-law", "assessment", "g-law", "h-law", "perceptual-law"]
    assert all(len(p["sha256"]) == 64 and "seed" in p["order"] for p in doc)


def test_simulate_export_analyze_calibrate(tmp_path):
    db = str(tmp_path / "cli.sqlite3")
    r = _run("simulate", "alpha-law", "--participants", "4", "--seed", "3", "--db", db, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["trials_submitted"] == 16

    r = _run("status", "--db", db, "--json")
    sessions = json.loads(r.output)["sessions"]
    assert len(sessions) == 4 and all(s["trials_done"] == s["trials_total"] == 4 for s in sessions)

    out = tmp_path / "answers.csv"
    assert _run("export", "--db", db, "--format", "csv", "-o", str(out)).exit_code == 0
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert len(rows) == 4 * 4 * 2
    assert {r["participant"] for r in rows} == {f"SIM-3-00{i}" for i in range(1, 5)}
    prov = json.loads((tmp_path / "answers.csv.provenance.json").read_text())
    assert prov["tactilize"] and prov["schema_version"] == 1

    strokes = list(csv.DictReader(io.StringIO(_run("export", "--db", db, "--strokes").output)))
    assert len(strokes) == 4 * 4 * 3 * 12  # participants x trials x images x samples per stroke
    assert all(float(s["pulse_frequency_hz"]) <= 300 for s in strokes)

    doc = json.loads(_run("export", "--db", db, "--format", "json").output)
    assert doc["provenance"]["python"] and len(doc["answers"]) == 32
    assert doc["protocol_versions"][0]["name"] == "alpha-law"

    # Simulated participants are left out of the analysis unless asked for.
    r = _run("analyze", "--db", db)
    assert r.exit_code == 2 and "--include-simulated" in r.output
    r = _run("analyze", "--db", db, "--figures", str(tmp_path / "figs"), "--include-simulated", "--json")
    assert r.exit_code == 0, r.output
    res = json.loads(r.output)
    q = res["protocols"]["alpha-law"]["questions"]["speed_match"]
    assert q["friedman"]["n"] == 4 and len(q["pairwise"]) == 6
    assert (tmp_path / "figs" / "alpha-law.png").stat().st_size > 1000
    assert (tmp_path / "figs" / "alpha-law.svg").exists()
    assert (tmp_path / "figs" / "alpha-law.pdf").read_bytes().startswith(b"%PDF")

    prof = tmp_path / "me.toml"
    r = _run("calibrate", "SIM-3-001", "--db", db, "-o", str(prof), "--json")
    assert r.exit_code == 0, r.output
    from tactilize.mapping import Profile

    assert Profile.resolve(str(prof)).speed.kind == "sigmoid"

    refine = tmp_path / "refine.toml"
    r = _run("refine", "SIM-3-001", "--db", db, "-o", str(refine), "--steps", "3")
    assert r.exit_code == 0, r.output
    from tactilize.experiments.protocols import load_protocol

    assert [c.id for c in load_protocol(str(refine)).conditions] == ["R1", "R2", "R3"]


def test_bad_input_is_one_line_and_exit_2(tmp_path):
    for args in (["simulate", "nope", "--participants", "1", "--seed", "1"],
                 ["simulate", "g-law", "--participants", "0", "--seed", "1", "--db", str(tmp_path / "x.db")],
                 ["analyze", "--db", str(tmp_path / "empty.db")],
                 ["calibrate", "NOBODY", "--db", str(tmp_path / "empty.db"), "-o", str(tmp_path / "p.toml")]):
        r = CliRunner().invoke(main, ["experiment", *args])
        assert r.exit_code == 2, (args, r.output)
        assert r.output.count("\n") == 1 and r.output.startswith("tactilize: ")
