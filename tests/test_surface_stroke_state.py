"""The stroke's fired and pending events (tactilize.surface.stroke).

The equivalent Drive's window holds every event fired in the last 150 ms and those
scheduled, whatever the speed (a window of the path's history instead of time would
shrink to 4 mm of path above 27 mm/s); a lone event in it is a rate of one per window.
"""

from __future__ import annotations

from tactilize.pen.samples import PenSample
from tactilize.surface import SurfaceStroke, surface_model
from tactilize.surface.equivalent import WINDOW_S, equivalent_drive, window_statistics
from tactilize.surface.events import PulseEvent
from tactilize.surface.fields import grain_field, grating_field

_FIELD = grain_field(1.0e-3, (60e-3, 12e-3), seed=11)
_SURFACE = surface_model(_FIELD.heights, pitch_m=_FIELD.pitch_m)


def test_a_stroke_with_a_stop_and_a_reversal_has_events_in_its_windows():
    """Held-up batches, a stop and a reversal: the window's statistics are those of its recent events."""
    stroke = SurfaceStroke(_SURFACE)
    gaps = [0.004] * 200 + [0.016, 0.03] * 20
    held = [0.0, 0.002, 0.0, 0.01] * 60
    speeds = [0.04, 0.0, -0.04, 0.16]
    t, x, checked = 0.0, 5e-3, 0
    for k, (gap, late) in enumerate(zip(gaps, held)):
        v = speeds[k * len(speeds) // len(gaps)]
        t += gap
        x = min(55e-3, max(1e-3, x + v * gap))
        stroke.update([PenSample(t, x, 6e-3)], abs(v), (0.0 if v > 0 else 3.141592653589793) if v else None,
                      played_until_s=t + late if late else None)
        got = stroke.window_statistics(WINDOW_S)
        assert got == window_statistics(stroke.recent(WINDOW_S), stroke.now_s, WINDOW_S)
        checked += got.pulses > 0
    assert checked > 150


def test_a_lone_event_in_a_window_is_one_pulse_per_window():
    stats = window_statistics([PulseEvent(1.0, 0.5)], 1.05, WINDOW_S)
    assert stats.pulses == 1 and stats.rate_hz == 1.0 / WINDOW_S and stats.interval_cv == 0.0


def _grating_stroke(speed_m_s: float, seconds: float) -> SurfaceStroke:
    """A straight stroke across ridges 2 mm apart, the output keeping up (everything handed out plays)."""
    g = grating_field(500.0, 0.0, (200e-3, 10e-3), 0.1e-3)
    stroke = SurfaceStroke(surface_model(g, pitch_m=0.1e-3))
    for k in range(int(seconds / 0.004)):
        t = 0.004 * k
        stroke.update([PenSample(t, 2e-3 + speed_m_s * t, 5e-3)], speed_m_s, 0.0)
    return stroke


def test_the_window_is_150_ms_of_events_at_any_speed():
    for speed in (0.02, 0.08, 0.16):
        stroke = _grating_stroke(speed, 1.0)
        rate = speed / 2e-3
        fired_in_window = [e for e in stroke.recent(WINDOW_S) if e.t_s <= stroke.now_s]
        # 150 ms of ridges at 10, 40, 80 a second: 1-2, 6, 12 (before: 4 mm of path, 2 at 80 and 160 mm/s).
        assert abs(len(fired_in_window) - rate * WINDOW_S) <= 1.5, (speed, len(fired_in_window))
        d = equivalent_drive(stroke.recent(WINDOW_S), stroke.now_s)
        assert abs(d.pulse_frequency_hz - rate) <= 0.05 * rate


def test_recent_is_every_event_fired_since_and_those_scheduled():
    stroke = SurfaceStroke(_SURFACE)
    handed: list[list[PulseEvent]] = []
    for k in range(300):  # 1.2 s at 40 mm/s, about 48 grains
        t = 0.004 * k
        handed.append(stroke.update([PenSample(t, 2e-3 + 0.04 * t, 6e-3)], 0.04, 0.0))
    now = stroke.now_s
    # An event handed out by batch k fired when the next batch came at or after its time.
    fired = [e for k, evs in enumerate(handed[:-1]) for e in evs if e.t_s <= 0.004 * (k + 1)]
    want = [e for e in fired if e.t_s >= now - WINDOW_S] + handed[-1]
    assert stroke.recent(WINDOW_S) == want
    assert len(want) >= 4





def test_recent_is_exact_when_events_fire_out_of_time_order():
    """An event can fire after one later than it (a bump found only once the batch before it was
    played, held up); recent() reads back from the newest fired event, as far as that disorder
    reaches, and gives exactly the events fired since the window's start and those scheduled."""
    import random

    from tactilize.surface.stroke import FIRED_KEPT, _Handed

    rng = random.Random(3)
    stroke = SurfaceStroke(_SURFACE)
    fired: list[PulseEvent] = []
    t = 0.0
    for k in range(400):
        t += 0.004
        # each batch fires a few events around now, now and then one up to 40 ms behind the newest
        batch = sorted(t - rng.choice((0.0, 0.0, 0.0, 0.04)) * rng.random() + 0.003 * j
                       for j in range(rng.randint(0, 3)))
        stroke._pending = [_Handed(PulseEvent(u, 0.5), u, u) for u in batch]
        stroke._fire_due(t + 0.01)
        fired += [PulseEvent(u, 0.5) for u in batch if u <= t + 0.01]
        stroke._pending = [_Handed(PulseEvent(t + 0.02, 0.5), t, t)]
        stroke.now_s = t
        since = t - WINDOW_S
        want = [e for e in fired[-FIRED_KEPT:] if e.t_s >= since] + [PulseEvent(t + 0.02, 0.5)]
        assert stroke.recent(WINDOW_S) == want, k
    assert any(b.t_s < max(e.t_s for e in fired[:i + 1]) for i, b in enumerate(fired[1:]))
