"""A participant on the experiment's page, as the tests play one: a session, pen batches, replies."""

from __future__ import annotations

API = "/experiment/api"


def open_session(client, code="S1"):
    """A consented, calibrated session: (token, its first trial)."""
    token = client.post(f"{API}/sessions", json={"participant_id": code, "consent": True}).json()["session"]
    st = client.post(f"{API}/sessions/{token}/calibration", json={"mm_per_px": 0.25, "felt": True}).json()
    return token, st["trial"]


def pen_batch(trial, image, batch, start=0, n=5):
    """The page's batch ``batch`` of ``n`` samples, 8 ms apart from sample ``start`` on."""
    return {"type": "samples", "trial": trial, "image": image, "batch": batch,
            "samples": [[(start + k) * 8.0, 1.0 + (start + k) * 0.5, 3.0, 0.4] for k in range(n)]}


def until(ws, kind):
    """The messages up to and including the first of type ``kind`` (an error fails, unless asked for)."""
    seen = []
    while not seen or seen[-1]["type"] != kind:
        seen.append(ws.receive_json())
        assert seen[-1]["type"] != "error" or kind == "error", seen[-1]
    return seen
