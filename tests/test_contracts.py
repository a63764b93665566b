"""The import contracts (pyproject.toml, [tool.importlinter]) hold, and fail on a violation.

Each violation is written into a copy of the package, never into the tree under test,
and import-linter is run on the copy with the project's own configuration.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "tactilize"

# import-linter's own entry point, run in a child so each run builds its graph afresh.
_LINT = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"


def _lint(src_root: Path, *contract_ids: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(src_root)}
    args = [sys.executable, "-c", _LINT, "--config", str(ROOT / "pyproject.toml"), "--no-cache"]
    for cid in contract_ids:
        args += ["--contract", cid]
    return subprocess.run(args, cwd=src_root, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def copy_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("contracts")
    shutil.copytree(SRC, root / "tactilize", ignore=shutil.ignore_patterns("__pycache__", "static", "*.toml"))
    return root


def _with_line(root: Path, relative: str, line: str) -> Path:
    """A copy of ``root``'s package with ``line`` appended to ``relative``."""
    target = root.parent / f"{root.name}-{relative.replace('/', '_')}"
    if target.exists():
        shutil.rmtree(target)
    shutil.copytree(root, target)
    path = target / "tactilize" / relative
    before = path.read_text() if path.exists() else ""
    path.write_text(before + "\n" + line + "\n")
    return target


def test_the_tree_keeps_every_contract():
    done = _lint(ROOT / "src")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "0 broken" in done.stdout


def test_the_copy_keeps_them_too(copy_root: Path):
    # The violations below are the only difference from a copy that passes.
    done = _lint(copy_root, "layers", "actuators-no-mapping", "firmware-stands-alone")
    assert done.returncode == 0, done.stdout + done.stderr


def test_an_actuator_importing_a_profile_breaks_its_contract(copy_root: Path):
    bad = _with_line(copy_root, "actuators/base.py", "from ..mapping import Profile  # noqa")
    done = _lint(bad, "actuators-no-mapping")
    assert done.returncode != 0
    assert "BROKEN" in done.stdout and "tactilize.actuators.base -> tactilize.mapping" in done.stdout


def test_an_upward_import_breaks_the_layers(copy_root: Path):
    # the laws reaching up into the pen loop: against the flow
    bad = _with_line(copy_root, "mapping/laws.py", "from ..pen import tracker  # noqa")
    done = _lint(bad, "layers")
    assert done.returncode != 0
    assert "tactilize.mapping.laws -> tactilize.pen" in done.stdout


def test_a_module_without_a_layer_breaks_the_layers(copy_root: Path):
    bad = _with_line(copy_root, "loose.py", "x = 1")
    done = _lint(bad, "layers")
    assert done.returncode != 0
    assert "tactilize.loose" in done.stdout


def test_a_circle_between_siblings_breaks_acyclic(copy_root: Path):
    # what actuators/sma/felt.py and actuators/simulated.py once were
    bad = _with_line(copy_root, "actuators/sma/wire.py", "from ..felt import feel  # noqa")
    done = _lint(bad, "acyclic")
    assert done.returncode != 0
    assert "BROKEN" in done.stdout


def test_the_board_importing_the_library_breaks_firmware_stands_alone(copy_root: Path):
    # what firmware/board.py once did (the wire model lives on the host only)
    bad = _with_line(copy_root, "firmware/tactile_heat.py", "from tactilize.actuators import sma  # noqa")
    done = _lint(bad, "firmware-stands-alone")
    assert done.returncode != 0
    assert "tactilize.firmware.tactile_heat -> tactilize.actuators" in done.stdout


def test_a_host_only_module_on_the_board_breaks_firmware_stands_alone(copy_root: Path):
    # MicroPython has no typing: a hint imported for mypy would fail only on the board
    bad = _with_line(copy_root, "firmware/tactile_frames.py", "from typing import Any  # noqa")
    done = _lint(bad, "firmware-stands-alone")
    assert done.returncode != 0
    assert "tactilize.firmware.tactile_frames -> typing" in done.stdout


def test_ci_checks_contracts_and_types_before_the_tests():
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    tests_at = next(i for i, line in enumerate(lines) if line.startswith('bash -euo pipefail -c "$cmd"'))
    assert lines.index("lint-imports") < tests_at and lines.index("mypy") < tests_at
    # `set -e` stops the run on the first failing check
    assert "set -euo pipefail" in lines
