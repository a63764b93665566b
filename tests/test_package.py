"""Packaging: the public API resolves, and importing the package stays light."""

from __future__ import annotations

import subprocess
import sys

import tactilize as tz


def test_import_does_not_load_heavy_modules():
    code = (
        "import sys, tactilize; "
        "heavy = [m for m in ('numpy', 'scipy', 'PIL', 'fastapi', 'sqlalchemy', 'matplotlib', 'pandas', 'dask') "
        "if m in sys.modules]; print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == ""


def test_every_public_name_resolves():
    for name in tz.__all__:
        assert getattr(tz, name) is not None, name


def test_unknown_attribute_is_an_attribute_error():
    try:
        tz.no_such_thing  # noqa: B018
    except AttributeError as exc:
        assert "no_such_thing" in str(exc)
    else:
        raise AssertionError("expected AttributeError")


def test_no_module_is_over_600_lines():
    import pathlib

    import tactilize

    root = pathlib.Path(tactilize.__file__).parent
    long = {str(p.relative_to(root)): n for p in root.rglob("*.py") if (n := len(p.read_text("utf-8").splitlines())) > 600}
    assert not long, long


def test_drive_is_a_plain_value_the_wire_needs_no_profile_for():
    import subprocess
    import sys

    # The wire physics imports the value, not the laws and profiles.
    code = "import sys, tactilize.actuators.sma; print('tactilize.mapping' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
