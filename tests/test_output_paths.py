"""Where the commands write: one rule for every output path (its folder must exist), said in one line."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from tactilize.cli import main
from tactilize.errors import SignalError, TactilizeError, check_output_path


def _run(*args, env=None):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False, env=env)


def _one_line_exit_2(res, *words):
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1, res.output
    assert all(w in lines[0] for w in words), lines[0]


def test_the_rule(tmp_path):
    assert check_output_path(tmp_path / "a.wav") == tmp_path / "a.wav"
    assert check_output_path(tmp_path / "figs", folder=True) == tmp_path / "figs"
    with pytest.raises(SignalError, match="does not exist"):
        check_output_path(tmp_path / "no" / "a.wav", SignalError)
    with pytest.raises(TactilizeError, match="is a folder"):
        check_output_path(tmp_path)
    (tmp_path / "f").write_text("x")
    with pytest.raises(TactilizeError, match="not a folder"):
        check_output_path(tmp_path / "f", folder=True)
    with pytest.raises(TactilizeError, match="is a file, not a folder"):
        check_output_path(tmp_path / "f" / "a.wav")


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("exp") / "exp.sqlite3"
    res = _run("experiment", "simulate", "g-law", "--participants", "2", "--seed", "1", "--db", path)
    assert res.exit_code == 0, res.output
    return path


@pytest.fixture(scope="module")
def png(tmp_path_factory):
    from tactilize.data import get_texture

    path = tmp_path_factory.mktemp("img") / "cord.png"
    path.write_bytes(get_texture("corduroy").png)
    return path


COMMANDS = {
    "export -o": lambda out, db, png: ["export", png, "--speed", "40", "--format", "ahap", "-o", out / "x.ahap"],
    "analyze --plot": lambda out, db, png: ["analyze", png, "--plot", out / "x.png"],
    "simulate --plot": lambda out, db, png: ["simulate", "--frequency", "50", "--pulse-width-ms", "1",
                                             "--current-ma", "300", "--duration", "0.1", "--plot", out / "x.png"],
    "envelope --plot": lambda out, db, png: ["envelope", "--plot", out / "x.png"],
    "profile report --plot": lambda out, db, png: ["profile", "report", "--no-wire", "--plot", out / "x.png"],
    "experiment analyze --figures": lambda out, db, png: ["experiment", "analyze", "--db", db, "--include-simulated",
                                                          "--figures", out / "figs"],
    "experiment export -o": lambda out, db, png: ["experiment", "export", "--db", db, "-o", out / "a.csv"],
    "experiment backup": lambda out, db, png: ["experiment", "backup", out / "b.sqlite3", "--db", db],
    "batch --out": lambda out, db, png: ["batch", png, "--out", out / "cat"],
}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_a_missing_folder_is_refused_in_one_line_and_not_made(tmp_path, db, png, name):
    missing = tmp_path / "missing"
    res = _run(*COMMANDS[name](missing, db, png))
    _one_line_exit_2(res, str(missing), "does not exist")
    assert not missing.exists()


def test_batch_refuses_a_file_name_for_its_catalog(tmp_path, png):
    res = _run("batch", png, "--out", tmp_path / "y.csv")
    _one_line_exit_2(res, "y.csv", "Parquet folder")
    assert not (tmp_path / "y.csv").exists()


@pytest.mark.parametrize("name", ["simulate --plot", "envelope --plot", "experiment export -o"])
def test_written_files_are_named(tmp_path, db, png, name):
    res = _run(*COMMANDS[name](tmp_path, db, png))
    assert res.exit_code == 0, res.output
    written = [ln for ln in res.output.splitlines() if ln.startswith("wrote ")]
    assert len(written) == 1 and written[0][len("wrote "):].startswith(str(tmp_path)), res.output


def test_experiment_run_takes_open_and_no_open():
    res = _run("experiment", "run", "--help")
    assert "--open / --no-open" in res.output


def test_experiment_simulate_says_where_the_database_is(tmp_path):
    res = _run("experiment", "simulate", "g-law", "--participants", "1", "--seed", "3",
               env={"XDG_DATA_HOME": str(tmp_path)})
    assert res.exit_code == 0, res.output
    line = res.output.strip().splitlines()[-1]
    assert line.startswith("database ") and str(tmp_path) in line and "experiments.sqlite3" in line


@pytest.mark.parametrize(
    "args, words",
    [
        (["simulate", "--texture", "corduroy", "--speed", "abc"], ["--speed", "abc"]),
        (["export"], ["IMAGE"]),
        (["experiment", "analyze", "--figure-width", "triple"], ["--figure-width", "triple"]),
        (["nosuchcommand"], ["nosuchcommand"]),
    ],
)
def test_clicks_own_faults_are_one_line_too(args, words):
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "tactilize.cli", *args], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tactilize: ") and all(w in lines[0] for w in words), proc.stderr


def test_a_fifo_is_named_as_one_by_analyze(tmp_path):
    import os

    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    res = _run("analyze", fifo)
    _one_line_exit_2(res, "pipe.png", "FIFO")
    assert "empty" not in res.output


def test_a_batch_folder_names_its_fifo_and_device_link_in_error_rows(tmp_path, png):
    import os

    from tactilize.catalog.sources import discover

    shop = tmp_path / "shop"
    shop.mkdir()
    (shop / "a.png").write_bytes(png.read_bytes())
    os.mkfifo(shop / "b.png")
    os.symlink("/dev/zero", shop / "c.png")
    items = {it.id: it.problem for it in discover(shop)}
    assert items["a.png"] is None
    assert "FIFO" in items["b.png"] and "character device" in items["c.png"]
    res = _run("batch", shop, "--out", tmp_path / "cat", "--workers", "1")
    assert res.exit_code == 0 and "2 failed" in res.output, res.output
    import pandas as pd

    rows = pd.read_parquet(tmp_path / "cat").set_index("id")["error"]
    assert "FIFO" in rows["b.png"] and "character device" in rows["c.png"] and pd.isna(rows["a.png"])


def test_a_batch_glob_names_its_fifo_in_an_error_row_as_a_folder_does(tmp_path, png):
    import os

    from tactilize.catalog.sources import discover

    shop = tmp_path / "shop"
    (shop / "sub").mkdir(parents=True)
    (shop / "a.png").write_bytes(png.read_bytes())
    os.mkfifo(shop / "b.png")
    pattern = str(shop / "*")  # matches the folder "sub" too, which lists nothing
    items = {it.id: it.problem for it in discover(pattern)}
    assert set(items) == {"a.png", "b.png"}
    assert items["a.png"] is None and "FIFO" in items["b.png"]
    assert items == {it.id: it.problem for it in discover(shop)}  # the same rows as the folder's
    res = _run("batch", pattern, "--out", tmp_path / "cat", "--workers", "1")
    assert res.exit_code == 0 and "1 failed" in res.output, res.output
    import pandas as pd

    rows = pd.read_parquet(tmp_path / "cat").set_index("id")["error"]
    assert "FIFO" in rows["b.png"] and pd.isna(rows["a.png"])
