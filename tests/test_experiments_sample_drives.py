"""The stroke log's drives: one computed per message for the page, every sample's logged exactly.

The socket answers each message with the drive of its latest sample; the
drives logged for the other samples are computed in the writer's thread
(tactilize.experiments.strokes, samples).  The log must hold exactly what
computing a drive for every sample on arrival would have given.
"""

from __future__ import annotations

import math
import sqlite3
import threading

import pytest

from tactilize.experiments.flow import Flow
from tactilize.experiments.protocols import load_protocol
from tactilize.experiments.samples import SampleWriter
from tactilize.experiments.store import Store
from tactilize.mapping.profile import Profile
from tactilize.pen import StrokeTracker
from tactilize.web.rows import samples_from_css


def _flow(tmp_path, name="alpha-law"):
    flow = Flow(load_protocol(name), Store(f"sqlite:///{tmp_path / 'drives.sqlite3'}"))
    token = flow.start("D1", True)["session"]
    state = flow.calibrate(token, {"mm_per_px": 0.25, "felt": True})
    return flow, token, state["trial"]


def _curve(n, start=0):
    """A stroke that speeds up, turns and presses harder: [t_ms, x_mm, y_mm, pressure]."""
    rows = []
    for k in range(start, start + n):
        a = 0.05 * k
        rows.append([k * 7.5, 10 + 0.02 * k * k * math.cos(a), 20 + 0.02 * k * k * math.sin(a),
                     min(1.0, 0.1 + 0.01 * k)])
    return rows


@pytest.mark.timeout(120)
def test_logged_drives_are_exactly_one_per_sample_computed_on_arrival(tmp_path):
    flow, token, trial = _flow(tmp_path)
    handler = flow.stroke_handler(token)
    images = [im["id"] for im in trial["images"]]
    batches = [(images[k % len(images)], _curve(4, start=4 * (k // len(images)))) for k in range(12)]
    replies = [handler.handle({"type": "samples", "trial": 0, "image": image, "batch": f"b{k}", "samples": rows})
               for k, (image, rows) in enumerate(batches)]
    assert all(r["type"] == "drive" and r["stored"] == "stored" for r in replies)

    # The reference: a drive for every sample, as the socket computed before.
    profile = flow.profile(flow.store.trials(flow.store.session_by_token(token).id)[0].condition_id)
    trackers = {image: StrokeTracker() for image in images}
    expected = []
    last = []
    for image, rows in batches:
        for ps in samples_from_css(rows, 1e-3):
            trackers[image].add(ps)
            st = trackers[image].state
            speed = st.speed_m_s if st else 0.0
            d = profile.drive(flow.image_features(image), speed_m_s=speed,
                              direction_rad=st.direction_rad if st else None, pressure=ps.pressure)
            expected.append((image, ps.t_s, ps.x_m, ps.y_m, ps.pressure, speed, d.pulse_frequency_hz,
                             d.pulse_width_s, d.amplitude))
        last.append(d.to_dict())
    with sqlite3.connect(tmp_path / "drives.sqlite3") as con:
        stored = con.execute("select image_id, t_s, x_m, y_m, pressure, speed_m_s, pulse_frequency_hz, "
                             "pulse_width_s, amplitude from stroke_samples order by id").fetchall()
    assert stored == expected  # equal floats, not close ones
    assert len({row[5] for row in stored}) > 10  # the speeds differ: each sample got its own drive
    assert [r["drive"] for r in replies] == last  # the page feels its latest sample's drive


def test_the_socket_computes_one_drive_per_message(tmp_path, monkeypatch):
    flow, token, trial = _flow(tmp_path)
    handler = flow.stroke_handler(token)
    on_socket = []
    original = Profile.drive

    def counted(self, *a, **kw):
        if threading.current_thread().name != SampleWriter.THREAD_NAME:
            on_socket.append(1)
        return original(self, *a, **kw)

    monkeypatch.setattr(Profile, "drive", counted)
    reply = handler.handle({"type": "samples", "trial": 0, "image": trial["images"][0]["id"], "batch": "b1", "samples": _curve(8)})
    assert reply["type"] == "drive" and reply["logged"] == 8 and reply["stored"] == "stored"
    assert len(on_socket) == 1


@pytest.mark.timeout(60)
def test_a_batch_whose_rows_cannot_be_made_fails_alone(tmp_path):
    flow, token, trial = _flow(tmp_path)
    sid = flow.store.session_by_token(token).id
    tid = flow.store.trials(sid)[0].id
    writer = SampleWriter(flow.store)
    row = {"image_id": "x", "t_s": 1.0, "x_m": 0.0, "y_m": 0.0, "pressure": None, "speed_m_s": 0.0,
           "pulse_frequency_hz": 1.0, "pulse_width_s": 1e-3, "amplitude": 1.0}

    def broken():
        raise ValueError("no drive")

    bad = writer.submit(sid, tid, "bad", broken)
    good = writer.submit(sid, tid, "good", lambda: [row])
    assert good.result(timeout=30) == "stored"
    assert isinstance(bad.exception(timeout=30), ValueError)
    assert writer.barrier(30)
    with sqlite3.connect(tmp_path / "drives.sqlite3") as con:
        assert con.execute("select batch_id, n_samples from stroke_batches").fetchall() == [("good", 1)]


def test_an_expired_open_trial_is_read_after_the_reply_not_before(tmp_path, monkeypatch):
    import tactilize.experiments.flow as flow_mod

    flow, token, trial = _flow(tmp_path)
    handler = flow.stroke_handler(token)
    msg = {"type": "samples", "trial": 0, "image": trial["images"][0]["id"], "batch": "b1", "samples": _curve(4)}
    assert handler.handle(msg)["stored"] == "stored"
    queries = []
    original = flow_mod.Flow._first_open

    def counted(self, *a, **kw):
        queries.append(1)
        return original(self, *a, **kw)

    monkeypatch.setattr(flow_mod.Flow, "_first_open", counted)
    monkeypatch.setattr(flow_mod, "OPEN_TRIAL_TTL_S", -1.0)  # every remembered value has expired
    reply, future = handler.take({**msg, "batch": "b2"})
    assert reply["type"] == "drive" and future.result(timeout=30) == "stored"
    assert queries == []  # the drive did not wait for the database
    assert flow.open_trial_due(handler.session)
    handler.refresh_open_trial()  # what the socket does once the reply is on its way
    assert queries == [1]
