"""The page's "Export this stroke" as WAV is the CLI's `export --stroke` WAV: the tip's acceleration."""

from __future__ import annotations

import io
import subprocess
import sys
import wave

import numpy as np
from fastapi.testclient import TestClient
from PIL import Image

from tactilize.actuators.recording import RecordingOutput
from tactilize.export import parse_stroke, stroke_csv
from tactilize.web import create_app

WIDTH_MM = 64.0  # 256 px: 0.25 mm a pixel, a 1 mm grating


def _png() -> bytes:
    row = 0.5 + 0.5 * np.cos(2 * np.pi * np.arange(256) / 4)
    buf = io.BytesIO()
    Image.fromarray(np.tile(np.round(row * 255).astype(np.uint8), (128, 1))).save(buf, format="PNG")
    return buf.getvalue()


def _frames(data: bytes) -> np.ndarray:
    with wave.open(io.BytesIO(data)) as w:
        return np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").reshape(-1, w.getnchannels())


def test_the_pages_wav_of_a_recorded_stroke_is_the_clis(tmp_path):
    """Same picture, stroke and profile (surface): the route's bytes equal `tactilize export --stroke`'s.
    Before, the page wrote the pulse train (unsigned, never below the midpoint) and the CLI the acceleration."""
    png = _png()
    t = np.arange(0.0, 0.6, 1 / 240)
    # At the CSV's precision (us, 0.1 um), so both read the very same samples.
    rows = [[round(float(a), 6), round(6.0 + 50.0 * float(a), 4), 16.0, 0.5] for a in t]
    (tmp_path / "g.png").write_bytes(png)
    (tmp_path / "s.csv").write_bytes(stroke_csv(parse_stroke(rows, "<t>")))
    out = tmp_path / "cli.wav"
    r = subprocess.run([sys.executable, "-m", "tactilize.cli", "export", str(tmp_path / "g.png"), "--stroke",
                        str(tmp_path / "s.csv"), "--format", "wav", "--width-mm", str(WIDTH_MM), "--profile",
                        "surface", "-o", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    with TestClient(create_app(RecordingOutput(), "surface", output_name="recorder", warm=False),
                    base_url="http://127.0.0.1") as client:
        up = client.post("/api/textures", files={"file": ("g.png", png, "image/png")}, data={"width_mm": str(WIDTH_MM)})
        assert up.status_code == 201, up.text
        page = client.post("/api/export/stroke", json={"texture": up.json()["id"], "format": "wav", "samples": rows,
                                                       "profile": "surface"})
        assert page.status_code == 200, page.text
    x = _frames(page.content)
    assert x.min() < -300 and x.max() > 300  # signed around zero: an acceleration
    np.testing.assert_array_equal(x, _frames(out.read_bytes()))
    assert page.content == out.read_bytes()
