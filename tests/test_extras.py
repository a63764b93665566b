"""Every command that needs an optional extra says which one, in one line, and exits 2.

Each optional module is hidden in turn from a ``tactilize`` subprocess (a
``sitecustomize`` on PYTHONPATH puts a finder in front of ``sys.meta_path`` that
refuses it, as if it were not installed) and every command that needs it is run.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tactilize.extras import EXTRAS, extra_for, missing, require
from tactilize.errors import MissingExtraError

ROOT = Path(__file__).resolve().parents[1]

HIDER = '''
import os, sys
_HIDE = set(filter(None, os.environ.get("TACTILIZE_TEST_HIDE", "").split(",")))
class _Hider:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in _HIDE:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None
if _HIDE:
    sys.meta_path.insert(0, _Hider())
'''

#: (command, the optional modules it needs, the extra it should name)
COMMANDS = [
    (["analyze", "{img}", "--plot", "{tmp}/fig.png"], ["matplotlib"], "plot"),
    (["simulate", "--frequency", "50", "--pulse-width-ms", "1", "--current-ma", "200", "--duration", "0.2",
      "--plot", "{tmp}/sim.png"], ["matplotlib"], "plot"),
    (["envelope", "--plot", "{tmp}/env.png"], ["matplotlib"], "plot"),
    (["profile", "report", "--image", "{img}", "--no-wire", "--plot", "{tmp}/rep.png"], ["matplotlib"], "plot"),
    (["drive", "{img}", "--speed", "30", "--output", "audio", "--hold", "0.1"], ["sounddevice"], "audio"),
    (["batch", "{imgs}", "--out", "{tmp}/cat.parquet", "--workers", "1"], ["pyarrow"], "batch"),
    (["batch", "{imgs}", "--out", "{tmp}/cat2.parquet", "--scheduler", "tcp://127.0.0.1:9"], ["distributed"], "batch"),
    (["experiment", "analyze", "--db", "{db}", "--include-simulated"], ["pandas", "pingouin"], "experiments"),
    (["experiment", "analyze", "--db", "{db}", "--include-simulated", "--figures", "{tmp}/figs"], ["matplotlib"],
     "experiments"),
    (["experiment", "export", "--db", "{db}", "--format", "parquet", "-o", "{tmp}/a.parquet"], ["pyarrow", "pandas"],
     "experiments"),
    (["experiment", "export", "--db", "{db}", "--format", "wide"], ["pandas"], "experiments"),
    (["experiment", "export", "--db", "{db}", "--format", "csv"], ["pandas"], "experiments"),
    (["experiment", "calibrate", "SIM-1-001", "--db", "{db}", "-o", "{tmp}/p.toml"], ["pandas"], "experiments"),
]
CASES = [(cmd, mod, extra) for cmd, mods, extra in COMMANDS for mod in mods]


@pytest.fixture(scope="module")
def where(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("extras")
    (tmp / "hide").mkdir()
    (tmp / "hide" / "sitecustomize.py").write_text(HIDER)
    imgs = tmp / "imgs"
    imgs.mkdir()
    x = np.arange(96)
    grating = (127 + 100 * np.sin(2 * np.pi * x / 12))[None, :].repeat(96, 0).astype(np.uint8)
    Image.fromarray(grating).save(imgs / "a.png")
    db = tmp / "exp.sqlite3"
    res = _tactilize(tmp, ["experiment", "simulate", "alpha-law", "--participants", "2", "--seed", "1", "--db", str(db)])
    assert res.returncode == 0, res.stderr
    return {"tmp": str(tmp), "imgs": str(imgs), "img": str(imgs / "a.png"), "db": str(db)}


def _tactilize(tmp, args, hide=()):
    env = dict(os.environ, TACTILIZE_TEST_HIDE=",".join(hide))
    # Absolute: the command runs in ``tmp`` (a relative "src" would find another tactilize).
    paths = [os.path.abspath(p) for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    env["PYTHONPATH"] = os.pathsep.join([str(Path(tmp) / "hide"), *paths])
    return subprocess.run([sys.executable, "-m", "tactilize.cli", *args], capture_output=True, text=True, env=env,
                          timeout=300, cwd=tmp)


@pytest.mark.parametrize("cmd,module,extra", CASES, ids=[f"{' '.join(c[:2])}-{m}" for c, m, _ in CASES])
def test_a_command_without_its_extra_says_which_to_install(where, cmd, module, extra):
    args = [a.format(**where) for a in cmd]
    res = _tactilize(where["tmp"], args, hide=[module])
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2, (res.returncode, res.stderr[-2000:])
    assert len(lines) == 1, res.stderr
    assert module in lines[0] and f"pip install 'tactilize[{extra}]'" in lines[0], lines[0]
    assert "Traceback" not in res.stderr and "internal error" not in res.stderr


@pytest.mark.parametrize("module", ["pandas", "pyarrow"])
def test_serve_with_a_parquet_catalog_without_its_extra_says_so_at_start(where, module):
    folder = Path(where["tmp"]) / "shop.parquet"
    folder.mkdir(exist_ok=True)
    (folder / "_catalog.json").write_text('{"settings": {}}')  # what `batch` writes first
    env = dict(os.environ, TACTILIZE_TEST_HIDE=module)
    paths = [os.path.abspath(p) for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    env["PYTHONPATH"] = os.pathsep.join([str(Path(where["tmp"]) / "hide"), *paths])
    proc = subprocess.Popen([sys.executable, "-m", "tactilize.cli", "serve", "--catalog", str(folder), "--port", "0",
                             "--no-open"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            cwd=where["tmp"])
    try:
        out, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # it started serving: the fault would be a 500 at the first request
        proc.kill()
        out, err = proc.communicate(timeout=30)
        pytest.fail(f"serve started without {module}: {out[-500:]}")
    lines = err.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, err
    assert module in lines[0] and "pip install 'tactilize[batch]'" in lines[0] and str(folder) in lines[0], lines[0]
    assert "serving" not in out


def test_the_hider_hides_only_what_it_is_told(where):
    # The same command with the module present gets past the import (the test above
    # would pass on any exit 2 otherwise).
    res = _tactilize(where["tmp"], ["experiment", "export", "--db", where["db"], "--format", "wide"], hide=["pyarrow"])
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("protocol,participant,")


def test_the_all_extra_holds_every_extra_but_test():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert extras["all"] == [f"tactilize[{','.join(sorted(set(extras) - {'all', 'test'}, key=list(extras).index))}]"]
    # tactilize.extras names the same extras as pyproject.toml (one table, checked against the other).
    assert set(EXTRAS) == set(extras) - {"all", "test"}
    for name, modules in EXTRAS.items():
        packages = " ".join(extras[name]).lower()
        for m in modules:
            # Two distributions import under another name: dask[distributed], scikit-image.
            assert m in packages or {"distributed": "dask[distributed]", "skimage": "scikit-image"}.get(m, m) in packages, (name, m)


def test_one_rule_for_the_message(monkeypatch):
    assert extra_for("pyarrow.parquet") == "experiments"
    assert extra_for("pyarrow", prefer="batch") == "batch"
    assert extra_for("numpy") is None
    err = missing("--out x.parquet", "pyarrow", "batch")
    assert isinstance(err, MissingExtraError)
    assert str(err) == "--out x.parquet: needs pyarrow, in the 'batch' extra (pip install 'tactilize[batch]')"
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if not installed
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)  # an earlier test may have imported it
    with pytest.raises(MissingExtraError, match=r"^--plot: needs matplotlib, in the 'plot' extra"):
        require("matplotlib.pyplot", "--plot", "plot")


def test_the_readme_lists_every_extra():
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("### Extras"):]
    for name in [*EXTRAS, "all", "test"]:
        assert f"| `{name}` |" in section, name
    assert "PortAudio" in section and "Chromium" in section
