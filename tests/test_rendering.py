"""The rendering interface: every preset renders through the same calls, frames carry the data."""

from __future__ import annotations

import ast
import math
import sqlite3
import sys
from pathlib import Path

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


# ----------------------------------------------------------------- consumers ask the rendering

#: Where a profile's rendering name may be read: the rendering interface (rendering_kind,
#: rendering_for) and the profile's own load, save and presets.
NAME_READERS = ("surface/rendering.py", "mapping/")


def _profile_like(expr) -> bool:
    """``profile``, ``prof``, ``p``, ``settings.profile``, ``self.renderer.profile``...: a profile."""
    import re

    name = expr.attr if isinstance(expr, ast.Attribute) else expr.id if isinstance(expr, ast.Name) else None
    return name is not None and re.fullmatch(r"p|prof|\w*profile", name) is not None


def _name_reads(tree) -> list[int]:
    """Lines of ``tree`` that read a profile's rendering name: ``getattr(x, "rendering", ...)``,
    ``<a profile>.rendering``, or any ``x.rendering`` or variable ``rendering`` compared with something."""
    lines = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr"
                and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant) and node.args[1].value == "rendering"):
            lines.append(node.lineno)
        elif isinstance(node, ast.Attribute) and node.attr == "rendering" and _profile_like(node.value):
            lines.append(node.lineno)
        elif isinstance(node, ast.Compare) and any(
                (isinstance(x, ast.Attribute) and x.attr == "rendering") or (isinstance(x, ast.Name) and x.id == "rendering")
                for x in (node.left, *node.comparators)):
            lines.append(node.lineno)
    return sorted(set(lines))


def test_the_reader_of_rendering_names_finds_every_form():
    code = '''
if profile.rendering == "surface": pass
a = getattr(profile, "rendering", "steady")
b = settings.profile.rendering
c = self.renderer.profile.rendering
d = p.rendering
e = obj.rendering != "steady"
if rendering != "surface": pass
f = self.rendering.frame(state)
g = renderer.rendering.name
'''
    assert _name_reads(ast.parse(code)) == [2, 3, 4, 5, 6, 7, 8]


def test_no_consumer_reads_a_profiles_rendering_name():
    """Consumers ask the rendering (rendering_for, rendering_kind), never branch on the name."""
    import tactilize

    src = Path(tactilize.__file__).parent
    found = []
    for path in sorted(src.rglob("*.py")):
        rel = path.relative_to(src).as_posix()
        if rel.startswith(NAME_READERS):
            continue
        found += [f"src/tactilize/{rel}:{line}" for line in _name_reads(ast.parse(path.read_text("utf-8")))]
    assert found == [], "read a profile's rendering name outside surface/rendering.py (ask the rendering):\n" + \
        "\n".join(found)


@pytest.fixture
def name_readers(monkeypatch):
    """The source files (under src/tactilize) that read a Profile's ``rendering`` while the test runs."""
    import tactilize

    src = Path(tactilize.__file__).parent
    readers: set[str] = set()
    original = Profile.__getattribute__

    def watched(self, name):
        if name == "rendering":
            caller = Path(sys._getframe(1).f_code.co_filename)
            if caller.is_relative_to(src):
                readers.add(caller.relative_to(src).as_posix())
        return original(self, name)

    monkeypatch.setattr(Profile, "__getattribute__", watched)
    return readers


def _protocol(preset):
    """test_experiments_feel's one-picture protocol on ``preset``."""
    from test_experiments_feel import SURFACE_PROTOCOL

    return SURFACE_PROTOCOL.replace('base_profile = "surface"', f'base_profile = "{preset}"')


