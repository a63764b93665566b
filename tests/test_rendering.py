"""The rendering interface: every preset renders through the same calls, frames carry the data."""

from __future__ import annotations

import math

import pytest

from tactilize.actuators.recording import RecordingOutput
from tactilize.actuators.simulated import SimulatedOutput
from tactilize.data import get_texture
from tactilize.features import extract_features
from tactilize.mapping import Profile
from tactilize.maps.texturemap import texture_map
from tactilize.pen import PenRenderer, PenSample
from tactilize.surface import surface_model
from tactilize.surface.rendering import (Frame, SteadyRendering, SurfaceRendering, rendered_drive, rendering_for,
                                         train_events)

PRESETS = ("paper", "physical", "perceptual", "surface")


def _picture():
    img = get_texture("corduroy").image
    return img, texture_map(img), surface_model(img)


def _stroke(tmap, speed_m_s=0.05, rate_hz=240.0, n=200):
    y = tmap.height_m / 2
    return [PenSample(k / rate_hz, 1e-3 + speed_m_s * k / rate_hz, y, 0.5) for k in range(n)]


def test_the_profile_picks_the_rendering_and_a_switch_keeps_the_picture():
    img, tmap, sm = _picture()
    assert isinstance(rendering_for(Profile.preset("paper"), sm), SteadyRendering)
    r = rendering_for(Profile.preset("surface"), sm)
    assert isinstance(r, SurfaceRendering) and r.surface is sm
    # a surface profile without a picture renders by its laws
    assert isinstance(rendering_for(Profile.preset("surface")), SteadyRendering)
    # the same rendering is kept for another profile that renders the same way
    assert rendering_for(Profile.preset("surface"), sm, previous=r) is r
    s = rendering_for(Profile.preset("paper"), sm, previous=r)
    assert isinstance(s, SteadyRendering) and s.surface is sm
    assert isinstance(rendering_for(Profile.preset("surface"), s.surface, previous=s), SurfaceRendering)


def test_a_steady_frame_is_its_drives_regular_train():
    img, tmap, sm = _picture()
    prof = Profile.preset("paper")
    rendering = rendering_for(prof, sm)
    tracker_states = PenRenderer(tmap, prof, None)
    frames = []
    samples = _stroke(tmap)
    for k in range(0, len(samples), 4):
        res = tracker_states.feed(samples[k: k + 4])
        if res.state is not None and res.features is not None:
            frames.append(rendering.frame(res.state, res.features, samples[k: k + 4]))
    on = [f for f in frames if not f.drive.is_off]
    assert on and all(isinstance(f, Frame) and f.regular for f in frames)
    for f in on:
        period = 1.0 / f.drive.pulse_frequency_hz
        gaps = [b.t_s - a.t_s for a, b in zip(f.events, f.events[1:])]
        assert all(math.isclose(g, period, rel_tol=1e-9) for g in gaps)
    # the train keeps its phase from batch to batch
    d = on[0].drive
    a = train_events(d, 0.0, 0.0, 0.05)
    b = train_events(d, 0.0, a[1].t_s - 1e-6, 0.05)
    assert b[0].t_s == pytest.approx(a[1].t_s)


@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_renders_through_every_output_by_the_same_calls(preset):
    img, tmap, sm = _picture()
    prof = Profile.preset(preset)
    outputs = [RecordingOutput(), SimulatedOutput(channels=2, start=False)]
    for out in outputs:
        r = PenRenderer(tmap, prof, out, surface=sm, resend_rel=0.0)
        assert r.rendering.name == prof.rendering
        samples = _stroke(tmap)
        results = []
        for k in range(0, len(samples), 4):
            results.append(r.feed(samples[k: k + 4]))
            if hasattr(out, "advance"):
                out.advance(4 / 240.0)
        assert any(res.on for res in results), (preset, type(out).__name__)
        r.lift()
        out.close()


@pytest.mark.parametrize("preset", PRESETS)
def test_the_catalogue_row_the_command_and_the_rendering_give_one_drive(preset):
    from tactilize.catalog.analysis import AnalysisSettings, _row_from_image, speed_label

    img, tmap, sm = _picture()
    prof = Profile.preset(preset)
    feat = extract_features(img)
    speeds = (0.02, 0.06)
    row = _row_from_image(img, AnalysisSettings(profile=prof, speeds_m_s=speeds))
    for v in speeds:
        one = rendering_for(prof, image=img).steady_drive(feat, v)
        assert rendered_drive(prof, img, feat, v, surface=sm) == one
        assert row[f"drive_{speed_label(v)}_pulse_frequency_hz"] == pytest.approx(one.pulse_frequency_hz)
        assert row[f"drive_{speed_label(v)}_pulse_width_s"] == pytest.approx(one.pulse_width_s)
