"""Materials: heights in metres, hardness, micro-roughness, the library and ``--material``
(docs/surfaces.md, "Materials"; docs/references.md, section 11).

Every picture is generated here: a flat metal sheet under uneven light, a grain field.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.ndimage import gaussian_filter

from tactilize.cli import main
from tactilize.errors import MaterialError
from tactilize.materials import (LEAST_FELT_PROMINENCE_M, MicroRoughness, library, material, sensation_ratio,
                                 threshold_acceleration_m_s2)
from tactilize.pen.samples import PenSample
from tactilize.surface import SurfaceStroke, surface_model
from tactilize.surface import stroke_events
from tactilize.surface.straight import MirroredSurface
from tactilize.synthesis.acceleration import spectrum, tip_acceleration

N = 400
WIDTH_M = 50e-3
PITCH_M = WIDTH_M / N
FS = 48_000.0


def _lit_flat_metal(seed: int = 3) -> np.ndarray:
    """A flat sheet photographed under uneven light: a gradient, vignetting, streaks of
    reflected light along the sheet, and sensor noise.  Nothing of it is relief."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:N, 0:N] / N - 0.5
    vignette = 1.0 - 0.9 * (xx ** 2 + yy ** 2)
    gradient = 0.25 * (xx + 0.5)
    streaks = gaussian_filter(rng.standard_normal((N, N)), (0.5, 25.0))  # bright lines along x...
    streaks = 0.15 * streaks / streaks.std()
    stroke_streaks = 0.08 * np.sin(2 * math.pi * xx * N / 6.0)  # ...and across the stroke, 0.75 mm apart
    noise = 0.01 * rng.standard_normal((N, N))
    return np.clip(0.35 + 0.4 * vignette + gradient + streaks + stroke_streaks + noise, 0, 1).astype(np.float32)


