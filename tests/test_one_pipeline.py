"""One rendering, one pipeline: every preset through every output kind by the same call
(``Output.play``), and through every export format from one events timeline."""

from __future__ import annotations

import numpy as np
import pytest

from tactilize.actuators.audio import AudioOutput
from tactilize.actuators.recording import RecordingOutput
from tactilize.actuators.simulated import SimulatedOutput
from tactilize.data import get_texture
from tactilize.export import FORMATS, parse_stroke, render, run_stroke
from tactilize.export.events import timeline_events
from tactilize.mapping import Profile
from tactilize.maps.texturemap import texture_map
from tactilize.pen import PenRenderer, PenSample
from tactilize.surface import surface_model

from test_audio import FakeStream, Identity, fake_sd  # noqa: F401  (the fake sound device)

PRESETS = ("paper", "physical", "perceptual", "surface")


@pytest.fixture(scope="module")
def picture():
    img = get_texture("corduroy").image
    return texture_map(img), surface_model(img)


def _samples(tmap, speed_m_s=0.04, rate_hz=240.0, n=240):
    y = tmap.height_m / 2
    return [PenSample(k / rate_hz, 1e-3 + speed_m_s * k / rate_hz, y, 0.5) for k in range(n)]


class _Played(RecordingOutput):
    """A recording output that also counts the frames it was handed through ``play``."""

    def __init__(self) -> None:
        super().__init__()
        self.frames = 0

    def play(self, frame, now_s, channels):
        self.frames += 1
        return super().play(frame, now_s, channels)


@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_plays_on_every_output_kind_through_play(preset, picture, fake_sd):  # noqa: F811
    tmap, sm = picture
    prof = Profile.preset(preset)
    outputs = {"recording": _Played(), "simulated": SimulatedOutput(start=False),
               "audio": AudioOutput(sample_rate_hz=48_000.0, envelope=Identity())}
    for kind, out in outputs.items():
        r = PenRenderer(tmap, prof, out, surface=sm)
        samples = _samples(tmap)
        on, sound = 0, 0.0
        for k in range(0, len(samples), 4):
            res = r.feed(samples[k:k + 4])
            on += res.on
            # every frame carries events (a steady rendering's are its drive's regular train)
            assert res.regular == (prof.rendering != "surface") or not res.events
            if kind == "simulated":
                out.advance(4 / 240.0)
            if kind == "audio":  # the device plays as the batches come
                sound = max(sound, float(np.abs(FakeStream.instances[-1].pull(200)).max()))
        assert on > 0, (preset, kind)
        if kind == "recording":
            assert out.frames > 0
        if kind == "audio":
            assert sound > 0.0, preset
        if kind == "simulated":
            assert any(ch["fired"] for ch in out.event_counts()) or out.pulse_log(0), preset
        r.lift()
        out.close()


@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_exports_every_format_from_one_events_timeline(preset, picture):
    tmap, sm = picture
    rows = [[k / 240, (1e-3 + 0.04 * k / 240) * 1e3, tmap.height_m / 2 * 1e3, 0.5] for k in range(240)]
    stroke = parse_stroke(rows, "<test>", tmap.width_m, tmap.height_m)
    tl = run_stroke(stroke, tmap, Profile.preset(preset), surface=sm)
    assert len(timeline_events(tl)) > 0, preset
    for fmt in FORMATS:
        assert len(render(tl, fmt)) > 0, (preset, fmt)
