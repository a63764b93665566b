"""The experiments package imports one way.

Its layers are an import-linter contract (the contract "experiments-layers" in pyproject.toml); its
modules import what they use at the top (only the command line, which every
``tactilize`` command imports, defers its work's modules); the design layer
needs no database and no web server; the names users meet ("protocol") stay.
"""

from __future__ import annotations

import ast
import pathlib
import subprocess
import sys

import pytest

import tactilize.experiments as experiments

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = pathlib.Path(experiments.__file__).parent
PYPROJECT = ROOT / "pyproject.toml"

#: Imports inside functions that stay there, and why.
DEFERRED_OK = {
    # every `tactilize` command imports the experiment CLI: each command imports what it runs
    "cli.py": None,
    # the pen app's server: patched by the tests where it is looked up, and optional in a build without it
    "web.py": {"..web.serve", "uvicorn"},
}
#: Third-party libraries too heavy to load before they are used.
HEAVY = ("pandas", "pingouin", "matplotlib", "scipy", "PIL", "dask", "pyarrow")


def _imports_inside_functions(path: pathlib.Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text("utf-8"))):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for inner in ast.walk(node):
                if isinstance(inner, ast.Import):
                    found |= {a.name for a in inner.names}
                elif isinstance(inner, ast.ImportFrom):
                    found.add("." * inner.level + (inner.module or ""))
    return found


def test_modules_import_at_the_top_but_heavy_libraries():
    late = {}
    for path in sorted(PACKAGE.glob("*.py")):
        allowed = DEFERRED_OK.get(path.name, set())
        if allowed is None:
            continue
        names = {n for n in _imports_inside_functions(path) if n.split(".")[0] not in HEAVY and n not in allowed}
        if names:
            late[path.name] = sorted(names)
    assert late == {}


def _loaded(module: str) -> set[str]:
    code = (f"import sys, {module}; print(','.join(m for m in ('numpy', 'sqlalchemy', 'fastapi', 'starlette', "
            "'pandas', 'matplotlib', 'pingouin') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    return set(filter(None, out.split(",")))


def test_the_package_stays_light_and_the_design_needs_no_database():
    assert _loaded("tactilize.experiments") == set()
    assert _loaded("tactilize.experiments.design_toml").isdisjoint({"sqlalchemy", "fastapi", "starlette", "pandas"})


def test_the_names_users_meet_still_work():
    from tactilize.experiments import design, design_toml, errors, protocols

    assert protocols.Protocol is design.Design is experiments.Protocol is experiments.Design
    assert protocols.ProtocolError is errors.DesignError is experiments.ProtocolError
    assert protocols.load_protocol is design_toml.load_design is experiments.load_protocol
    assert [d.name for d in protocols.builtin_protocols()] == design_toml.builtin_names()
    with pytest.raises(errors.DesignError, match="neither a built-in protocol"):
        protocols.load_protocol("no-such-protocol")


def _lint(tmp_path, config_text: str | None, *args: str) -> subprocess.CompletedProcess:
    if config_text is None:
        config = PYPROJECT
    else:
        config = tmp_path / "contract.ini"
        config.write_text(config_text)
    env_code = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"
    return subprocess.run([sys.executable, "-c", env_code, "--config", str(config), *args],
                          capture_output=True, text=True, cwd=ROOT)


def test_the_layers_contract_is_kept_and_fails_on_a_violation(tmp_path):
    kept = _lint(tmp_path, None, "--contract", "experiments-layers")
    assert kept.returncode == 0, kept.stdout + kept.stderr
    assert "1 kept, 0 broken" in kept.stdout
    # The flow imports the errors: a contract that puts the errors above the flow is broken.
    upside_down = _lint(tmp_path, "[importlinter]\nroot_package = tactilize\n\n[importlinter:contract:x]\n"
                                  "name = upside down\ntype = layers\nlayers =\n    tactilize.experiments.errors\n"
                                  "    tactilize.experiments.flow\n")
    assert upside_down.returncode == 1
    assert "tactilize.experiments.flow is not allowed to import" in upside_down.stdout.replace("\n", " ")
