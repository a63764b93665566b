"""``tactilize serve`` from outside: the loopback rule, binding, the CLI's address, warnings and bad input."""

from __future__ import annotations

import re
import socket
import subprocess
import sys

from tactilize.web.serve import bind_socket, is_loopback


def test_is_loopback():
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1") and is_loopback("127.5.0.1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5") and not is_loopback("example.org")


def test_one_loopback_rule_for_the_pen_and_the_experiments():
    from tactilize.experiments import web as experiments_web

    assert experiments_web.is_loopback is is_loopback
    # The cases the two copies disagreed on.  The empty host binds every
    # interface (experiments/web.py called it loopback, so a server bound there
    # got no experimenter token); other names than localhost may resolve anywhere.
    assert not is_loopback("")
    assert not is_loopback("localhost.localdomain") and not is_loopback("ip6-localhost")
    assert is_loopback("[::1]") and not is_loopback("::") and not is_loopback("[::]")


def _serve(*args):
    return subprocess.Popen(
        [sys.executable, "-m", "tactilize.cli", "serve", "--no-open", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_cli_serve_prints_address_on_loopback():
    import httpx

    proc = _serve("--port", "0")
    try:
        line = proc.stdout.readline()
        m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert m, line
        r = httpx.get(m.group(0) + "api/config", timeout=10)
        # the pen's default is the surface rendering; the presets are one click away
        assert r.status_code == 200 and r.json()["profile"] == "surface"
        profiles = httpx.get(m.group(0) + "api/profiles", timeout=10).json()
        assert profiles["default"] == "surface"
        assert {"paper", "physical", "perceptual", "surface"} <= {p["name"] for p in profiles["profiles"]}
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
    assert "reachable from other machines" not in err


def test_cli_serve_warns_when_asked_for_all_interfaces():
    proc = _serve("--host", "0.0.0.0", "--port", "0")
    try:
        line = proc.stdout.readline()
        assert "serving" in line
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
    assert "warning" in err and "0.0.0.0" in err


def test_cli_serve_bad_input_is_one_line_exit_2():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    try:
        r = subprocess.run(
            [sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", str(s.getsockname()[1])],
            capture_output=True,
            text=True,
            timeout=60,
        )
    finally:
        s.close()
    assert r.returncode == 2 and "cannot listen" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = subprocess.run(
        [sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--profile", "nope"], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 2 and "nope" in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run(
        [sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", "0", "--output", "teleport"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and "teleport" in r.stderr


def test_accepted_connections_have_no_nagle_delay():
    # A drive written right after a wire trace must not wait for the client's
    # delayed ACK (about 40 ms): the server's connections carry TCP_NODELAY.
    listener = bind_socket("127.0.0.1", 0)
    try:
        client = socket.create_connection(listener.getsockname()[:2], timeout=5)
        conn, _ = listener.accept()
        try:
            assert conn.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0
        finally:
            conn.close()
            client.close()
    finally:
        listener.close()
