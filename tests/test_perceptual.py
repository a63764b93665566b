"""The perceptual profile: textures told apart, every stroke felt, irregular textures felt irregular."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from tactilize.actuators.simulated import SimulatedOutput
from tactilize.data import get_texture, texture_ids
from tactilize.drive import Drive
from tactilize.features import extract_features
from tactilize.mapping import Profile
from tactilize.report import FREQUENCY_JND, distinguishable, interval_cv, profile_report
from tactilize.synthesis import JITTER_MAX_PERIODS, PulseStream, pulse_train

SPEEDS = (10, 20, 40, 60, 100, 160)


@pytest.fixture(scope="module")
def features():
    return {tid: extract_features(get_texture(tid).image) for tid in texture_ids()}


def test_built_in_textures_are_told_apart_and_every_drive_is_felt(features):
    rep = profile_report(Profile.preset("perceptual"), features)
    assert rep.pairs == 21 * len(SPEEDS)
    assert rep.distinct_share >= 0.95, rep.close_pairs
    assert rep.followed_share == 1.0, [r for r in rep.rows if not r["follows"]]
    # By frequency alone, too, at least 95 % (the regularity only adds to it).
    by_freq = 0
    for v in SPEEDS:
        f = {r["texture"]: r["frequency_hz"] for r in rep.rows if r["speed_mm_s"] == v}
        names = sorted(f)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                lo, hi = sorted((f[a], f[b]))
                by_freq += hi >= lo * (1 + FREQUENCY_JND)
    assert by_freq / rep.pairs >= 0.95
    # Nothing piles up at the wire's ceiling.
    assert max(r["frequency_hz"] for r in rep.rows) < 300.0
    # The paper's preset, for contrast, leaves most pairs indistinguishable (the issue: 26 of 126).
    paper = profile_report(Profile.preset("paper"), features, simulate_wire=False)
    assert paper.distinct_share < 0.5


@dataclass
class Grating:
    spatial_frequency_per_m: float
    spectral_intensity: float = 0.9
    orientation_deg: float = 0.0
    anisotropy: float = 1.0
    periodicity: float = 0.95


def test_frequency_never_falls_with_speed_nor_with_a_finer_grating():
    prof = Profile.preset("perceptual")
    f_s = [100.0, 200.0, 300.0, 500.0, 800.0, 1300.0, 2000.0, 3500.0, 5000.0]
    speeds = np.geomspace(1.0, 300.0, 40)
    table = np.array([[prof.drive(Grating(fs), v / 1e3).pulse_frequency_hz for v in speeds] for fs in f_s])
    assert np.all(np.diff(table, axis=1) >= 0), "frequency fell as the speed rose"
    assert np.all(np.diff(table, axis=0) >= 0), "a finer grating got a lower frequency"
    # and it rises where the band allows (no plateau inside the design range)
    inside = (table > 1.0) & (table < 300.0)
    assert np.all(np.diff(table, axis=1)[inside[:, 1:]] > 0)


def _intervals(starts: np.ndarray) -> np.ndarray:
    return np.diff(np.sort(starts))


def test_a_noisy_texture_pulses_irregularly_around_the_same_mean_frequency(features):
    prof = Profile.preset("perceptual")
    clean, noisy = features["corduroy"], features["sandpaper"]
    assert clean.periodicity > 0.9 and noisy.periodicity < 0.01
    d_clean = prof.drive(clean, 0.06)
    d_noisy = prof.drive(noisy, 0.06)
    assert d_clean.regularity == 1.0 and d_noisy.regularity == 0.0
    # the same mean frequency for both (the noisy one made to match the clean one)
    d_noisy = d_noisy.replace(pulse_frequency_hz=d_clean.pulse_frequency_hz, pulse_width_s=d_clean.pulse_width_s)
    fs = 48_000
    out = {}
    for name, d in (("clean", d_clean), ("noisy", d_noisy)):
        x = pulse_train(d, 60.0, fs)
        on = x > 0
        starts = np.flatnonzero(on[1:] & ~on[:-1]) + 1
        iv = _intervals(starts) / fs
        out[name] = (iv.mean(), iv.std() / iv.mean(), starts.size)
    # Threshold 0.2: the fingertip's frequency Weber fraction; an even train's CV is
    # only its one-sample rounding (1 / 48000 s in 85 ms: 1e-4).
    assert out["noisy"][1] > 0.2 and out["clean"][1] < 0.01
    assert out["noisy"][1] == pytest.approx(JITTER_MAX_PERIODS / math.sqrt(6), rel=0.1)
    assert out["noisy"][0] == pytest.approx(out["clean"][0], rel=0.01)
    assert abs(out["noisy"][2] - out["clean"][2]) <= 1


def test_the_jitter_is_seeded_reproducible_and_the_same_in_blocks():
    d = Drive(80.0, 3e-4, 1.0, (), 0.5, 0.0)
    assert np.array_equal(pulse_train(d, 2.0, 48_000, seed=3), pulse_train(d, 2.0, 48_000, seed=3))
    assert not np.array_equal(pulse_train(d, 2.0, 48_000, seed=3), pulse_train(d, 2.0, 48_000, seed=4))
    a, b = PulseStream(48_000, d), PulseStream(48_000, d)
    whole = a.render(96_000)
    pieces = np.concatenate([b.render(n) for n in [128] * 750])
    assert np.array_equal(whole, pieces)
    # a drive change every few pulses (a pen) does not restart the pattern
    s = PulseStream(48_000, d)
    blocks = []
    for i in range(400):
        s.set_drive(d.replace(pulse_frequency_hz=80.0 + (i % 2) * 0.5))
        blocks.append(s.render(480))
    x = np.concatenate(blocks)
    on = x > 0
    iv = np.diff(np.flatnonzero(on[1:] & ~on[:-1]))
    assert iv.std() / iv.mean() > 0.15


def test_the_simulated_wire_plays_the_jitter_and_follows_it(features):
    prof = Profile.preset("perceptual")
    d = prof.drive(features["sandpaper"], 0.06)
    with SimulatedOutput(channels=1, start=False) as out:
        out.standby()
        out.advance(3.0)
        out.apply([d])
        for _ in range(100):
            out.advance(0.02)
        log = [p for p in out.pulse_log(0) if p[0] > 3.5]
    starts = np.array([p[0] for p in log])
    iv = np.diff(starts)
    assert iv.std() / iv.mean() > 0.2
    assert 1 / iv.mean() == pytest.approx(d.pulse_frequency_hz, rel=0.03)
    # A pulse close after the previous one may merge with it (felt.IRREGULAR_FOLLOWED_SHARE);
    # the rest each have their own peak.
    followed = sum(rise >= 0.5e-6 for _, rise, _ in log)
    assert followed >= 0.95 * len(log)


def test_distinguishable_counts_frequency_and_regularity():
    a = Drive(100.0, 3e-4)
    assert not distinguishable(a, Drive(115.0, 3e-4))
    assert distinguishable(a, Drive(121.0, 3e-4))
    assert interval_cv(Drive(100.0, 3e-4, regularity=0.0)) == pytest.approx(JITTER_MAX_PERIODS / math.sqrt(6))
    assert distinguishable(a, Drive(105.0, 3e-4, regularity=0.0))
    assert interval_cv(a) == 0.0 and interval_cv(Drive.off()) == 0.0


def test_old_profiles_load_and_the_paper_stays_even_and_exact(tmp_path):
    paper = Profile.preset("paper")
    text = paper.to_toml()
    old = "\n".join(line for line in text.splitlines())
    # a file written before the [regularity] section existed
    cut = old.split("[regularity]")[0] + "\n[actuator]" + old.split("[actuator]")[1]
    p = tmp_path / "old.toml"
    p.write_text(cut, "utf-8")
    loaded = Profile.load(p)
    d = loaded.drive(Grating(799.0, 0.874, periodicity=0.0), 0.01)
    assert d.regularity is None  # even: the paper has no irregular textures
    g = 40.0 * math.log(800.0)
    alpha = 2.9 / (1.0 + math.exp(-0.05 * (10.0 - 60.0))) + 0.1
    assert d.pulse_frequency_hz == pytest.approx(alpha * g, rel=1e-12)
    assert Profile.preset("paper").drive(Grating(799.0, 0.874, periodicity=0.0), 0.01) == d


def test_exports_play_the_irregularity_of_a_noisy_texture():
    from tactilize.data import builtin_map
    from tactilize.export.stroke import run_stroke, synthetic_stroke

    prof = Profile.preset("perceptual")
    cv = {}
    for tid in ("corduroy", "sandpaper"):
        tmap = builtin_map(tid)
        stroke = synthetic_stroke(tmap.width_m, tmap.height_m, 0.02, 3.0)
        tl = run_stroke(stroke, tmap, prof, output=None, start_s=0.0, mirror=True)
        starts = np.array([p.t_s for p in tl.pulses()])
        iv = np.diff(starts)
        cv[tid] = iv.std() / iv.mean()
    # the transients of AHAP, .haptic taps and the WAV all come from these pulses
    assert cv["sandpaper"] > 0.2 and cv["corduroy"] < 0.05
