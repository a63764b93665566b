"""Database passwords are never printed: every URL form, through every command that shows a URL."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import pytest
from click.testing import CliRunner

from tactilize.cli import main
from tactilize.redact import ambiguous_user, redact_text, redact_url

SECRET = "s3cr3tPW"

# (URL, what must still be readable): port 1 on loopback refuses at once.
FORMS = [
    (f"postgresql+psycopg://ana:{SECRET}@127.0.0.1:1/study", "127.0.0.1:1/study"),
    (f"postgresql+psycopg://ana@127.0.0.1:1/study?password={SECRET}", "127.0.0.1:1/study"),
    (f"postgresql+psycopg://ana@127.0.0.1:1/study?sslmode=disable&PassWord={SECRET}&x=1", "sslmode=disable"),
    (f"postgresql+psycopg://ana:{SECRET[:4]}@{SECRET[4:]}@127.0.0.1:1/study", "127.0.0.1:1/study"),
    (f"postgresql+psycopg://ana:{SECRET[:4]}%40{SECRET[4:]}@127.0.0.1:1/study", "127.0.0.1:1/study"),
    (f"postgre sql://ana:{SECRET}@127.0.0.1:1/study", "127.0.0.1:1/study"),  # unparsable
    (f"postgresql+psycopg://ana:{SECRET}@127.0.0.1:notaport/study", "study"),  # unparsable port
    (f"ana:{SECRET}@127.0.0.1:1/study", "127.0.0.1"),  # the scheme forgotten
]


def _hidden(text: str) -> bool:
    """No piece of the secret (whole, either half around an '@') is in ``text``."""
    return SECRET not in text and SECRET[:4] + "@" not in text and "@" + SECRET[4:] not in text \
        and SECRET[4:] + "@" not in text and "%40" + SECRET[4:] not in text


@pytest.mark.parametrize("url, kept", FORMS)
def test_redact_url_hides_every_password_form(url, kept):
    out = redact_url(url)
    assert _hidden(out), out
    assert "***" in out and kept in out


def test_redact_url_leaves_urls_without_secrets_alone():
    for url in ["sqlite:////tmp/a@b.sqlite3", "/home/me/study.sqlite3", "postgresql://ana@db.lab/study",
                "postgresql://db.lab:5433/study?sslmode=require"]:
        assert redact_url(url) == url
    assert redact_url(None) == ""


def test_redact_text_masks_the_url_and_pieces_of_the_password_a_driver_quotes():
    url = f"postgresql://ana:{SECRET[:4]}@{SECRET[4:]}@db.lab/study"
    msg = f"failed to resolve host '{SECRET[4:]}@db.lab' for {url}"
    out = redact_text(msg, url)
    assert SECRET[4:] not in out and SECRET not in out and "db.lab" in out
    assert redact_text("plain failure", None) == "plain failure"


def test_an_unescaped_at_in_the_password_is_refused_before_connecting():
    assert ambiguous_user(f"postgresql://ana:{SECRET[:4]}@{SECRET[4:]}@127.0.0.1/study")
    assert not ambiguous_user(f"postgresql://ana:{SECRET[:4]}%40{SECRET[4:]}@127.0.0.1/study")
    assert not ambiguous_user("postgresql://ana@127.0.0.1/study?password=a@b")
    assert not ambiguous_user("sqlite:////tmp/a@b@c.sqlite3")


def _cli(*args):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


@pytest.mark.parametrize("url, _kept", FORMS)
@pytest.mark.parametrize("command", [
    ("experiment", "status", "--db"),
    ("experiment", "simulate", "alpha-law", "--participants", "1", "--seed", "1", "--db"),
    ("experiment", "run", "alpha-law", "--port", "0", "--db"),
])
def test_a_connection_failure_prints_one_line_without_the_password(command, url, _kept):
    r = _cli(*command, url)
    assert r.exit_code == 2, r.output
    assert r.output.count("\n") == 1 and _hidden(r.output), r.output


@pytest.mark.parametrize("url, _kept", FORMS[:5])
def test_batch_into_an_unreachable_database_hides_the_password(tmp_path, url, _kept):
    import numpy as np
    from PIL import Image

    Image.fromarray((np.arange(64 * 64) % 251).astype("uint8").reshape(64, 64)).save(tmp_path / "a.png")
    r = _cli("batch", str(tmp_path / "a.png"), "--out", url, "--workers", "1")
    assert r.exit_code == 2 and _hidden(r.output), r.output


def _sqlite_with_password(tmp_path) -> str:
    # SQLite ignores the query (with a warning): a stand-in for a server URL that works.
    return f"sqlite:///{tmp_path / 'study.sqlite3'}?password={SECRET}"


def test_status_and_exports_of_a_working_database_hide_the_query_password(tmp_path):
    url = _sqlite_with_password(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert _cli("experiment", "simulate", "alpha-law", "--participants", "1", "--seed", "2", "--db", url).exit_code == 0
        status = _cli("experiment", "status", "--db", url, "--json")
        assert status.exit_code == 0 and _hidden(status.output)
        assert json.loads(status.output)["db"].endswith("?password=***")
        for extra in ([], ["--strokes"]):
            r = _cli("experiment", "export", "--db", url, "--format", "json", *extra)
            assert r.exit_code == 0 and _hidden(r.output)
            assert json.loads(r.output)["provenance"]["db"].endswith("?password=***")
        analysis = _cli("experiment", "analyze", "--db", url, "--include-simulated", "--json")
        assert analysis.exit_code == 0 and _hidden(analysis.output)
        empty = _cli("experiment", "analyze", "--db", url, "--json")  # no real participants: an error line
        assert empty.exit_code == 2 and _hidden(empty.output)


def test_the_start_up_line_of_experiment_run_hides_the_query_password(tmp_path):
    url = _sqlite_with_password(tmp_path)
    proc = subprocess.Popen([sys.executable, "-W", "ignore", "-m", "tactilize.cli", "experiment", "run", "alpha-law",
                             "--port", "0", "--db", url], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    try:
        for line in proc.stdout:
            lines.append(line)
            if "participant" in line and "http://" in line:
                break
    finally:
        proc.kill()
        proc.wait(timeout=10)
    text = "".join(lines)
    assert "database sqlite:///" in text and "?password=***" in text, text
    assert _hidden(text), text
