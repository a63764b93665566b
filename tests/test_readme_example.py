"""The README's library example runs as written (on a generated picture saved as cloth.jpg)."""

from __future__ import annotations

import re
from pathlib import Path

from PIL import Image

import numpy as np

from tactilize.data import get_texture

ROOT = Path(__file__).resolve().parents[1]


def _example() -> str:
    text = (ROOT / "README.md").read_text("utf-8")
    library = text[text.index("## The library"):]
    return re.search(r"```python\n(.*?)```", library, re.S).group(1)


def test_the_library_example_runs_as_written(tmp_path, monkeypatch):
    pixels = get_texture("corduroy").image.pixels
    Image.fromarray(np.round(pixels * 255).astype(np.uint8)).save(tmp_path / "cloth.jpg", quality=95)
    monkeypatch.chdir(tmp_path)
    names: dict = {}
    exec(compile(_example(), "README.md", "exec"), names)  # noqa: S102
    assert "from tactilize import surface" in _example()
    assert names["events"] and names["stats"].pulses == len(names["events"])
    assert names["steady"].pulse_frequency_hz > 0 and names["wave"].size > 0