def _logged_stroke(tmp_path, preset):
    """A stroke over an experiment trial of ``preset``: the replies, the log's rows, the profile
    and the rendering the trial's stroke was rendered with."""
    from tactilize.experiments.flow import Flow
    from tactilize.experiments.protocols import load_protocol
    from tactilize.experiments.store import Store

    path = tmp_path / f"{preset}.toml"
    path.write_text(_protocol(preset))
    db = tmp_path / f"{preset}.sqlite3"
    flow = Flow(load_protocol(str(path)), Store(f"sqlite:///{db}"))
    token = flow.start("P1", True)["session"]
    trial = flow.calibrate(token, {"mm_per_px": 0.25, "felt": True})["trial"]
    image = trial["images"][0]["id"]
    handler = flow.stroke_handler(token)
    replies, batches = [], []
    for b in range(12):  # a straight stroke at a steady 60 mm/s, then faster: [t_ms, x_mm, y_mm, pressure]
        rows = [[8.0 * k, 5.0 + (0.48 if b < 6 else 0.96) * k, 10.0, 0.5] for k in range(4 * b, 4 * b + 4)]
        batches.append(rows)
        replies.append(handler.handle({"type": "samples", "trial": trial["index"], "image": image,
                                       "batch": f"b{b}", "samples": rows}))
    with sqlite3.connect(db) as con:
        logged = con.execute("select t_s, speed_m_s, pulse_frequency_hz, pulse_width_s, amplitude "
                             "from stroke_samples order by id").fetchall()
    profile = flow.profile(flow.store.trials(flow.store.session_by_token(token).id)[0].condition_id)
    return replies, batches, logged, profile, flow.image_features(image), handler.pen.renderers[(0, image)].rendering


def _every_preset():
    from tactilize.mapping.profile import preset_names

    return preset_names()


