"""The stroke tracker and the pen renderer on generated and tablet-like strokes, bad cases included."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from tactilize.mapping import Drive, Profile
from tactilize.data import builtin_map
from tactilize.actuators.recording import RecordingOutput
from tactilize.pen import PenRenderer, PenSample, StrokeTracker, is_trackable
from tactilize.web.rows import DEFAULT_M_PER_CSS_PX, sample_error, samples_from_css


def line_stroke(speed_m_s, direction_rad=0.0, rate_hz=240.0, duration_s=0.3, start=(0.01, 0.02), t0=0.0, jitter_m=0.0, seed=0):
    """A straight stroke; direction in the y-up frame, positions returned y-down."""
    rng = np.random.default_rng(seed)
    n = int(duration_s * rate_hz)
    out = []
    for i in range(n):
        t = t0 + i / rate_hz
        d = speed_m_s * (t - t0)
        x = start[0] + d * math.cos(direction_rad) + rng.normal(0, jitter_m)
        y = start[1] - d * math.sin(direction_rad) + rng.normal(0, jitter_m)
        out.append(PenSample(t, x, y, 0.5))
    return out


# A stroke in the form a pen tablet delivers it through the browser: about 200 Hz
# with irregular intervals, timestamps quantised to 0.1 ms, positions quantised to
# whole CSS pixels, several samples per coalesced batch, a speed that rises and
# falls, a duplicate resent at a batch boundary and one late sample.  (Written
# down in code: no tablet is attached to the machines the tests run on.)
def tablet_like_rows():
    rng = np.random.default_rng(42)
    rows, t, x = [], 1000.0, 30.0
    for i in range(120):
        t += float(rng.choice([4.4, 4.5, 5.0, 5.5, 5.6]))
        v_px_ms = 0.25 * math.sin(math.pi * i / 119) + 0.02  # bell-shaped speed profile
        x += v_px_ms * 5.0
        rows.append([round(t, 1), float(round(x)), float(round(60 + 0.2 * rng.normal())), 0.4 + 0.2 * i / 120, 12.0, -5.0])
    rows.insert(50, list(rows[49]))  # duplicate
    late = list(rows[70])
    rows.insert(74, late)  # out of order (older timestamp)
    return rows


# ------------------------------------------------------------------- tracker


@pytest.mark.parametrize("rate_hz", [100.0, 240.0, 1000.0])
@pytest.mark.parametrize("speed", [0.01, 0.06, 0.3])
def test_speed_of_straight_strokes(rate_hz, speed):
    tr = StrokeTracker()
    st = tr.extend(line_stroke(speed, 0.3, rate_hz))
    assert st.speed_m_s == pytest.approx(speed, rel=1e-6)
    assert st.direction_rad == pytest.approx(0.3, abs=1e-6)


def test_the_velocity_at_the_newest_sample_follows_a_hand_speeding_up():
    """The line's slope trails an accelerating pen by half its window; the parabola through the
    same samples gives the velocity at the newest one (exact for constant acceleration), which the
    path ahead is predicted with."""
    acc, rate = 0.2, 240.0  # m/s^2, Hz: from rest, as a stroke starts
    samples = [PenSample(k / rate, 0.01 + 0.5 * acc * (k / rate) ** 2, 0.02) for k in range(60)]
    tr = StrokeTracker()
    for k, s in enumerate(samples):
        st = tr.extend([s])
        if k >= 10:
            true = acc * s.t_s
            assert st.speed_now_m_s == pytest.approx(true, rel=1e-6) and st.direction_now_rad == pytest.approx(0.0)
            assert true - st.speed_m_s > acc * 0.010  # the line's: the velocity 10 ms and more ago
    # a steady stroke: the same speed either way
    st = StrokeTracker().extend(line_stroke(0.06, 0.3, 240.0))
    assert st.speed_now_m_s == pytest.approx(st.speed_m_s, rel=1e-6) and st.direction_now_rad == pytest.approx(0.3)


def test_direction_is_y_up():
    tr = StrokeTracker()
    # Moving up the screen: y decreases in pointer coordinates.
    samples = [PenSample(i / 100, 0.02, 0.03 - 0.0005 * i) for i in range(10)]
    st = tr.extend(samples)
    assert st.direction_rad == pytest.approx(math.pi / 2)
    tr.reset()
    st = tr.extend([PenSample(i / 100, 0.02 - 0.0005 * i, 0.03) for i in range(10)])
    assert abs(st.direction_rad) == pytest.approx(math.pi)


def test_jitter_is_averaged():
    true_speed = 0.05
    errs = []
    for seed in range(20):
        st = StrokeTracker().extend(line_stroke(true_speed, 0.0, 240.0, jitter_m=0.5 * DEFAULT_M_PER_CSS_PX, seed=seed))
        errs.append(abs(st.speed_m_s - true_speed) / true_speed)
    # Half-pixel jitter between neighbours alone would give ~100 % error at 240 Hz.
    assert np.median(errs) < 0.15


def test_speed_from_timestamps_not_arrival():
    # The same samples delivered in one burst give the same speed as one by one.
    s = line_stroke(0.08, 1.0)
    a = StrokeTracker().extend(s)
    b = StrokeTracker()
    for x in s:
        b.add(x)
    assert a.speed_m_s == b.state.speed_m_s == pytest.approx(0.08)


def test_duplicates_and_out_of_order_are_dropped():
    s = line_stroke(0.05, 0.0, 200.0)
    bad = []
    for i, x in enumerate(s):
        bad.append(x)
        if i % 5 == 0:
            bad.append(x)  # duplicate
        if i % 7 == 3 and i > 3:
            bad.append(s[i - 3])  # late
    tr = StrokeTracker()
    st = tr.extend(bad)
    assert st.speed_m_s == pytest.approx(0.05, rel=1e-6)
    assert tr.counts["duplicate"] > 0 and tr.counts["out_of_order"] > 0
    assert tr.counts["accepted"] == len(s)


def test_equal_time_different_place_is_dropped():
    tr = StrokeTracker()
    tr.extend(line_stroke(0.05, 0.0, 200.0, duration_s=0.05))
    last = tr.state
    assert not tr.add(PenSample(last.t_s, last.x_m + 0.001, last.y_m))
    assert tr.counts["out_of_order"] == 1


def test_invalid_values_are_dropped():
    tr = StrokeTracker()
    tr.extend(line_stroke(0.05, duration_s=0.05))
    before = tr.state
    for bad in (PenSample(math.nan, 0.0, 0.0), PenSample(1.0, math.inf, 0.0), PenSample(1.0, 0.0, -math.inf)):
        assert not tr.add(bad)
    assert tr.state == before and tr.counts["invalid"] == 3


def test_gap_starts_a_new_stroke():
    tr = StrokeTracker()
    tr.extend(line_stroke(0.1, 0.0, duration_s=0.1))
    st = tr.extend([PenSample(5.0, 0.03, 0.03)])
    assert tr.counts["gap"] == 1
    assert st.speed_m_s == 0.0 and st.samples == 1


def test_clock_reset_starts_a_new_stroke():
    tr = StrokeTracker()
    tr.extend(line_stroke(0.1, 0.0, duration_s=0.1, t0=100.0))
    st = tr.extend(line_stroke(0.02, 0.0, duration_s=0.1, t0=0.0))
    assert tr.counts["clock_reset"] == 1
    assert st.speed_m_s == pytest.approx(0.02)


def test_jump_restarts_and_never_reports_impossible_speed():
    tr = StrokeTracker()
    a = line_stroke(0.05, 0.0, 200.0, duration_s=0.1, start=(0.005, 0.01))
    b = line_stroke(0.05, 0.0, 200.0, duration_s=0.1, start=(0.06, 0.04), t0=a[-1].t_s + 0.005)
    speeds = []
    for x in a + b:
        tr.add(x)
        speeds.append(tr.state.speed_m_s)
    assert max(speeds) < 0.06  # the 55 mm leap in 5 ms (11 m/s) never shows
    assert tr.counts["jump"] == 1
    assert tr.state.speed_m_s == pytest.approx(0.05)
    assert tr.state.x_m == pytest.approx(b[-1].x_m)


def test_single_glitch_is_discarded():
    tr = StrokeTracker()
    s = line_stroke(0.05, 0.0, 200.0, duration_s=0.2)
    glitch = PenSample(s[20].t_s + 0.001, 0.5, 0.5)
    seq = s[:21] + [glitch] + s[21:]
    speeds = [tr.extend([x]).speed_m_s for x in seq]
    assert max(speeds) < 0.06
    assert tr.counts["glitch"] == 1 and tr.counts["jump"] == 0
    assert tr.state.speed_m_s == pytest.approx(0.05)


def test_trackable_means_finite_time_and_position():
    assert is_trackable(PenSample(0.0, 0.01, 0.02, None, math.nan, math.inf))  # pressure and tilt are not needed
    for bad in (math.nan, math.inf, -math.inf):
        assert not is_trackable(PenSample(bad, 0.0, 0.0))
        assert not is_trackable(PenSample(0.0, bad, 0.0))
        assert not is_trackable(PenSample(0.0, 0.0, bad))


def test_memory_is_bounded_at_any_rate():
    tr = StrokeTracker(max_samples=64)
    tr.extend(line_stroke(0.05, 0.0, rate_hz=20000.0, duration_s=0.5))
    assert len(tr._buf) == 64
    assert tr.state.speed_m_s == pytest.approx(0.05)


def test_sparse_device_uses_min_samples():
    # 50 Hz: only one sample per 30 ms window; the fit still uses three.
    st = StrokeTracker().extend(line_stroke(0.04, 0.0, rate_hz=50.0, duration_s=0.3))
    assert st.samples == 3 and st.speed_m_s == pytest.approx(0.04)


def test_tablet_like_stroke():
    rows = tablet_like_rows()
    assert all(sample_error(r) is None for r in rows)
    tr = StrokeTracker()
    speeds = []
    for s in samples_from_css(rows, DEFAULT_M_PER_CSS_PX):
        if tr.add(s):
            speeds.append(tr.state.speed_m_s * 1e3)
    assert tr.counts["duplicate"] == 1 and tr.counts["out_of_order"] == 1
    # The bell-shaped profile peaks at 0.27 px/ms = 71 mm/s in the middle.
    mid = speeds[len(speeds) // 2 - 5 : len(speeds) // 2 + 5]
    assert 55 < np.mean(mid) < 85
    assert speeds[5] < 25 and speeds[-1] < 25
    assert tr.state.pressure == pytest.approx(rows[-1][3])


# ------------------------------------------------------------------- renderer


@pytest.fixture(scope="module")
def corduroy():
    return builtin_map("corduroy")


def make_renderer(tmap, profile="paper"):
    out = RecordingOutput()
    return PenRenderer(tmap, Profile.preset(profile), out, splitter=lambda d, n, s: [d] * n), out


def test_faster_stroke_higher_frequency(corduroy):
    r, out = make_renderer(corduroy)
    slow = r.feed(line_stroke(0.010, 0.0, duration_s=0.2)).applied[0].pulse_frequency_hz
    r.lift()
    fast = r.feed(line_stroke(0.040, 0.0, duration_s=0.2)).applied[0].pulse_frequency_hz
    prof = Profile.preset("paper")
    feat = corduroy.lookup(0.012, 0.02)
    assert slow == pytest.approx(prof.drive(feat, 0.010).pulse_frequency_hz, rel=1e-6)
    assert fast == pytest.approx(prof.drive(feat, 0.040).pulse_frequency_hz, rel=1e-6)
    assert fast > 2 * slow
    assert len(out.applied) == 2 and all(len(a) == 2 for a in out.applied)


def test_lift_stops_at_once(corduroy):
    r, out = make_renderer(corduroy)
    res = r.feed(line_stroke(0.03, duration_s=0.1))
    assert res.on and out.stops == 0
    res = r.lift()
    assert out.stops == 1 and not res.on and not res.down
    assert all(d.is_off for d in res.applied)
    assert r.tracker.state is None
    r.lift()
    assert out.stops == 1  # already off: no redundant stop frames


def test_leaving_the_picture_stops_and_reentry_resumes(corduroy):
    r, out = make_renderer(corduroy)
    w = corduroy.width_m
    inside = r.feed(line_stroke(0.05, 0.0, duration_s=0.05, start=(w - 0.004, 0.02)))
    assert inside.on and inside.inside
    leaving = r.feed(line_stroke(0.05, 0.0, duration_s=0.1, start=(w + 0.001, 0.02), t0=0.06))
    assert not leaving.inside and not leaving.on and out.stops == 1
    assert leaving.state.speed_m_s == pytest.approx(0.05)  # still tracked outside
    back = r.feed(line_stroke(0.05, math.pi, duration_s=0.1, start=(w - 0.001, 0.02), t0=0.17))
    assert back.on and back.inside


def test_negative_coordinates_are_outside(corduroy):
    r, out = make_renderer(corduroy)
    res = r.feed([PenSample(0.0, -0.001, 0.01), PenSample(0.01, -0.0005, 0.01)])
    assert not res.inside and not res.on and out.applied == []


def test_texture_under_the_pen_changes():
    tmap = builtin_map("patchwork")
    r, out = make_renderer(tmap)
    left = r.feed(line_stroke(0.03, 0.0, duration_s=0.05, start=(0.005, 0.005)))
    r.lift()
    right = r.feed(line_stroke(0.03, 0.0, duration_s=0.05, start=(0.045, 0.005)))
    assert right.features.spatial_frequency_per_m > 3 * left.features.spatial_frequency_per_m
    assert right.applied[0].pulse_frequency_hz > left.applied[0].pulse_frequency_hz


def test_clamps_are_reported(corduroy):
    r, _ = make_renderer(corduroy)
    res = r.feed(line_stroke(0.2, 0.0, duration_s=0.1))
    d = res.to_dict()
    assert d["channels"][0]["pulse_frequency_hz"] == 300.0
    assert "max_frequency_hz" in d["channels"][0]["clamped"]
    assert d["channels"][0]["requested_frequency_hz"] == 300.0


def test_output_envelope_result_is_what_is_reported(corduroy):
    class Halving(RecordingOutput):
        def apply(self, channels):
            return [d.with_clamp("envelope", pulse_width_s=d.pulse_width_s / 2) for d in channels]

    out = Halving()
    r = PenRenderer(corduroy, Profile.preset("paper"), out, splitter=lambda d, n, s: [d] * n)
    res = r.feed(line_stroke(0.02, duration_s=0.1))
    assert res.applied[0].pulse_width_s == pytest.approx(res.requested[0].pulse_width_s / 2)
    assert "envelope" in res.to_dict()["channels"][0]["clamped"]


def test_still_pen_renders_zero_speed(corduroy):
    r, _ = make_renderer(corduroy)
    moving = r.feed(line_stroke(0.05, duration_s=0.1))
    still = r.still()
    assert still.state.speed_m_s == 0.0 and still.down
    assert still.applied[0].pulse_frequency_hz < moving.applied[0].pulse_frequency_hz
    # physical profile: a resting stylus on a grating feels nothing
    r2, out2 = make_renderer(corduroy, "physical")
    r2.feed(line_stroke(0.05, duration_s=0.1))
    assert not r2.still().on and out2.stops == 1


def test_all_rejected_samples_stop():
    r, out = make_renderer(builtin_map("corduroy"))
    res = r.feed([PenSample(math.nan, 0.01, 0.01)])
    assert res.down and not res.on and res.state is None


def test_default_split_gives_two_channels(corduroy):
    out = RecordingOutput()
    r = PenRenderer(corduroy, Profile.preset("paper"), out)
    res = r.feed(line_stroke(0.03, 0.5, duration_s=0.1))
    assert len(res.applied) == 2 == len(out.applied[-1])
    assert all(isinstance(d, Drive) for d in res.applied)
    assert any(not d.is_off for d in res.applied)


def test_set_texture_stops(corduroy):
    r, out = make_renderer(corduroy)
    r.feed(line_stroke(0.03, duration_s=0.1))
    res = r.set_texture(builtin_map("linen"))
    assert out.stops == 1 and not res.on and r.tracker.state is None


def test_slow_stroke_on_whole_pixels():
    # 10 mm/s reported in whole CSS pixels at 200 Hz: a new pixel every 26 ms.
    px = DEFAULT_M_PER_CSS_PX
    rows = [[i * 5.0, float(math.floor(20 + 0.01 * i * 5.0 / (px * 1e3))), 40.0] for i in range(100)]
    tr = StrokeTracker()
    speeds = [tr.extend([s]).speed_m_s for s in samples_from_css(rows, px)][30:]
    assert min(speeds) > 0.006 and max(speeds) < 0.014
    assert np.median(speeds) == pytest.approx(0.010, rel=0.1)
    # A pure 30 ms window would see zero speed between pixel steps.
    short = StrokeTracker(max_window_s=0.03)
    speeds_short = [short.extend([s]).speed_m_s for s in samples_from_css(rows, px)][30:]
    assert min(speeds_short) == 0.0


def test_unchanged_drive_is_not_resent(corduroy, monkeypatch):
    import tactilize.pen.renderer as pen_mod

    clock = [100.0]
    monkeypatch.setattr(pen_mod.time, "monotonic", lambda: clock[0])
    r, out = make_renderer(corduroy)
    s = line_stroke(0.03, 0.0, rate_hz=1000.0, duration_s=0.2)
    r.feed(s[:100])
    assert len(out.applied) == 1
    r.feed(s[100:104])  # same speed, same texture: within 0.5 %
    assert len(out.applied) == 1
    assert r.last.applied == out.applied[-1]
    clock[0] += 0.2  # refresh: the output is asked again
    r.feed(s[104:108])
    assert len(out.applied) == 2
    faster = line_stroke(0.05, 0.0, rate_hz=1000.0, duration_s=0.1, start=(s[-1].x_m, s[-1].y_m), t0=s[107].t_s + 0.001)
    r.feed(faster)
    assert len(out.applied) == 3  # a real change goes out at once
    r.lift()
    r.feed(line_stroke(0.05, 0.0, rate_hz=1000.0, duration_s=0.1, t0=5.0))
    assert len(out.applied) == 4  # after a stop, the first drive always goes out


def test_direction_frame_matches_the_texture(corduroy):
    # Corduroy's ribs are vertical (wave vector along x).  With the physical
    # profile only the stroke component across the ribs counts.
    r, _ = make_renderer(corduroy, "physical")
    across = r.feed(line_stroke(0.05, 0.0, duration_s=0.1, start=(0.01, 0.03)))
    assert across.applied[0].pulse_frequency_hz == pytest.approx(0.05 * across.features.spatial_frequency_per_m, rel=1e-3)
    r.lift()
    along = r.feed(line_stroke(0.05, math.pi / 2, duration_s=0.1, start=(0.01, 0.04)))  # up the screen
    assert along.state.direction_rad == pytest.approx(math.pi / 2)
    # cos 90 deg ~ 0: only the actuator's 1 Hz floor remains
    assert along.applied[0].pulse_frequency_hz <= 1.0 < 0.1 * across.applied[0].pulse_frequency_hz
    r.lift()
    linen = builtin_map("linen")  # wave vector at 45 deg, y up
    r.set_texture(linen)
    diag = r.feed(line_stroke(0.05, math.radians(45), duration_s=0.1, start=(0.01, 0.04)))
    anti = r.feed(line_stroke(0.05, math.radians(-45), duration_s=0.1, start=(0.01, 0.02), t0=1.0))
    assert anti.applied[0].pulse_frequency_hz <= 1.0
    assert diag.applied[0].pulse_frequency_hz == pytest.approx(0.05 * 800, rel=0.02)


def test_default_split_is_phantom_only_where_amplitude_is_intensity():
    import math as _math

    from tactilize.actuators.base import OutputBase
    from tactilize.actuators.simulated import SimulatedOutput
    from tactilize.pen import StrokeState, default_splitter

    class VoiceCoil(OutputBase):
        def apply(self, channels):
            return list(channels)

        def stop(self):
            pass

    drive = Drive(120.0, 3e-4, 1.0)
    fields = {f: 0.0 for f in StrokeState._fields}
    state = StrokeState(**{**fields, "direction_rad": 0.0})
    coil = default_splitter(VoiceCoil())(drive, 2, state)
    # energy model: a stroke along the actuator axis puts the whole intensity on actuator 2
    assert coil[0].amplitude == pytest.approx(0.0, abs=1e-9) and coil[1].amplitude == pytest.approx(1.0)
    assert coil[0].amplitude ** 2 + coil[1].amplitude ** 2 == pytest.approx(1.0)
    diagonal = StrokeState(**{**fields, "direction_rad": _math.pi / 2})
    half = default_splitter(VoiceCoil())(drive, 2, diagonal)
    assert half[0].amplitude == pytest.approx(_math.sqrt(0.5)) == half[1].amplitude
    # the SMA wire: both pins at the texture's full current, whatever the direction
    assert SimulatedOutput.amplitude_is_intensity is False
    sma = default_splitter(SimulatedOutput(start=False))(drive, 2, diagonal)
    assert sma == [drive, drive]


# ------------------------------------------------------------------- the package


def test_the_pages_rows_are_the_webs_not_the_pens():
    # The pen sits below the web: no shim re-exports the page's rows from here.
    import tactilize.pen as pen
    from tactilize.web import rows

    for name in ("sample_error", "samples_from_css", "DEFAULT_M_PER_CSS_PX"):
        assert hasattr(rows, name)
        with pytest.raises(AttributeError):
            getattr(pen, name)


def test_the_pen_does_not_load_the_web_server():
    import subprocess
    import sys

    code = "import sys, tactilize.pen, tactilize.web.rows; print('fastapi' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"



def test_lift_and_hover_rest_the_output_in_standby_where_it_has_one():
    from tactilize.actuators.base import OutputBase

    class Standing(OutputBase):
        channels = 2

        def __init__(self):
            self.calls = []

        def apply(self, drives):
            self.calls.append("apply")
            return list(drives)

        def standby(self):
            self.calls.append("standby")

        def stop(self):
            self.calls.append("stop")

    from tactilize.pen import PenRenderer, PenSample
    from tactilize.maps.texturemap import texture_map
    from tactilize.data import get_texture

    out = Standing()
    r = PenRenderer(texture_map(get_texture("corduroy").image), output=out)
    r.hover()
    assert out.calls == ["standby"]
    r.feed([PenSample(0.0, 0.01, 0.01, 0.5), PenSample(0.01, 0.0104, 0.01, 0.5)])
    assert out.calls[-1] == "apply"
    r.hover()  # a hover while the pen renders does not interrupt it
    assert out.calls[-1] == "apply"
    r.lift()
    assert out.calls[-1] == "standby" and "stop" not in out.calls
