"""``tactilize serve --lan`` and ``--https``: the address chosen, the QR code printed, the certificate made.

Everything reaches the server through loopback only: the LAN address is chosen
by a function tested on given addresses, and the printing is tested with the
server's run replaced.
"""

from __future__ import annotations

import os
import re
import ssl
import stat
import subprocess
import sys

import pytest

from tactilize.errors import TactilizeError
from tactilize.web import lan
from tactilize.web.serve import DEFAULT_PROFILE
from tactilize.web.lan import choose_lan_address, context_notes, lan_host, page_url, qr_text
from tactilize.web.tls import certificate_for, certificate_names


def test_the_address_a_phone_can_reach_is_chosen():
    # A private address over a public one, and never loopback, link-local or "any".
    assert choose_lan_address(["127.0.0.1", "169.254.3.4", "0.0.0.0", "8.8.4.4", "192.168.1.20"]) == "192.168.1.20"
    assert choose_lan_address(["127.0.0.1", "::1", "fe80::1", "203.0.113.300", "8.8.4.4"]) == "8.8.4.4"
    assert choose_lan_address(["127.0.0.1", "::1", "not an address"]) is None
    assert choose_lan_address(["10.0.0.7", "172.16.0.2"]) == "10.0.0.7"  # the route's order is kept


def test_lan_host_refuses_loopback_and_a_machine_without_a_network(monkeypatch):
    with pytest.raises(TactilizeError, match="--host 127.0.0.1"):
        lan_host("127.0.0.1")
    assert lan_host("192.168.4.2") == "192.168.4.2"
    monkeypatch.setattr(lan, "lan_addresses", lambda: ["127.0.0.1"])
    with pytest.raises(TactilizeError, match="--lan"):
        lan_host(None)
    monkeypatch.setattr(lan, "lan_addresses", lambda: ["127.0.0.1", "10.1.2.3"])
    assert lan_host("0.0.0.0") == "10.1.2.3"


def _modules(text: str) -> list[list[bool]]:
    """The QR's modules back from the terminal text (True = dark), two rows per line."""
    upper = {"█": (False, False), "▀": (False, True), "▄": (True, False), " ": (True, True)}
    rows: list[list[bool]] = []
    for line in text.rstrip("\n").split("\n"):
        pairs = [upper[ch] for ch in line]
        rows.append([p[0] for p in pairs])
        rows.append([p[1] for p in pairs])
    return rows


def test_the_qr_code_printed_is_the_url():
    import segno

    url = page_url("192.168.1.20", 8765)
    assert url == "http://192.168.1.20:8765/" and page_url("fd00::5", 443, secure=True) == "https://[fd00::5]:443/"
    text = qr_text(url)
    qr = segno.make(url, error="l", micro=False)
    want = [[bool(v) for v in row] for row in qr.matrix]
    got = _modules(text)
    border = 2
    n = len(want)
    inner = [row[border:border + n] for row in got[border:border + n]]
    assert inner == want
    # The quiet zone is light all round.
    assert not any(got[0]) and not any(row[0] for row in got[: border + n])
    # Another URL draws another code.
    assert _modules(qr_text(page_url("192.168.1.21", 8765))) != got


def test_what_works_over_http_and_https_is_said():
    plain = " ".join(context_notes(secure=False))
    assert "touch" in plain and "vibration" in plain and "AudioWorklet" in plain and "--https" in plain
    secure = " ".join(context_notes(secure=True))
    assert "need" not in secure and "audio output" in secure and "certificate" in secure


def test_the_certificate_names_the_hosts_and_is_reused(tmp_path):
    cert, key = certificate_for(["192.168.1.20"], tmp_path)
    assert {"192.168.1.20", "127.0.0.1", "::1", "localhost"} <= certificate_names(cert)
    assert stat.S_IMODE(os.stat(key).st_mode) == 0o600
    first = cert.read_bytes()
    assert certificate_for(["192.168.1.20"], tmp_path)[0].read_bytes() == first  # no new warning at every start
    # A new address: a new certificate that still names the old one.
    cert2, _ = certificate_for(["10.0.0.9"], tmp_path)
    assert cert2.read_bytes() != first
    assert {"10.0.0.9", "192.168.1.20"} <= certificate_names(cert2)
    # A corrupt file is replaced, not a crash.
    cert2.write_text("not a certificate")
    assert "10.0.0.9" not in certificate_names(certificate_for([], tmp_path)[0])


def test_a_key_regenerated_over_a_readable_key_file_is_owner_only(tmp_path):
    cert, key = certificate_for([], tmp_path)
    old_key = key.read_bytes()
    os.chmod(key, 0o644)  # as an older version, a copy or an umask may have left it
    cert.write_text("not a certificate")  # forces a new certificate and key
    _, key2 = certificate_for(["10.0.0.9"], tmp_path)
    assert key2 == key and key2.read_bytes() != old_key
    assert stat.S_IMODE(os.stat(key2).st_mode) == 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([cert.name, key.name])  # no temporary file left


def test_serve_lan_prints_the_address_a_qr_and_what_works(monkeypatch):
    import uvicorn

    from tactilize.web import serve as serve_mod

    # Bound on loopback here (tests reach the server through loopback only);
    # what is printed and passed on is what a LAN address would get.
    monkeypatch.setattr(lan, "lan_host", lambda given=None: "127.0.0.1")
    seen = {}

    def fake_run(self, sockets=None):
        seen["host"], seen["port"] = self.config.host, self.config.port
        seen["sock"] = sockets[0].getsockname()[:2]

    monkeypatch.setattr(uvicorn.Server, "run", fake_run)
    lines: list[str] = []
    serve_mod.serve("127.0.0.1", 0, open_browser=False, echo=lines.append, warn=lines.append, lan=True)
    url = page_url(*seen["sock"])
    assert (seen["host"], seen["port"]) == seen["sock"]  # the server knows the address it is reached at
    assert any(url in line and "phone" in line for line in lines)
    assert qr_text(url) in lines


def test_serve_https_on_loopback_with_the_generated_certificate(tmp_path):
    import httpx

    env = dict(os.environ, XDG_DATA_HOME=str(tmp_path))
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--https", "--port", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    try:
        line = proc.stdout.readline()
        m = re.search(r"https://127\.0\.0\.1:(\d+)/", line)
        assert m, (line, proc.stderr.read() if proc.poll() is not None else "")
        cert = tmp_path / "tactilize" / "tls" / "serve-cert.pem"
        assert cert.exists()
        ctx = ssl.create_default_context(cafile=str(cert))
        r = httpx.get(m.group(0) + "api/config", verify=ctx, timeout=10)
        assert r.status_code == 200 and r.json()["profile"] == DEFAULT_PROFILE
        # Without the certificate the client refuses, as a browser warns.
        with pytest.raises(httpx.ConnectError):
            httpx.get(m.group(0) + "api/config", timeout=10)
        notes = proc.stdout.readline()
        assert "self-signed" in notes and "docs/serve.md" in notes
    finally:
        proc.terminate()
        proc.communicate(timeout=10)


def test_cli_lan_with_an_unreachable_host_is_one_line():
    bad = subprocess.run(
        [sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--lan", "--host", "169.254.1.1", "--port", "0"],
        capture_output=True, text=True, timeout=60,
    )
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and "--host 169.254.1.1" in bad.stderr
