"""One rendering, one pipeline: every preset through every output kind by the same call
(``Output.play``), and through every export format from one events timeline."""

from __future__ import annotations

import json

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
    what of it fired: a frame's events due by the next batch's newest sample (no transport),
    each with the drive of the frame that handed it and whether that frame was a regular train."""
    from tactilize.surface.playback import stroke_batches

    now = [0.0]
    renderer._clock = lambda: now[0]
    fired, pending = [], ()
    for batch in stroke_batches(samples, batch_s):
        now[0] = batch[-1].t_s
        fired += [e for e in pending if e[0].t_s <= now[0]]
        res = renderer.feed(batch)
        pending = [(e, res.requested[0], res.regular) for e in res.events]
    fired += [e for e in pending if e[0].t_s <= now[0]]
    return fired


@pytest.mark.parametrize("preset", PRESETS)
def test_a_recorded_stroke_fires_the_same_events_on_every_path(preset, picture):
    """A hand-like stroke (curved, speed 20 .. 120 mm/s, a reversal), every preset: the whole-stroke
    path, the pen's renderer fed batch by batch (the socket's path) and every export format's events
    timeline fire the same events; an export's event carries what its frame's drive played (a steady
    rendering's pulse: the drive's strength and frequency) or the bump's own strength."""
    _same_events_on_every_path(preset, *picture)


@pytest.fixture(scope="module", params=["brick", "grass", "gravel"])
def photograph(request):
    """scikit-image's CC0 photographs (shipped in its package), 60 mm wide."""
    data = pytest.importorskip("skimage.data")
    from tactilize.image import TextureImage

    a = np.asarray(getattr(data, request.param)(), dtype=np.float32) / 255.0
    pitch = 60e-3 / a.shape[1]
    img = TextureImage(a, (pitch, pitch), source=f"skimage.data.{request.param}")
    return texture_map(img), surface_model(img)


@pytest.mark.parametrize("preset", PRESETS)
def test_a_recorded_stroke_on_a_photograph_fires_the_same_events_on_every_path(preset, photograph):
    """The same on photographs nobody here made: their bumps are irregular, which the generated
    textures' are not."""
    _same_events_on_every_path(preset, *photograph)


def _same_events_on_every_path(preset, tmap, sm):
    from tactilize.export.events import drive_strength, plan_events, PHONE_TRANSIENT_S
    from tactilize.export.readers import read_ahap, read_haptic
    from tactilize.surface.playback import play_stroke
    from tactilize.surface.rendering import rendering_for

    prof = Profile.preset(preset)
    samples = _hand_stroke(tmap)
    one = play_stroke(rendering_for(prof, sm), samples, tmap, batch_s=FRAME_S, transport_s=0.0).events
    # (each channel the frame's own drive, as an export's: run_stroke's splitter)
    pen = PenRenderer(tmap, prof, RecordingOutput(), surface=sm, splitter=lambda d, n, st: [d] * n)
    socket = _socket_fired(pen, samples, FRAME_S)
    # (the perceptual law plays 1 .. 15 Hz on this stroke: 9 pulses in its 1.2 s)
    assert len(one) > 5
    assert [(e.t_s, e.strength, e.clamped) for e, _, _ in socket] == [(e.t_s, e.strength, e.clamped) for e in one]
    rows = [[s.t_s, s.x_m * 1e3, s.y_m * 1e3, s.pressure] for s in samples]
    tl = run_stroke(parse_stroke(rows, "<hand>", tmap.width_m, tmap.height_m), tmap, prof, surface=sm)
    exported = timeline_events(tl)
    assert tl.events is not None and exported == tl.events
    assert tl.regular == all(r for _, _, r in socket)
    assert [e.t_s for e in exported] == pytest.approx([e.t_s - samples[0].t_s for e, _, _ in socket], abs=1e-12)
    assert [e.clamped for e in exported] == [e.clamped for e, _, _ in socket]
    # (the export reads the stroke back from millimetres: the last bits of a position, and so of a
    # strength read there, differ)
    for x, (e, drive, regular) in zip(exported, socket):
        if regular:
            assert (x.strength, x.frequency_hz) == pytest.approx((drive_strength(drive), drive.pulse_frequency_hz),
                                                                 rel=1e-9)
        else:
            assert x.strength == pytest.approx(e.strength, rel=1e-9) and x.frequency_hz > 0
    # every format plays that one timeline: a phone's taps are its events a phone plays apart
    plan = plan_events(exported, PHONE_TRANSIENT_S, tl.end_s)
    for fmt, read in (("ahap", lambda b: read_ahap(json.loads(b))), ("haptic", read_haptic)):
        taps = [t.t_s for t in read(render(tl, fmt)).taps]
        assert taps == pytest.approx([e.t_s for e in plan.transients], abs=1e-3), fmt
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


@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_plays_a_straight_stroke_over_serial_on_the_virtual_board(preset, picture):
    """The serial report's path: the one whole-stroke path's frames through the host's serial
    output to the firmware on the virtual board.  The pin shows what play_stroke fired: each
    scheduled event within 5 ms (p95) and none missing or added; a steady preset's train at
    its drive's frequency."""
    from tactilize.features import extract_features
    from tactilize.serial_report import played_on_board
    from tactilize.surface.playback import Everywhere, play_stroke
    from tactilize.surface.rendering import rendering_for
    from tactilize.surface.straight import MirroredSurface, straight_stroke

    tmap, sm = picture
    prof = Profile.preset(preset)
    feat = extract_features(get_texture("corduroy").image)
    duration = 1.0
    t, x, y = straight_stroke(sm.width_m, sm.height_m, 0.06, duration_s=duration)
    samples = [PenSample(float(a), float(b), float(c)) for a, b, c in zip(t, x, y) if a < duration]
    want = play_stroke(rendering_for(prof, MirroredSurface(sm)), samples, Everywhere(feat))
    run = played_on_board(rendering_for(prof, MirroredSurface(sm)), samples, Everywhere(feat))
    assert run.played.events == want.events and len(want.events) > 10
    pins = run.pins_s[(run.pins_s >= -0.005) & (run.pins_s < duration)]
    fired = np.array([e.t_s for e in want.events])
    if all(regular for _, regular in want.regular):
        # a regular train: the board makes it from the drive sent with SET
        f = run.trains[-1].pulse_frequency_hz
        assert [d.pulse_frequency_hz for d in run.trains[1:]] == pytest.approx([f] * (len(run.trains) - 1), rel=1e-6)
        assert abs(pins.size - f * duration) <= 1.5
    else:
        assert not any(regular for _, regular in want.regular)
        err = np.min(np.abs(pins[:, None] - fired[None, :]), axis=1)
        assert pins.size == fired.size == run.counts.fired and run.counts.skipped == 0
        assert np.percentile(err, 95) <= 5e-3
