"""Pulse trains: exact counts and widths, phase-continuous streaming, phantom and SOA laws."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactilize.errors import SignalError, TactilizeError
from tactilize.mapping import Drive
from tactilize.synthesis import (
    PenStream,
    PulseStream,
    pen_channels,
    pen_pulse_trains,
    phantom_amplitudes,
    phantom_beta,
    pulse_train,
    soa_s,
)


def runs(x: np.ndarray) -> list[tuple[int, int, float]]:
    """(start, length, value) of every run of nonzero samples, found independently."""
    on = np.concatenate(([0], (np.asarray(x) != 0).astype(int), [0]))
    d = np.diff(on)
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    return [(int(s), int(e - s), float(x[s])) for s, e in zip(starts, ends)]


@pytest.mark.parametrize(
    "f, w, fs, dur",
    [(100.0, 1e-3, 48_000, 1.0), (300.0, 50e-6, 48_000, 0.5), (37.0, 2.3e-3, 44_100, 2.0), (241.7, 0.31e-3, 48_000, 1.3)],
)
def test_pulse_count_and_width_exact(f, w, fs, dur):
    x = pulse_train(Drive(f, w, 0.6), dur, fs)
    n = int(math.floor(dur * fs + 0.5))
    assert x.dtype == np.float32 and x.size == n
    r = runs(x)
    # Starts are k / f rounded half up: count those below n.
    expected_starts = [int(math.floor(k * fs / f + 0.5)) for k in range(int(dur * f) + 2)]
    expected_starts = [s for s in expected_starts if s < n]
    width = max(1, int(math.floor(w * fs + 0.5)))
    assert [s for s, _, _ in r] == expected_starts
    # every pulse but possibly a last one cut by the buffer end has the exact width
    for s, length, value in r:
        assert length == min(width, n - s)
        assert value == pytest.approx(0.6)
    assert set(np.unique(x)) <= {0.0, np.float32(0.6)}


def test_pulse_of_sub_sample_width_is_one_sample():
    x = pulse_train(Drive(50.0, 1e-6), 0.1, 48_000)
    assert [length for _, length, _ in runs(x)] == [1] * 5


def test_phase_shifts_the_train_and_shows_a_pulse_begun_before_zero():
    fs, f, w = 48_000, 100.0, 1e-3
    base = pulse_train(Drive(f, w), 0.1, fs)
    shifted = pulse_train(Drive(f, w), 0.1, fs, phase_s=-0.5e-3)  # began 24 samples before 0
    r = runs(shifted)
    assert r[0][0] == 0 and r[0][1] == 48 - 24
    assert r[1][0] == 480 - 24
    assert runs(base)[1][0] == 480


def test_off_drive_is_silent_and_bad_requests_raise():
    assert not pulse_train(Drive.off(), 0.5, 48_000).any()
    with pytest.raises(SignalError):
        pulse_train(Drive(100.0, 1e-3), -1.0, 48_000)
    with pytest.raises(SignalError):
        pulse_train(Drive(100.0, 1e-3), 1.0, 0)
    with pytest.raises(SignalError):  # 100 % duty: pulses would merge
        pulse_train(Drive(100.0, 10e-3), 1.0, 48_000)
    with pytest.raises(TactilizeError):
        pulse_train("not a drive", 1.0, 48_000)  # type: ignore[arg-type]


def test_stream_equals_one_shot_for_a_steady_drive_whatever_the_blocks():
    d = Drive(173.0, 0.37e-3, 0.8)
    x = pulse_train(d, 2.0, 48_000)
    s = PulseStream(48_000, d)
    rng = np.random.default_rng(1)
    blocks, total = [], 0
    while total < x.size:
        n = int(min(rng.integers(1, 3000), x.size - total))
        blocks.append(s.render(n))
        total += n
    assert np.array_equal(np.concatenate(blocks), x)


def test_stream_changes_never_truncate_nor_double_a_pulse():
    """Random drive changes at random moments, checked against the documented rules."""
    fs = 48_000
    rng = np.random.default_rng(7)
    s = PulseStream(fs)
    out = []
    changes = []  # (position, drive) in force from that sample
    for _ in range(300):
        if rng.random() < 0.15:
            d = Drive.off()
        else:
            f = float(rng.uniform(20, 300))
            d = Drive(f, float(rng.uniform(20e-6, 0.3 / f)), float(rng.uniform(0.1, 1.0)))
        changes.append((s.position, d))
        s.set_drive(d)
        out.append(s.render(int(rng.integers(1, 900))))
    x = np.concatenate(out)
    r = runs(x)
    assert len(r) > 100

    def drive_at(pos):
        current = None
        for p, d in changes:
            if p <= pos:
                current = d
        return current

    prev = None
    for start, length, value in r:
        d = drive_at(start)
        assert not d.is_off
        width = max(1, int(math.floor(d.pulse_width_s * fs + 0.5)))
        cut = start + width > x.size
        # complete with the width and height of the drive in force at its start
        assert length == (x.size - start if cut else width)
        assert value == pytest.approx(d.amplitude)
        if prev is not None:
            p_start, p_len = prev
            period = fs / d.pulse_frequency_hz
            # never sooner than the new period after the previous start; both
            # starts are rounded from exact positions, so at sample resolution
            # the spacing is at least floor(period), as in a steady train
            assert start - p_start >= math.floor(period)
            # a gap between pulses: two pulses never merge into one doubled pulse
            assert start > p_start + p_len
        prev = (start, length)


def test_stream_change_takes_effect_at_next_start():
    fs = 48_000
    s = PulseStream(fs, Drive(100.0, 1e-3))
    a = s.render(100)  # inside the first pulse (48 samples) and after it
    s.set_drive(Drive(200.0, 0.5e-3))
    b = s.render(2000)
    r = runs(np.concatenate([a, b]))
    assert r[0] == (0, 48, 1.0)
    # next start = previous start + the new period (240 samples), width 24
    assert r[1][0] == 240 and r[1][1] == 24
    assert r[2][0] == 480


def test_change_in_the_middle_of_a_pulse_completes_it():
    s = PulseStream(48_000, Drive(50.0, 2e-3, 1.0))
    a = s.render(30)  # pulse of 96 samples in progress
    s.set_drive(Drive(50.0, 0.5e-3, 0.3))
    b = s.render(2000)
    r = runs(np.concatenate([a, b]))
    assert r[0] == (0, 96, 1.0)
    assert r[1][1] == 24 and r[1][2] == pytest.approx(0.3)


def test_phantom_energy_law():
    for beta in np.linspace(0, 1, 11):
        a1, a2 = phantom_amplitudes(float(beta), 0.8)
        assert a1 == pytest.approx(math.sqrt(1 - beta) * 0.8)
        assert a2 == pytest.approx(math.sqrt(beta) * 0.8)
        assert a1**2 + a2**2 == pytest.approx(0.64)
    with pytest.raises(SignalError):
        phantom_amplitudes(1.5)


def test_pen_channels_follow_the_stroke_direction():
    d = Drive(120.0, 3e-4, 1.0)
    along = pen_channels(d, 0.0)
    against = pen_channels(d, math.pi)
    across = pen_channels(d, math.pi / 2)
    assert along[0].amplitude == pytest.approx(0.0, abs=1e-12) and along[1].amplitude == pytest.approx(1.0)
    assert against[0].amplitude == pytest.approx(1.0) and against[1].amplitude == pytest.approx(0.0, abs=1e-12)
    assert across[0].amplitude == pytest.approx(math.sqrt(0.5)) == across[1].amplitude
    assert phantom_beta(math.pi / 3) == pytest.approx((1 + 0.5) / 2)
    assert pen_channels(d, None) == [d, d]
    assert all(c.pulse_frequency_hz == 120.0 and c.pulse_width_s == 3e-4 for c in along)


def test_soa_law():
    for d_ms in (40, 100, 160):
        assert soa_s(d_ms / 1e3) * 1e3 == pytest.approx(0.32 * d_ms + 47.3)
    with pytest.raises(SignalError):
        soa_s(0.0)


@pytest.mark.parametrize("direction, lead", [(0.0, 0), (math.pi, 1)])
def test_apparent_movement_bursts_are_soa_apart(direction, lead):
    fs = 48_000
    burst = 0.1
    x = pen_pulse_trains(Drive(200.0, 2e-4), 1.0, fs, direction, mode="movement", burst_s=burst)
    assert x.shape == (48_000, 2)
    on_lead = np.flatnonzero(x[:, lead])
    on_lag = np.flatnonzero(x[:, 1 - lead])
    soa = 0.32 * burst + 47.3e-3
    assert on_lead[0] == 0
    assert on_lag[0] == int(math.floor(soa * fs + 0.5))
    # bursts: no pulse starts outside [0, burst) of each cycle of SOA + burst
    cycle = int(math.floor(soa * fs + 0.5)) + int(math.floor(burst * fs + 0.5))
    starts = [s for s, _, _ in runs(x[:, lead])]
    assert all((s % cycle) < burst * fs for s in starts)
    assert len([s for s in starts if s < cycle]) == 20  # 200 Hz for 100 ms


def test_phantom_pen_stream_blocks_match_one_shot():
    d = Drive(150.0, 4e-4, 0.9)
    one = pen_pulse_trains(d, 0.5, 48_000, 1.0)
    s = PenStream(48_000)
    s.set_drive(d, 1.0)
    blocks = np.concatenate([s.render(n) for n in (1000, 7, 15993, 7000)])
    assert np.array_equal(one, blocks)
    a1, a2 = phantom_amplitudes((1 + math.cos(1.0)) / 2, 0.9)
    assert one[:, 0].max() == pytest.approx(a1, rel=1e-6) and one[:, 1].max() == pytest.approx(a2, rel=1e-6)
