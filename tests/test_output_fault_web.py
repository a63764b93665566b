"""The pen page hears when its output cannot be trusted (a faulty sense path, a
stopped simulation): every drive message carries ``output_fault``."""

from __future__ import annotations

import json

from fastapi.testclient import TestClient

from tactilize.web.app import create_app
from test_web import FakeOutput, hello, recv_type, stroke_rows


def test_drive_messages_carry_the_outputs_fault():
    out = FakeOutput()
    app = create_app(out, "paper", output_name="fake")
    with TestClient(app, base_url="http://127.0.0.1") as client:
        page = client.get("/").text
        assert 'data-testid="output-fault"' in page
        with client.websocket_connect("ws://127.0.0.1/ws") as ws:
            hello(ws)
            ws.send_text(json.dumps({"type": "samples", "batch": "0", "samples": stroke_rows(20.0)}))
            assert recv_type(ws, "drive")["output_fault"] is None
            out.fault = "sense fault on channel 0: the controller limits it with the circuit's worst case"
            ws.send_text(json.dumps({"type": "samples", "batch": "1", "samples": stroke_rows(20.0, t0=2000.0)}))
            assert recv_type(ws, "drive")["output_fault"] == out.fault
