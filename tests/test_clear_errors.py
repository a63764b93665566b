"""Clear errors: one line and exit 2, or a 4xx that says what is wrong,
where there was exit 1, a 500 or a traceback (docs/safety.md, "Clear errors")."""

from __future__ import annotations

import errno
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

CLI = [sys.executable, "-m", "tactilize.cli"]


def _run(*args, **kw):
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=300, **kw)


def _one_line_exit_2(r, *words):
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def pictures(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("pictures")
    rng = np.random.default_rng(1)
    x = np.arange(320)[None, :]
    for i in range(40):
        a = (127 + 80 * np.sin(x / (3 + i % 7)) + 20 * rng.standard_normal((240, 320))).clip(0, 255)
        Image.fromarray(a.astype("uint8")).save(root / f"p{i:03d}.png")
    return root


# ------------------------------------------------------------------ analyze


@pytest.mark.parametrize("option", [("--width-mm", "1e-300"), ("--dpi", "1e300"), ("--width-mm", "1e300")])
def test_analyze_with_an_absurd_pixel_size_is_one_line(pictures, option):
    _one_line_exit_2(_run("analyze", str(pictures / "p000.png"), *option), "p000.png", "pixel")


def test_a_symlink_loop_is_not_called_a_missing_file(tmp_path):
    loop = tmp_path / "loop.png"
    loop.symlink_to(loop)
    dangling = tmp_path / "dangling.png"
    dangling.symlink_to(tmp_path / "gone.png")
    assert "symbolic link loop" in _one_line_exit_2(_run("analyze", str(loop)), "loop.png")
    assert "broken symbolic link" in _one_line_exit_2(_run("analyze", str(dangling)), "dangling.png")
    assert "symbolic link loop" in _one_line_exit_2(_run("batch", str(loop), "--out", str(tmp_path / "o.parquet")))
    assert "file not found" in _one_line_exit_2(_run("analyze", str(tmp_path / "nothing.png")))


# ------------------------------------------------------------------ batch


def test_batch_into_an_unwritable_place_is_one_line(pictures, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    _one_line_exit_2(_run("batch", str(pictures), "--out", str(blocker / "shop.parquet"), "--workers", "1"),
                     "shop.parquet", "cannot write")


def test_batch_on_a_full_disk_is_one_line(pictures, tmp_path, monkeypatch):
    from click.testing import CliRunner

    import pyarrow.parquet as pq

    from tactilize.cli import main

    def full(table, where, *a, **kw):  # the disk fills up while a part is written
        Path(where).write_bytes(b"PAR1 half a part")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(pq, "write_table", full)
    out = tmp_path / "full.parquet"
    r = CliRunner().invoke(main, ["batch", str(pictures), "--out", str(out), "--workers", "1"])
    assert r.exit_code == 2, (r.output, r.exception)
    lines = [ln for ln in r.output.splitlines() if ln.startswith("tactilize:")]
    assert len(lines) == 1 and "No space left on device" in lines[0] and "rerun" in lines[0], r.output
    assert "full.parquet" in lines[0]
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]  # no half-written part is left behind


def test_batch_workers_end_with_a_killed_parent(pictures, tmp_path):
    psutil = pytest.importorskip("psutil")
    proc = subprocess.Popen([*CLI, "batch", str(pictures), "--out", str(tmp_path / "k.parquet"), "--workers", "2"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    parent = psutil.Process(proc.pid)
    try:
        for _ in range(600):  # the pool's two workers start
            if len(parent.children()) >= 2:
                break
            time.sleep(0.1)
        workers = parent.children()
        assert len(workers) >= 2
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    _, alive = psutil.wait_procs(workers, timeout=60)
    for p in alive:
        p.kill()
    assert alive == []


CLUSTER = """
import sys, time, distributed
if __name__ == "__main__":
    c = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://",
                                 host="127.0.0.1", dashboard_address=None)
    print(c.scheduler_address, flush=True)
    while not c.scheduler.tasks:
        time.sleep(0.01)
    print("busy", flush=True)
    time.sleep(600)
"""


def test_a_lost_dask_scheduler_is_one_line(pictures, tmp_path):
    pytest.importorskip("distributed")
    cluster = subprocess.Popen([sys.executable, "-c", CLUSTER], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                               text=True)
    try:
        address = cluster.stdout.readline().strip()
        assert address.startswith("tcp://")
        batch = subprocess.Popen([*CLI, "batch", str(pictures), "--out", str(tmp_path / "d.parquet"), "--scheduler",
                                  address], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert cluster.stdout.readline().strip() == "busy"  # the batch's tasks reached the scheduler
        cluster.kill()
        _, err = batch.communicate(timeout=300)
    finally:
        cluster.kill()
        cluster.wait()
    lines = err.strip().splitlines()
    assert batch.returncode == 2 and len(lines) == 1, err
    assert "lost the Dask scheduler" in lines[0] and "rerun" in lines[0]


# ------------------------------------------------------------------ the experiment and the sockets


def test_a_protocol_query_on_a_single_protocol_experiment_is_a_404_not_a_500(tmp_path):
    from fastapi.testclient import TestClient

    from tactilize.experiments.web import create_experiment_app

    app = create_experiment_app("alpha-law", str(tmp_path / "x.db"))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        image = app.state.experiment_flow.design.images[0].id
        api = "/experiment/api/images"
        assert c.get(f"{api}/{image}.png").status_code == 200
        assert c.get(f"{api}/{image}.png?protocol=alpha-law").status_code == 200
        r = c.get(f"{api}/{image}.png?protocol=g-law")
        assert r.status_code == 404 and "g-law" in r.json()["error"]


def test_closing_pen_pages_logs_nothing_and_prints_no_traceback():
    from websockets.sync.client import connect

    proc = subprocess.Popen([*CLI, "serve", "--no-open", "--port", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        port = re.search(r"127\.0\.0\.1:(\d+)/", proc.stdout.readline()).group(1)
        for k in range(8):
            with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=60) as ws:
                ws.send(json.dumps({"type": "hello", "texture": "corduroy"}))
                for j in range(200):  # drives and wire traces are on their way when the page goes
                    rows = [[1000 + 100 * j + 5 * i, 5 + 0.5 * i, 8, 0.5] for i in range(20)]
                    ws.send(json.dumps({"type": "samples", "batch": str(j), "samples": rows}))
                if k % 2:  # abrupt: the connection drops without a close frame
                    ws.socket.shutdown(socket.SHUT_RDWR)
        with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=60) as ws:  # the server still answers
            ws.send(json.dumps({"type": "ping", "id": 1}))
            assert '"pong"' in ws.recv(timeout=60)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=60)
    assert "Traceback" not in err and "Cannot call" not in err and "pen session ended" not in err, err