@pytest.mark.timeout(300)
@pytest.mark.parametrize("preset", _every_preset())
def test_every_preset_renders_through_every_consumer(preset, tmp_path, name_readers):
    """The report's rows, the catalogue's row and the experiments' stroke log of every preset:
    each the rendering's data, none of them reading the profile's rendering name."""
    from tactilize.catalog.analysis import AnalysisSettings, _row_from_image, speed_label
    from tactilize.cli.materials import choice_of, surface_only
    from tactilize.drive import interval_cv
    from tactilize.errors import CatalogError, TactilizeError
    from tactilize.report import profile_report
    from tactilize.surface.events import event_statistics
    from tactilize.surface.rendering import Straight, rendering_kind
    from tactilize.surface.straight import STROKE_S
    from tactilize.pen import StrokeTracker
    from tactilize.web.rows import samples_from_css

    img, tmap, sm = _picture()
    prof = Profile.preset(preset)
    feat = extract_features(img)
    rendering = rendering_for(prof, image=img)
    assert rendering.name == rendering_kind(prof).name == prof.rendering
    speeds = (0.02, 0.06)

    # The report: one row per texture and speed, the rendering's straight stroke.
    rep = profile_report(prof, speeds_mm_s=[v * 1e3 for v in speeds], simulate_wire=False, images={"corduroy": img})
    assert [r["speed_mm_s"] for r in rep.rows] == [20.0, 60.0] and rep.pairs == 0
    for v, row in zip(speeds, rep.rows):
        st = rendering.straight(feat, v)
        assert isinstance(st, Straight) and st.drive == rendering.steady_drive(feat, v)
        assert (row["frequency_hz"], row["interval_cv"], row["pulses"], row["strength"]) == \
            (st.rate_hz, st.interval_cv, st.pulses, st.strength)
        assert row["pulse_width_ms"] == st.drive.pulse_width_s * 1e3 and row["clamped"] == list(st.clamped)
        assert st.pulses == len(st.events) > 0
        if rendering.reads_surface:  # measured on the stroke's events
            stats = event_statistics(st.events, STROKE_S)
            assert (st.rate_hz, st.interval_cv) == (stats.rate_hz, stats.interval_cv)
        else:  # the law's drive and its regular train over the stroke
            law = prof.drive(feat, v)
            assert st.drive == law and st.rate_hz == law.pulse_frequency_hz and st.interval_cv == interval_cv(law)
            assert st.pulses == len(train_events(law, 0.0, 0.0, STROKE_S))

    # The catalogue's row: the rendering's steady drive at every reference speed.
    row = _row_from_image(img, AnalysisSettings(profile=prof, speeds_m_s=speeds))
    for v in speeds:
        one = rendering.steady_drive(feat, v)
        p = f"drive_{speed_label(v)}_"
        assert row[p + "pulse_frequency_hz"] == pytest.approx(one.pulse_frequency_hz)
        assert row[p + "pulse_width_s"] == pytest.approx(one.pulse_width_s)
        assert row[p + "amplitude"] == pytest.approx(one.amplitude)
        assert row[p + "clamped"] == ",".join(one.clamped)
        assert (row[p + "strength"] is None) == (one.strength is None)
    # A material: only a rendering that reads the surface renders it; the others refuse it.
    choice = choice_of("fabric-knit", None)
    if rendering.reads_surface:
        assert _row_from_image(img, AnalysisSettings(profile=prof, speeds_m_s=speeds), "fabric-knit")
        surface_only(choice, prof)
    else:
        with pytest.raises(CatalogError, match="needs a surface profile .*'steady'"):
            _row_from_image(img, AnalysisSettings(profile=prof, speeds_m_s=speeds), "fabric-knit")
        with pytest.raises(TactilizeError, match="--material: needs a surface profile"):
            surface_only(choice, prof)

    # The experiments' stroke log: what the rendering rendered at each sample.
    replies, batches, logged, trial_profile, feats, trial_rendering = _logged_stroke(tmp_path, preset)
    assert trial_rendering.name == rendering.name
    assert all(r["type"] == "drive" and r["stored"] == "stored" for r in replies)
    assert len(logged) == sum(len(b) for b in batches)
    by_batch = [logged[4 * b: 4 * b + 4] for b in range(len(batches))]
    for reply, rows in zip(replies, by_batch):
        last = reply["drive"]
        assert rows[-1][2:] == (last["pulse_frequency_hz"], last["pulse_width_s"], last["amplitude"])
        if trial_rendering.reads_surface:  # the frame's drive, the window's operating point, at every sample
            assert all(r[2:] == rows[-1][2:] for r in rows)
    if not trial_rendering.reads_surface:  # the law at every sample's state, exactly
        tracker, expected = StrokeTracker(), []
        for rows in batches:
            for ps in samples_from_css(rows, 1e-3):
                tracker.add(ps)
                st = tracker.state
                law = trial_profile.drive(feats, speed_m_s=st.speed_m_s if st else 0.0,
                                          direction_rad=st.direction_rad if st else None, pressure=ps.pressure)
                expected.append((law.pulse_frequency_hz, law.pulse_width_s, law.amplitude))
        assert [r[2:] for r in logged] == expected
    assert any(r[2] > 0 for r in logged)

    assert name_readers <= {"surface/rendering.py", "mapping/profile.py"}, name_readers


def test_the_report_strokes_only_what_a_rendering_reads():
    """Features alone serve a steady rendering; a surface rendering needs each texture's picture
    (given, or the built-in one of that name) and says which one it lacks."""
    from tactilize.errors import TactilizeError
    from tactilize.report import profile_report

    img, tmap, sm = _picture()
    feat = extract_features(img)
    steady = profile_report(Profile.preset("perceptual"), {"mine": feat}, (60.0,), simulate_wire=False)
    assert [r["texture"] for r in steady.rows] == ["mine"] and steady.rows[0]["pulses"] > 0
    with pytest.raises(TactilizeError, match="mine: no picture of this texture"):
        profile_report(Profile.preset("surface"), {"mine": feat}, (60.0,), simulate_wire=False)
    built_in = profile_report(Profile.preset("surface"), {"corduroy": feat}, (60.0,), simulate_wire=False)
    assert [r["texture"] for r in built_in.rows] == ["corduroy"] and built_in.rows[0]["pulses"] > 0
