"""AudioOutput with a fake sounddevice module (no sound card in tests)."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from tactilize.actuators import audio as audio_mod
from tactilize.actuators.audio import AudioOutput
from tactilize.actuators.factory import open_output
from tactilize.errors import OutputError
from tactilize.mapping import Drive

RATE = 48_000


class FakeStream:
    instances: list["FakeStream"] = []

    def __init__(self, **kwargs):
        self.kwargs = kwargs
        self.callback = kwargs["callback"]
        self.started = False
        self.closed = False
        FakeStream.instances.append(self)

    def start(self):
        self.started = True

    def stop(self):
        self.started = False

    def close(self):
        self.closed = True

    def pull(self, frames: int, block: int = 256) -> np.ndarray:
        """Run the callback as PortAudio would, block by block."""
        out = []
        for start in range(0, frames, block):
            n = min(block, frames - start)
            buf = np.full((n, self.kwargs["channels"]), np.nan, dtype=np.float32)
            self.callback(buf, n, None, None)
            out.append(buf)
        return np.concatenate(out)


class PortAudioError(Exception):
    pass


@pytest.fixture
def fake_sd(monkeypatch):
    mod = types.ModuleType("sounddevice")
    FakeStream.instances.clear()

    def output_stream(**kwargs):
        if kwargs.get("device") == "missing":
            raise PortAudioError("No such device")
        return FakeStream(**kwargs)

    mod.OutputStream = output_stream
    mod.PortAudioError = PortAudioError
    monkeypatch.setitem(sys.modules, "sounddevice", mod)
    return mod


class Identity:
    def apply(self, d: Drive) -> Drive:
        return d


def runs(x: np.ndarray) -> list[int]:
    """Lengths of the runs of nonzero samples."""
    on = np.concatenate([[0], (x > 0).astype(int), [0]])
    edges = np.diff(on)
    return list(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1))


def test_stream_parameters(fake_sd):
    with AudioOutput(device=3, envelope=Identity()):
        s = FakeStream.instances[0]
        assert s.started
        assert s.kwargs["samplerate"] == RATE and s.kwargs["channels"] == 2 and s.kwargs["device"] == 3
    assert s.closed


def test_pulse_trains_per_channel(fake_sd):
    with AudioOutput(envelope=Identity(), gain=0.5) as out:
        out.apply([Drive(120.0, 400e-6, 1.0), Drive(50.0, 1e-3, 0.5)])
        x = FakeStream.instances[0].pull(RATE)  # one second
    ch0, ch1 = x[:, 0], x[:, 1]
    assert len(runs(ch0)) == 120 and len(runs(ch1)) == 50
    # 400 us at 48 kHz is 19.2 samples, 1 ms is 48 samples
    # exact at sample resolution (the synthesiser's rule): 400 us at 48 kHz is
    # round(19.2) = 19 samples, 1 ms is 48
    assert runs(ch0) == [19] * 120 and runs(ch1) == [48] * 50
    assert ch0.max() == pytest.approx(0.5) and ch1.max() == pytest.approx(0.25)
    assert not np.isnan(x).any()


def test_drive_change_mid_stream_is_continuous_and_stop_silences(fake_sd):
    with AudioOutput(envelope=Identity()) as out:
        stream = FakeStream.instances[0]
        out.apply([Drive(100.0, 500e-6)])
        a = stream.pull(RATE // 2)
        out.apply([Drive(200.0, 500e-6)])
        b = stream.pull(RATE // 2)
        assert len(runs(a[:, 0])) == 50 and len(runs(b[:, 0])) == 100
        # no sliver of a pulse where the blocks meet
        assert min(runs(np.concatenate([a[:, 0], b[:, 0]]))) >= 24
        assert not a[:, 1].any()  # the channel not given a drive stays silent
        out.stop()
        assert not stream.pull(4800).any()


def test_drives_pass_the_envelope(fake_sd):
    class Halve:
        def apply(self, d: Drive) -> Drive:
            return d.with_clamp("envelope", pulse_width_s=d.pulse_width_s / 2)

    with AudioOutput(envelope=Halve()) as out:
        sent = out.apply([Drive(100.0, 1e-3)])
        assert sent[0].pulse_width_s == pytest.approx(5e-4) and "envelope" in sent[0].clamped
        x = FakeStream.instances[0].pull(RATE)
    assert runs(x[:, 0]) == [24] * 100


def test_missing_sounddevice_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "sounddevice", None)  # import fails
    with pytest.raises(OutputError, match=r"pip install 'tactilize\[audio\]'"):
        AudioOutput()


def test_missing_portaudio_says_how_to_install(monkeypatch):
    def no_portaudio(name):
        raise OSError("PortAudio library not found")

    import importlib

    monkeypatch.setattr(importlib, "import_module", no_portaudio)
    with pytest.raises(OutputError, match="PortAudio library not found; install the PortAudio library .*libportaudio2"):
        AudioOutput()


def test_a_device_that_cannot_be_opened(fake_sd):
    with pytest.raises(OutputError, match="cannot open the sound device"):
        AudioOutput(device="missing")


def test_factory_audio_spec(fake_sd):
    out = open_output("audio:2", envelope=Identity())
    try:
        assert isinstance(out, AudioOutput) and FakeStream.instances[-1].kwargs["device"] == 2
    finally:
        out.close()
    out = open_output("audio:USB Audio", envelope=Identity())
    try:
        assert FakeStream.instances[-1].kwargs["device"] == "USB Audio"
    finally:
        out.close()


def test_a_drive_the_synthesiser_refuses_fails_in_the_callers_thread(fake_sd):
    from tactilize.errors import TactilizeError

    with AudioOutput(envelope=Identity()) as out:
        with pytest.raises(TactilizeError):
            out.apply([Drive(1000.0, 1e-3)])  # pulses as long as the period: they would touch
        x = FakeStream.instances[0].pull(4800)
    assert not x.any()  # nothing was played


# ----------------------------------------------------------------- pulse events (the surface rendering)


def _grating_events(speed_m_s: float = 0.1, duration_s: float = 1.0):
    from tactilize.surface import stroke_events, surface_model
    from tactilize.surface.fields import grating_field

    pitch = 0.26e-3
    surface = surface_model(grating_field(1000.0, 0.0, (0.3, 0.02), pitch), pitch_m=pitch)
    t = np.arange(0.0, duration_s, 1 / 240)
    return stroke_events(surface, t, 5e-3 + speed_m_s * t, np.full(t.size, 10e-3))


def _frame(events):
    from tactilize.surface.rendering import Frame

    return Frame(tuple(events), Drive.off(), False)


def test_events_play_as_wavelets_at_the_crossing_rate(fake_sd):
    from tactilize.synthesis.acceleration import spectral_peak_hz, spectrum

    events = _grating_events(0.1)
    out = AudioOutput(sample_rate_hz=RATE, envelope=Identity())
    eq = Drive(pulse_frequency_hz=100.0, pulse_width_s=0.001, amplitude=0.5)
    applied = out.play(_frame(events), 0.0, [eq, eq])
    assert applied[0] == eq
    x = FakeStream.instances[-1].pull(RATE)
    assert np.isfinite(x).all()
    f, p = spectrum(x[:, 0].astype(float), RATE)
    assert spectral_peak_hz(f, p) == pytest.approx(100.0, rel=0.03)
    # Bipolar, as strong as the events (one pulse train would be >= 0), and no steady train under it.
    strongest = max(e.strength for e in events)
    assert x[:, 0].min() == pytest.approx(-strongest, abs=0.02) and x[:, 0].max() > 0.1
    # Each wavelet's trough lands one block after the event's time (the output's lead).
    trough = int(np.argmin(x[:4800, 0]))
    first = events[0].t_s * RATE + 256
    assert abs(trough - first) <= 2


def test_a_new_batch_replaces_what_has_not_started(fake_sd):
    out = AudioOutput(sample_rate_hz=RATE, envelope=Identity())
    stream = FakeStream.instances[-1]
    from tactilize.surface.events import PulseEvent

    on = Drive(pulse_frequency_hz=50.0, pulse_width_s=0.001, amplitude=0.5)
    out.play(_frame([PulseEvent(0.005, 1.0), PulseEvent(0.200, 1.0)]), 0.0, [on, on])
    first = stream.pull(1024)  # 21 ms: the first wavelet has started
    out.play(_frame([PulseEvent(0.200, 0.5)]), 1024 / RATE, [on, on])
    rest = stream.pull(RATE // 2)
    x = np.concatenate([first, rest])[:, 0]
    assert x[:3400].min() < -0.99  # the started one played to its end (3 sigma = 34 ms)...
    # ...the one at 200 ms was replaced by the later batch's weaker one
    assert x[3400:].min() == pytest.approx(-0.5, abs=0.005)
    out.stop()
    assert np.abs(stream.pull(4800)).max() == 0.0


def test_a_steady_drive_after_events_drops_them(fake_sd):
    from tactilize.surface.events import PulseEvent

    out = AudioOutput(sample_rate_hz=RATE, envelope=Identity())
    on = Drive(pulse_frequency_hz=50.0, pulse_width_s=0.001, amplitude=0.5)
    out.play(_frame([PulseEvent(0.05, 1.0)]), 0.0, [on, on])
    out.apply([on, on])
    x = FakeStream.instances[-1].pull(RATE // 5)
    assert x.min() >= 0.0  # only the pulse train: no wavelet


def test_an_event_re_sent_after_its_wavelet_started_plays_once(fake_sd):
    """A batch re-sends every event whose time has not come; its wavelet starts 3 sigma before."""
    from tactilize.surface.events import PulseEvent

    out = AudioOutput(sample_rate_hz=RATE, envelope=Identity())
    stream = FakeStream.instances[-1]
    on = Drive(pulse_frequency_hz=50.0, pulse_width_s=0.001, amplitude=0.5)
    events = [PulseEvent(0.010, 1.0), PulseEvent(0.030, 1.0)]
    out.play(_frame(events), 0.0, [on, on])
    head = stream.pull(600)  # the first wavelet (centre 15.3 ms, 3 sigma = 13.5 ms) has started
    out.play(_frame(events), 600 / RATE + 0.004, [on, on])  # a later batch, arriving late
    x = np.concatenate([head, stream.pull(4800)])[:, 0]
    troughs = np.flatnonzero((x[1:-1] < x[:-2]) & (x[1:-1] <= x[2:]) & (x[1:-1] < -0.9))
    assert len(troughs) == 2
    assert np.diff(troughs)[0] == pytest.approx(0.020 * RATE, abs=2)  # where the events are, 20 ms apart


def test_an_event_fired_on_the_stroke_clock_plays_though_the_device_is_behind(fake_sd):
    """A batch re-sends only the events whose time has not come on the stroke's clock; one
    that has come is not in it, and must still play where the device has not reached it."""
    from tactilize.surface.events import PulseEvent

    out = AudioOutput(sample_rate_hz=RATE, envelope=Identity())
    stream = FakeStream.instances[-1]
    on = Drive(pulse_frequency_hz=50.0, pulse_width_s=0.001, amplitude=0.5)
    events = [PulseEvent(0.010 + 0.020 * k, 1.0) for k in range(4)]  # 20 ms apart
    out.play(_frame(events), 0.0, [on, on])
    head = stream.pull(600)  # the device is 12.5 ms in: the 30 ms wavelet has not started
    out.play(_frame(events[2:]), 0.035, [on, on])  # the stroke is at 35 ms: two have fired
    x = np.concatenate([head, stream.pull(4800)])[:, 0]
    troughs = np.flatnonzero((x[1:-1] < x[:-2]) & (x[1:-1] <= x[2:]) & (x[1:-1] < -0.9))
    assert len(troughs) == 4
    assert np.diff(troughs) == pytest.approx([0.020 * RATE] * 3, abs=2)


def test_the_pen_renderer_plays_each_bump_crossed_once_on_the_sound_card(fake_sd):
    """End to end: pen batches through PenRenderer (surface profile) to the sound card, the
    device advancing one batch of frames per batch; six bumps crossed, six wavelets, where
    the bumps are."""
    from tactilize.image import TextureImage
    from tactilize.mapping import Profile
    from tactilize.pen import PenRenderer, PenSample
    from tactilize.surface import surface_model
    from tactilize.surface.fields import bump_field
    from tactilize.maps import texture_map

    centres = [(x * 1e-3, 10e-3) for x in (8, 14, 20, 26, 32, 38)]
    f = bump_field(centres, 1e-3, (50e-3, 20e-3), 0.1e-3)
    img = TextureImage(f.heights, (f.pitch_m, f.pitch_m))
    out = AudioOutput(sample_rate_hz=RATE, envelope=Identity())
    stream = FakeStream.instances[-1]
    r = PenRenderer(texture_map(img), Profile.preset("surface"), out, surface=surface_model(img))
    t = np.arange(0.0, 0.8, 1 / 500)
    samples = [PenSample(a, 3e-3 + 0.05 * a, 10e-3, 0.5) for a in t]
    pulled = []
    for k in range(0, len(samples), 8):  # 16 ms batches, the device 16 ms on each time
        r.feed(samples[k : k + 8])
        pulled.append(stream.pull(768))
    r.lift()
    pulled.append(stream.pull(RATE // 5))
    both = np.concatenate(pulled)
    # The two channels share each wavelet as they share the drive (the phantom split by direction).
    loud = int(np.argmax(np.abs(both).max(axis=0)))
    x = both[:, loud]
    troughs = np.flatnonzero((x[1:-1] < x[:-2]) & (x[1:-1] <= x[2:]) & (x[1:-1] < -0.5))
    assert len(troughs) == 6, troughs
    np.testing.assert_allclose(np.diff(troughs) / RATE, 0.120, atol=0.002)  # 6 mm apart at 50 mm/s
    # Each at full strength: a bump first seen at the look-ahead's end (partly, weak) glides to
    # its strength when the next batch re-sends it, rather than playing weak or twice.
    assert x[troughs + 1].max() < -0.9