def _grains(seed: int = 0, sigma_px: float = 2.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = gaussian_filter(rng.standard_normal((N, N)), sigma_px)
    return ((a - a.min()) / (a.max() - a.min())).astype(np.float32)


def _stroke(speed_m_s: float, duration_s: float = 1.0, y_m: float = 0.5 * WIDTH_M):
    t = np.arange(-0.1, duration_s + 0.1, 1 / 240.0)
    return t, 5e-3 + speed_m_s * t, np.full(t.size, y_m)


def _acceleration(surface, speed_m_s: float, duration_s: float = 1.0) -> np.ndarray:
    t, x, y = _stroke(speed_m_s, duration_s)
    return tip_acceleration(MirroredSurface(surface), t, x, y, sample_rate_hz=FS, start_s=0.0, end_s=duration_s).samples


def _rms_db(x: np.ndarray) -> float:
    return 20 * math.log10(math.sqrt(float(np.mean(x * x))))


# ----------------------------------------------------------------- silence of a smooth material


@pytest.mark.parametrize("speed_m_s", [0.05, 0.1, 0.2])
def test_lit_flat_metal_is_silent_as_polished_metal(speed_m_s):
    photo = _lit_flat_metal()
    metal = surface_model(photo, pitch_m=PITCH_M, material="metal-polished")
    t, x, y = _stroke(speed_m_s)
    assert stroke_events(metal, t, x, y) == []
    acc = _acceleration(metal, speed_m_s)
    assert sensation_ratio(acc, FS) < 0.5  # under the detection threshold, with margin
    # Every component under the threshold at its own frequency, not only the sum.
    f, p = spectrum(acc, FS)
    band = (f >= 20) & (f <= 1000)
    amplitude = np.sqrt(2 * p[band] * (f[1] - f[0]))
    assert (amplitude < threshold_acceleration_m_s2(f[band])).all()
    # The picture alone renders its lighting as bumps: what this test guards against.
    assert len(stroke_events(surface_model(photo, pitch_m=PITCH_M), t, x, y)) > 10


def test_the_threshold_is_the_published_shape():
    # docs/references.md, section 11 (detection threshold in displacement): about 0.1 um at
    # 250 Hz, constant acceleration below it in the Pacinian range, steep above it.
    a = threshold_acceleration_m_s2([40.0, 100.0, 250.0, 500.0])
    assert a[2] == pytest.approx((2 * math.pi * 250) ** 2 * 0.1e-6)
    assert a[0] == pytest.approx(a[2], rel=0.01) and a[1] == pytest.approx(a[2], rel=0.01)
    assert a[3] > 10 * a[2]
    assert sensation_ratio(0.9 * a[1] * np.sin(2 * math.pi * 100 * np.arange(48_000) / FS), FS) == \
        pytest.approx(0.9, rel=0.02)


# ----------------------------------------------------------------- metres and the relief scale


def test_doubling_the_relief_scale_raises_the_acceleration_6_db():
    img = _grains()
    one = surface_model(img, pitch_m=PITCH_M, relief_scale_m=50e-6)
    two = surface_model(img, pitch_m=PITCH_M, relief_scale_m=100e-6)
    assert one.relief.source == "given" and one.full_scale_acceleration is not None
    gain = _rms_db(_acceleration(two, 0.1)) - _rms_db(_acceleration(one, 0.1))
    assert gain == pytest.approx(20 * math.log10(2), abs=0.05)


def test_an_estimated_scale_says_so_and_a_bad_scale_is_refused():
    s = surface_model(_grains(), pitch_m=PITCH_M, relief_scale_m="estimate")
    assert s.relief.source == "estimate" and s.relief.scale_m > 0
    for bad in (0.0, -1e-6, math.nan, "deep"):
        with pytest.raises(MaterialError):
            surface_model(_grains(), pitch_m=PITCH_M, relief_scale_m=bad)


def test_events_in_metres_use_absolute_prominence():
    img = _grains()
    t, x, y = _stroke(0.1)
    deep = surface_model(img, pitch_m=PITCH_M, relief_scale_m=400e-6)
    shallow = surface_model(img, pitch_m=PITCH_M, relief_scale_m=40e-6)
    assert deep.prominence_floor >= LEAST_FELT_PROMINENCE_M
    s_deep = np.mean([e.strength for e in stroke_events(deep, t, x, y)])
    s_shallow = np.mean([e.strength for e in stroke_events(shallow, t, x, y)])
    assert s_deep > s_shallow + 0.1  # the same picture, ten times deeper, plays stronger


# ----------------------------------------------------------------- hardness


def test_a_compliant_material_attenuates_the_high_frequencies():
    img = _grains(sigma_px=1.0)
    scale = 200e-6  # the same relief on both: only the hardness differs
    hard = surface_model(img, pitch_m=PITCH_M, material="stone-polished", relief_scale_m=scale)
    soft = surface_model(img, pitch_m=PITCH_M, material="fabric-knit", relief_scale_m=scale)
    f, p_hard = spectrum(_acceleration(hard, 0.1), FS)
    _, p_soft = spectrum(_acceleration(soft, 0.1), FS)

    def band_db(p, lo, hi):
        sel = (f >= lo) & (f < hi)
        return 10 * math.log10(float(p[sel].sum()))

    low = band_db(p_soft, 20, 60) - band_db(p_hard, 20, 60)
    high = band_db(p_soft, 300, 1000) - band_db(p_hard, 300, 1000)
    # (The knit's band above 300 Hz is down to the picture's pixel floor, about 17 dB under the
    # hard one's at 100 mm/s; below 60 Hz the two differ by the knit's wider contact alone.)
    assert high < -12.0 and high < low - 6.0


# ----------------------------------------------------------------- micro-roughness


def test_micro_roughness_is_the_same_both_ways_and_has_its_statistics():
    r = MicroRoughness.of("stone-granite", 15e-6, 150e-6, 125e-6)
    x = np.linspace(0.0, 0.2, 100_001)
    y = 0.37 * x + 3e-3
    h = r.height_m(x, y)
    assert np.array_equal(h, r.height_m(x[::-1], y[::-1])[::-1])
    assert np.std(h) == pytest.approx(r.felt_rms_m, rel=0.15)
    # Gaussian autocorrelation exp(-d^2 / (4 sigma^2)) along the line.
    d = np.hypot(x[1] - x[0], y[1] - y[0])
    lag = int(round(2 * r.sigma_m / d))
    c = np.corrcoef(h[:-lag], h[lag:])[0, 1]
    assert c == pytest.approx(math.exp(-1), abs=0.1)


def test_micro_roughness_is_the_same_on_every_run():
    code = ("from tactilize.materials import MicroRoughness;"
            "print(repr(float(MicroRoughness.of('paper-kraft', 4e-6, 40e-6, 125e-6).height_m(0.0123, 0.0456))))")
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    here = float(MicroRoughness.of("paper-kraft", 4e-6, 40e-6, 125e-6).height_m(0.0123, 0.0456))
    assert float(out) == here and here != 0.0


def test_micro_roughness_is_felt_in_the_path_the_events_and_the_acceleration():
    flat = np.full((N, N), 0.5, dtype=np.float32)
    granite = surface_model(flat, pitch_m=PITCH_M, material="stone-granite")
    assert float(np.ptp(granite.height)) == 0.0  # nothing from the picture
    t, x, y = _stroke(0.04)  # within the picture
    h, _, _ = granite.regions(x, y)
    assert np.isfinite(h).all()
    assert np.array_equal(h, granite.regions(x[::-1], y[::-1])[0][::-1])  # stroked either way
    t, x, y = _stroke(0.1)
    events = stroke_events(granite, t, x, y)
    assert len(events) > 10
    assert sensation_ratio(_acceleration(granite, 0.1), FS) > 3.0


def test_the_real_time_stroke_reads_the_micro_roughness():
    granite = surface_model(np.full((N, N), 0.5, dtype=np.float32), pitch_m=PITCH_M, material="stone-granite")
    stroke = SurfaceStroke(granite)
    v, y = 0.08, 0.5 * WIDTH_M
    fired = 0
    for k in range(250):  # 1 s of 4 ms batches
        t = k * 0.004 + np.arange(4) * 0.001
        stroke.update([PenSample(float(a), float(5e-3 + v * a), y) for a in t], v, 0.0)
        fired += stroke.newly_fired
    t, x, yy = _stroke(v, 1.0)
    offline = len([e for e in stroke_events(granite, t, x, yy) if 0.0 <= e.t_s <= 1.0])
    assert offline > 10 and fired == pytest.approx(offline, rel=0.25)


# ----------------------------------------------------------------- two materials, one picture


def test_two_materials_on_one_picture_differ_as_the_library_says():
    img = _grains()
    p80, p240 = material("sandpaper-p80"), material("sandpaper-p240")
    s80 = surface_model(img, pitch_m=PITCH_M, material="sandpaper-p80")
    s240 = surface_model(img, pitch_m=PITCH_M, material="sandpaper-p240")
    ratio = p80.relief_rms_m / p240.relief_rms_m
    assert s80.relief.scale_m / s240.relief.scale_m == pytest.approx(ratio)
    # Same hardness, so the pictures' heights are in the library's ratio point for point.
    np.testing.assert_allclose(s80.height, ratio * s240.height, rtol=1e-4, atol=1e-12)
    assert s80.micro.rms_m == p80.micro_rms_m and s240.micro.correlation_length_m == p240.micro_correlation_m
    assert _rms_db(_acceleration(s80, 0.1)) > _rms_db(_acceleration(s240, 0.1)) + 6.0


# ----------------------------------------------------------------- the picture alone stays as it was


def test_the_picture_alone_is_unchanged():
    img = _grains()
    alone = surface_model(img, pitch_m=PITCH_M)
    assert alone.relief is None and alone.micro is None and alone.full_prominence is None
    assert alone.full_scale_acceleration is None
    same = surface_model(img, pitch_m=PITCH_M, material=None, relief_scale_m=None)
    assert np.array_equal(alone.height, same.height) and alone.prominence_floor == same.prominence_floor


# ----------------------------------------------------------------- the library and the command line


def test_the_library_holds_the_asked_materials_with_sources():
    names = set(library())
    asked = {"metal-polished", "metal-brushed", "glass", "plastic-smooth", "plastic-textured", "paper-printer",
             "paper-kraft", "cardboard", "wood-sanded", "wood-raw", "stone-polished", "stone-granite",
             "stone-sandstone", "fabric-silk", "fabric-woven", "fabric-knit", "fabric-denim", "fabric-corduroy",
             "fabric-fleece", "leather-smooth", "leather-grained", "rubber", "cork", "sandpaper-p80",
             "sandpaper-p240"}
    assert asked <= names
    for m in library().values():
        assert {"relief", "micro", "hardness", "friction"} <= set(m.sources), m.name
    # FEPA P-grades (docs/references.md, section 11 (FEPA grit sizes)): a quarter of the mean grain.
    assert material("sandpaper-p80").relief_rms_m == pytest.approx(0.25 * 201e-6, rel=0.01)
    assert material("sandpaper-p240").relief_rms_m == pytest.approx(0.25 * 58.5e-6, rel=0.01)


def test_materials_command_lists_them(tmp_path):
    r = CliRunner().invoke(main, ["materials", "--json"])
    assert r.exit_code == 0, r.output
    rows = json.loads(r.output)
    assert len(rows) == len(library()) and all("sources" in row for row in rows)
    r = CliRunner().invoke(main, ["materials"])
    assert r.exit_code == 0 and "stone-granite" in r.output and "section 11" in r.output


def test_an_unknown_material_is_one_line_naming_it_and_close_names(tmp_path):
    from PIL import Image

    path = tmp_path / "grain.png"
    Image.fromarray((_grains() * 255).astype(np.uint8)).save(path)
    for args in (["export", str(path), "--speed", "100", "--format", "wav", "-o", str(tmp_path / "a.wav")],
                 ["drive", str(path), "--speed", "100"]):
        r = CliRunner().invoke(main, [*args, "--material", "graniet"])
        assert r.exit_code == 2
        lines = r.output.strip().splitlines()
        assert len(lines) == 1 and "graniet" in lines[0] and "stone-granite" in lines[0]


def test_export_with_a_material_writes_metres_and_without_stays_as_it_was(tmp_path):
    from PIL import Image

    path = tmp_path / "metal.png"
    Image.fromarray((_lit_flat_metal() * 255).astype(np.uint8)).save(path)
    base = ["export", str(path), "--speed", "150", "--width-mm", "50", "--format", "wav", "--json"]
    r = CliRunner().invoke(main, [*base, "-o", str(tmp_path / "plain.wav")])
    assert r.exit_code == 0, r.output
    plain = json.loads(r.output)
    assert "material" not in plain and plain["peak_full_scale"] > 0.001
    r = CliRunner().invoke(main, [*base, "-o", str(tmp_path / "metal.wav"), "--material", "metal-polished"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["material"] == "metal-polished" and doc["relief_source"] == "material"
    assert doc["peak_full_scale"] < 1e-3  # under a hundredth of a m/s^2 of the stated full scale
    r = CliRunner().invoke(main, ["drive", str(path), "--speed", "100", "--width-mm", "50", "--json",
                                  "--material", "metal-polished"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["strength"] in (None, 0.0)


# ----------------------------------------------------------------- --relief-mm, profile report and serve


def _save(tmp_path, name, pixels):
    from PIL import Image

    path = tmp_path / name
    Image.fromarray((pixels * 255).astype(np.uint8)).save(path)
    return path


def _wav_rms_db(path) -> float:
    import wave

    with wave.open(str(path)) as w:
        kind = {2: np.int16, 4: np.int32}[w.getsampwidth()]
        x = np.frombuffer(w.readframes(w.getnframes()), dtype=kind).astype(np.float64)
    return _rms_db(x)


def test_doubling_relief_mm_raises_the_exported_acceleration_6_db(tmp_path):
    path = _save(tmp_path, "grain.png", _grains())
    base = ["export", str(path), "--speed", "100", "--width-mm", "50", "--format", "wav", "--json"]
    docs, levels = [], []
    for mm in ("0.005", "0.01"):
        out = tmp_path / f"{mm}.wav"
        r = CliRunner().invoke(main, [*base, "-o", str(out), "--relief-mm", mm])
        assert r.exit_code == 0, r.output
        docs.append(json.loads(r.output))
        levels.append(_wav_rms_db(out))
    assert docs[0]["relief_source"] == "given" and docs[0]["relief_rms_m"] == pytest.approx(5e-6)
    assert docs[0]["material"] is None and docs[1]["clipped_samples"] == 0
    assert levels[1] - levels[0] == pytest.approx(20 * math.log10(2), abs=0.1)


def test_relief_mm_overrides_the_materials_relief_and_keeps_its_hardness():
    img = _grains()
    typical = surface_model(img, pitch_m=PITCH_M, material="sandpaper-p80")
    given = surface_model(img, pitch_m=PITCH_M, material="sandpaper-p80", relief_rms_m=material("sandpaper-p80").relief_rms_m / 2)
    assert given.relief.source == "given" and given.relief.material.name == "sandpaper-p80"
    assert given.relief.scale_m == pytest.approx(typical.relief.scale_m / 2)
    assert given.micro.rms_m == typical.micro.rms_m


def test_a_bad_relief_mm_is_one_line():
    for bad in ("0", "-1", "nan", "deep"):
        r = CliRunner().invoke(main, ["drive", "x.png", "--speed", "100", "--relief-mm", bad])
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and "--relief-mm" in r.output, r.output
    with pytest.raises(MaterialError):
        surface_model(_grains(), pitch_m=PITCH_M, relief_scale_m=1e-5, relief_rms_m=1e-6)


def test_profile_report_renders_every_picture_as_the_material(tmp_path):
    path = _save(tmp_path, "metal.png", _lit_flat_metal())
    base = ["profile", "report", "--image", str(path), "--width-mm", "50", "--no-wire", "--json"]
    r = CliRunner().invoke(main, base)
    assert r.exit_code == 0, r.output
    plain = json.loads(r.output)
    assert "material" not in plain and sum(row["pulses"] for row in plain["rows"]) > 10
    r = CliRunner().invoke(main, [*base, "--material", "metal-polished"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["material"] == "metal-polished" and doc["rendered_as"].startswith("metal-polished (relief 50 nm")
    assert sum(row["pulses"] for row in doc["rows"]) == 0  # a polished sheet is silent however it is lit
    r = CliRunner().invoke(main, [*base, "--material", "graniet"])
    assert r.exit_code == 2 and "stone-granite" in r.output
    r = CliRunner().invoke(main, [*base, "--profile", "paper", "--material", "glass"])
    assert r.exit_code == 2 and "surface profile" in r.output


def test_serve_refuses_an_unknown_material_before_it_binds():
    r = CliRunner().invoke(main, ["serve", "--no-open", "--port", "0", "--material", "graniet"])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and "stone-granite" in r.output


# ----------------------------------------------------------------- a catalogue manifest's material column


def test_a_manifest_material_column_renders_each_row_as_its_material(tmp_path):
    pytest.importorskip("pyarrow")
    from tactilize.catalog import read_catalog

    _save(tmp_path, "metal.png", _lit_flat_metal())
    _save(tmp_path, "grain.png", _grains())
    (tmp_path / "m.csv").write_text(
        "id,path,width_mm,material\n"
        "polished,metal.png,50,metal-polished\n"
        "granite,metal.png,50,stone-granite\n"
        "alone,metal.png,50,\n"
        "p80,grain.png,50,sandpaper-p80\n"
        "p240,grain.png,50,Sandpaper-P240\n"
        "typo,metal.png,50,graniet\n")
    out = tmp_path / "cat"
    r = CliRunner().invoke(main, ["batch", str(tmp_path / "m.csv"), "--out", str(out), "--workers", "1", "--json"])
    assert r.exit_code == 0, r.output
    summary = json.loads(r.output)
    assert (summary["ok"], summary["failed"]) == (5, 1)  # the unknown name is its row's error; the batch goes on
    rows = {row["id"]: row for row in read_catalog(out).to_dict("records")}
    assert [rows[k]["material"] for k in ("polished", "granite", "alone", "p80", "p240")] == \
        ["metal-polished", "stone-granite", "", "sandpaper-p80", "sandpaper-p240"]
    rate = "drive_60mm_s_pulse_frequency_hz"
    # The same lit sheet: polished metal is under the least felt bump, granite is not, and the
    # picture alone reads its lighting as relief.
    assert rows["polished"][rate] == 0.0 and rows["granite"][rate] > 5.0 and rows["alone"][rate] > 5.0
    # The same grain: the coarser paper plays stronger (a relief 3.4 times deeper).
    assert rows["p80"]["drive_60mm_s_strength"] > rows["p240"]["drive_60mm_s_strength"]
    typo = rows["typo"]
    assert typo["status"] == "error" and "graniet" in typo["error"] and "stone-granite" in typo["error"]
    assert typo["material"] == "graniet"


def test_a_manifest_material_needs_a_surface_profile(tmp_path):
    from tactilize.catalog import AnalysisSettings, analyse_item, discover
    from tactilize.mapping import Profile

    _save(tmp_path, "grain.png", _grains())
    (tmp_path / "m.jsonl").write_text(json.dumps({"path": "grain.png", "material": "cork"}) + "\n")
    (item,) = discover(tmp_path / "m.jsonl")
    assert item.material == "cork" and item.problem is None
    row = analyse_item(item, AnalysisSettings(Profile.preset("paper")))
    assert row["status"] == "error" and "surface profile" in row["error"] and row["material"] == "cork"


# ----------------------------------------------------------------- a manifest's relief_mm, batch --material/--relief-mm


def _steady_drive_of(path, material_name, relief_rms_m, speed_m_s=0.060):
    """What every command renders for the picture at ``path`` (50 mm wide), independently of the batch."""
    from tactilize.image import load_image
    from tactilize.mapping import Profile
    from tactilize.maps.texturemap import texture_map
    from tactilize.surface.rendering import rendering_for

    img = load_image(path, width_mm=50)
    rendering = rendering_for(Profile.resolve(None), image=img, material=material_name, relief_rms_m=relief_rms_m)
    return rendering.steady_drive(texture_map(img, sample_px="auto").whole, speed_m_s)


def _missing(v) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))


def test_a_manifest_relief_mm_column_is_each_rows_relief(tmp_path):
    pytest.importorskip("pyarrow")
    from tactilize.catalog import read_catalog

    path = _save(tmp_path, "grain.png", _grains())
    (tmp_path / "m.csv").write_text(
        "id,path,width_mm,material,relief_mm\n"
        "shallow,grain.png,50,cork,0.004\n"
        "deep,grain.png,50,cork,0.02\n"
        "typical,grain.png,50,cork,\n"
        "words,grain.png,50,cork,deep\n"
        "negative,grain.png,50,cork,-0.01\n")
    out = tmp_path / "cat"
    r = CliRunner().invoke(main, ["batch", str(tmp_path / "m.csv"), "--out", str(out), "--workers", "1", "--json"])
    assert r.exit_code == 0, r.output
    assert (json.loads(r.output)["ok"], json.loads(r.output)["failed"]) == (3, 2)
    rows = {row["id"]: row for row in read_catalog(out).to_dict("records")}
    assert rows["shallow"]["relief_rms_m"] == pytest.approx(0.004e-3)
    assert rows["deep"]["relief_rms_m"] == pytest.approx(0.02e-3)
    assert _missing(rows["typical"]["relief_rms_m"]) and rows["typical"]["material"] == "cork"
    p = "drive_60mm_s_"
    for key, rms in (("shallow", 0.004e-3), ("deep", 0.02e-3), ("typical", None)):
        drv = _steady_drive_of(path, "cork", rms)
        assert rows[key][p + "pulse_frequency_hz"] == pytest.approx(drv.pulse_frequency_hz)
        assert rows[key][p + "strength"] == pytest.approx(drv.strength)
    # The relief is heard: five times deeper plays stronger.
    assert rows["deep"][p + "strength"] > rows["shallow"][p + "strength"]
    for key, shown in (("words", "'deep'"), ("negative", "-0.01")):
        row = rows[key]
        assert row["status"] == "error" and "relief_mm" in row["error"] and shown in row["error"], row
        assert len(row["error"].splitlines()) == 1 and "mm" in row["error"]


def test_batch_material_and_relief_mm_apply_to_rows_without_their_own(tmp_path):
    pytest.importorskip("pyarrow")
    from tactilize.catalog import Catalog, read_catalog

    path = _save(tmp_path, "grain.png", _grains())
    (tmp_path / "m.jsonl").write_text("\n".join(json.dumps(r) for r in (
        {"id": "bare", "path": "grain.png", "width_mm": 50},
        {"id": "own-relief", "path": "grain.png", "width_mm": 50, "relief_mm": 0.03},
        {"id": "own-material", "path": "grain.png", "width_mm": 50, "material": "sandpaper-p80", "relief_mm": ""},
        {"id": "picture", "path": "grain.png", "width_mm": 50, "material": "picture only"},
    )) + "\n")
    out = tmp_path / "cat"
    r = CliRunner().invoke(main, ["batch", str(tmp_path / "m.jsonl"), "--out", str(out), "--workers", "1",
                                  "--material", "cork", "--relief-mm", "0.005", "--json"])
    assert r.exit_code == 0, r.output
    rows = {row["id"]: row for row in read_catalog(out).to_dict("records")}
    assert {k: v["material"] for k, v in rows.items()} == {
        "bare": "cork", "own-relief": "cork", "own-material": "sandpaper-p80", "picture": ""}
    assert {k: v["relief_rms_m"] for k, v in rows.items()} == pytest.approx({
        "bare": 0.005e-3, "own-relief": 0.03e-3, "own-material": 0.005e-3, "picture": 0.005e-3})
    cat = Catalog(out)
    for key, row in rows.items():
        drv = _steady_drive_of(path, row["material"] or None, row["relief_rms_m"])
        assert row["status"] == "ok" and row["drive_60mm_s_strength"] == pytest.approx(drv.strength)
        # What the API and the shop render for the row is what the batch stored.
        assert cat.drive(cat.get(key), 0.060).strength == pytest.approx(drv.strength)


def test_batch_without_relief_has_no_relief_column_and_resumes_an_older_catalog(tmp_path):
    pytest.importorskip("pyarrow")
    from tactilize.catalog import AnalysisSettings, read_catalog
    from tactilize.catalog.stores import META_FILE
    from tactilize.mapping import Profile

    _save(tmp_path, "grain.png", _grains())
    out = tmp_path / "cat"
    args = ["batch", str(tmp_path / "grain.png"), "--out", str(out), "--workers", "1", "--json"]
    assert CliRunner().invoke(main, args).exit_code == 0
    assert "relief_rms_m" not in read_catalog(out).columns
    # A catalogue's settings as written before relief was a column: a rerun resumes it.
    settings = json.loads((out / META_FILE).read_text())["settings"]
    assert settings == AnalysisSettings(Profile.resolve(None)).fingerprint()
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0 and json.loads(r.output)["skipped"] == 1, r.output
    # Given a relief now, its rows would have a column the catalogue has not: refused, one line.
    r = CliRunner().invoke(main, [*args, "--relief-mm", "0.01"])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and "relief_rms_m" in r.output, r.output


def test_batch_refuses_a_bad_relief_mm_or_material_in_one_line(tmp_path):
    _save(tmp_path, "grain.png", _grains())
    base = ["batch", str(tmp_path / "grain.png"), "--out", str(tmp_path / "cat"), "--workers", "1"]
    for extra, named in ((["--relief-mm", "-1"], "--relief-mm"), (["--relief-mm", "deep"], "--relief-mm"),
                         (["--relief-mm", "nan"], "--relief-mm"), (["--material", "graniet"], "stone-granite"),
                         (["--relief-mm", "0.01", "--profile", "paper"], "surface profile")):
        r = CliRunner().invoke(main, [*base, *extra])
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and named in r.output, (extra, r.output)
    assert not (tmp_path / "cat").exists()


def test_a_manifest_relief_needs_a_surface_profile(tmp_path):
    from tactilize.catalog import AnalysisSettings, analyse_item, discover
    from tactilize.mapping import Profile

    _save(tmp_path, "grain.png", _grains())
    (tmp_path / "m.jsonl").write_text(json.dumps({"path": "grain.png", "relief_mm": "0.01"}) + "\n")
    (item,) = discover(tmp_path / "m.jsonl")
    assert item.relief_rms_m == pytest.approx(1e-5) and item.material is None and item.problem is None
    row = analyse_item(item, AnalysisSettings(Profile.preset("paper"), relief_column=True))
    assert row["status"] == "error" and "surface profile" in row["error"] and row["relief_rms_m"] == item.relief_rms_m
