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


# ------------------------------------------------ one whole-stroke path, offline and in real time

FRAME_S = 1 / 60  # run_stroke's batches (the page's display frame)


def _hand_stroke(tmap):
    """A hand-like curved stroke: speed from about 20 to 120 mm/s, a reversal, a gentle curve."""
    t = np.arange(0.0, 1.2, 1 / 240)
    x = tmap.width_m * (0.5 + 0.3 * np.sin(2 * np.pi * t / 1.6) * (1 - 0.3 * t))  # turns back at 0.4 s
    y = tmap.height_m * (0.5 + 0.1 * np.sin(2 * np.pi * t / 0.9))
    return [PenSample(float(a), float(b), float(c), 0.5) for a, b, c in zip(t, x, y)]


def _socket_fired(renderer, samples, batch_s):
    """What the pen's renderer (the socket's) hands an event-playing output batch by batch, and
    what of it fired: a frame's events due by the next batch's newest sample (no transport)."""
    from tactilize.surface.playback import stroke_batches

    now = [0.0]
    renderer._clock = lambda: now[0]
    fired, pending = [], ()
    for batch in stroke_batches(samples, batch_s):
        now[0] = batch[-1].t_s
        fired += [e for e in pending if e.t_s <= now[0]]
        res = renderer.feed(batch)
        pending = res.events
    fired += [e for e in pending if e.t_s <= now[0]]
    return fired


@pytest.mark.parametrize("preset", PRESETS)
def test_a_recorded_stroke_fires_the_same_events_on_every_path(preset, picture):
    from tactilize.surface.playback import play_stroke
    from tactilize.surface.rendering import rendering_for

    tmap, sm = picture
    prof = Profile.preset(preset)
    samples = _hand_stroke(tmap)
    one = play_stroke(rendering_for(prof, sm), samples, tmap, batch_s=FRAME_S, transport_s=0.0).events
    socket = _socket_fired(PenRenderer(tmap, prof, RecordingOutput(), surface=sm), samples, FRAME_S)
    assert len(one) > 10
    assert [(e.t_s, e.strength, e.clamped) for e in socket] == [(e.t_s, e.strength, e.clamped) for e in one]
    rows = [[s.t_s, s.x_m * 1e3, s.y_m * 1e3, s.pressure] for s in samples]
    tl = run_stroke(parse_stroke(rows, "<hand>", tmap.width_m, tmap.height_m), tmap, prof, surface=sm)
    if tl.events is not None:  # the rendering's own events (a steady one's are its drives' trains)
        exported = timeline_events(tl)
        assert len(exported) == len(one)
        assert [e.t_s for e in exported] == pytest.approx([e.t_s - samples[0].t_s for e in one], abs=1e-12)
        assert [(e.strength, e.clamped) for e in exported] == [(e.strength, e.clamped) for e in one]
        for fmt in FORMATS:
            assert len(render(tl, fmt)) > 0, (preset, fmt)


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("speed_m_s", [0.05, 0.2])
def test_a_catalogue_row_is_what_the_pen_fires_over_the_straight_stroke(preset, speed_m_s, picture):
    from tactilize.features import extract_features
    from tactilize.surface.equivalent import drive_of_statistics
    from tactilize.surface.events import event_statistics
    from tactilize.surface.playback import Everywhere
    from tactilize.surface.rendering import rendering_for
    from tactilize.surface.straight import MirroredSurface, straight_stroke

    tmap, sm = picture
    prof = Profile.preset(preset)
    feat = extract_features(get_texture("corduroy").image)
    row = rendering_for(prof, sm).steady_drive(feat, speed_m_s)  # what catalog/analysis.py reads
    t, x, y = straight_stroke(sm.width_m, sm.height_m, speed_m_s)
    samples = [PenSample(float(a), float(b), float(c)) for a, b, c in zip(t, x, y)]
    pen = PenRenderer(Everywhere(feat), prof, RecordingOutput(), surface=MirroredSurface(sm))
    now = [0.0]
    pen._clock = lambda: now[0] + 0.001
    fired, pending, drives = [], (), []
    from tactilize.surface.playback import BATCH_S, stroke_batches
    for batch in stroke_batches(samples, BATCH_S):
        now[0] = batch[-1].t_s
        fired += [e for e in pending if e.t_s <= now[0]]
        res = pen.feed(batch)
        pending = res.events
        drives.append(res.requested[0])
    fired += [e for e in pending if e.t_s <= now[0]]
    def numbers(d):
        return (d.pulse_frequency_hz, d.pulse_width_s, d.amplitude, d.strength or 0.0, d.regularity or 0.0)

    assert len(fired) > 10
    if pen.rendering.name == "steady":
        # a steady preset: every frame once the tracker has a speed is the law's drive (the row)
        for d in drives[1:]:
            assert numbers(d)[:2] == pytest.approx(numbers(row)[:2], rel=1e-9) and d.clamped == row.clamped
    else:
        want = drive_of_statistics(event_statistics(fired, float(t[-1])), prof)
        assert numbers(row) == pytest.approx(numbers(want), rel=1e-12) and row.clamped == want.clamped
