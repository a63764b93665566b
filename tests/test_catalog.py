"""Batch catalogs: a generated shop of a few hundred pictures with corrupt files mixed in.

Every picture is made here in code (gratings at many frequencies, angles,
contrasts, modes and formats); the corrupt ones are the faults a real crawl
produces: random bytes, a truncated file, an empty file, a text file named
like an image, a manifest row with a bad width.
"""

from __future__ import annotations

from tactilize.mapping import DEFAULT_PRESET
from tactilize.surface.rendering import rendered_drive

import io
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from PIL import Image

from tactilize.catalog import (
    AnalysisSettings,
    Catalog,
    CatalogError,
    CatalogItem,
    TerminalProgress,
    analyse_item,
    discover,
    read_catalog,
    run_batch,
)
from tactilize.cli import main
from tactilize.errors import ImageError
from tactilize.features import extract_features
from tactilize.image import load_image
from tactilize.mapping import Profile
from tactilize.maps.texturemap import texture_map

N_GOOD = 280
SPEEDS_M_S = (0.03, 0.06, 0.12)


def _grating(h: int, w: int, period_px: float, angle_deg: float, contrast: float, seed: int) -> np.ndarray:
    rows, cols = np.mgrid[0:h, 0:w]
    t = math.radians(angle_deg)
    a = 0.5 + 0.5 * contrast * np.cos(2 * np.pi * (cols * math.cos(t) - rows * math.sin(t)) / period_px + seed)
    a += 0.03 * np.random.default_rng(seed).standard_normal(a.shape)
    return (np.clip(a, 0, 1) * 255).astype(np.uint8)


def _write_good(path: Path, i: int) -> None:
    h, w = (64, 96) if i % 3 else (96, 64)
    grey = _grating(h, w, 3.0 + (i % 17), (i * 37) % 180, 0.3 + 0.6 * ((i % 5) / 4), i)
    kind = i % 4
    if kind == 0:
        Image.fromarray(grey).save(path.with_suffix(".png"), dpi=(150, 150))
    elif kind == 1:
        Image.fromarray(np.stack([grey, grey // 2, 255 - grey], -1)).save(path.with_suffix(".jpg"), quality=92)
    elif kind == 2:
        Image.fromarray(grey).convert("P").save(path.with_suffix(".gif"))
    else:
        Image.fromarray(np.stack([grey, grey, grey, np.full_like(grey, 200)], -1)).save(path.with_suffix(".png"))


def _write_bad(folder: Path) -> dict[str, str]:
    """Corrupt files; returns {id: a word its error message must contain}."""
    rng = np.random.default_rng(7)
    (folder / "bad").mkdir()
    (folder / "bad" / "noise.jpg").write_bytes(rng.integers(0, 256, 3000, dtype=np.uint8).tobytes())
    (folder / "bad" / "empty.png").write_bytes(b"")
    (folder / "bad" / "text.png").write_text("this is not a picture\n")
    buf = io.BytesIO()
    Image.fromarray(_grating(96, 96, 5, 0, 0.8, 1)).save(buf, format="PNG")
    (folder / "bad" / "truncated.png").write_bytes(buf.getvalue()[: len(buf.getvalue()) // 2])
    buf = io.BytesIO()
    Image.fromarray(_grating(96, 96, 5, 30, 0.8, 2)).save(buf, format="JPEG")
    (folder / "bad" / "cut.jpg").write_bytes(buf.getvalue()[:200])
    (folder / "bad" / "folder.png").mkdir()  # a directory named like an image is not one
    return {
        "bad/noise.jpg": "not an image",
        "bad/empty.png": "empty",
        "bad/text.png": "not an image",
        "bad/truncated.png": "truncated",
        "bad/cut.jpg": "",
    }


@pytest.fixture(scope="module")
def shop(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    root = tmp_path_factory.mktemp("shop")
    for i in range(N_GOOD):
        sub = root / f"dept{i % 4}"
        sub.mkdir(exist_ok=True)
        _write_good(sub / f"item{i:04d}", i)
    (root / "README.txt").write_text("not an image: not listed")
    (root / ".hidden").mkdir()
    Image.fromarray(_grating(64, 64, 4, 0, 1, 0)).save(root / ".hidden" / "skip.png")
    bad = _write_bad(root)
    return root, bad


@pytest.fixture(scope="module")
def pooled(shop, tmp_path_factory) -> tuple[Path, object]:
    """The shop analysed once with two local processes."""
    root, _ = shop
    out = tmp_path_factory.mktemp("out") / "shop.parquet"
    summary = run_batch(root, out, workers=2, speeds_m_s=SPEEDS_M_S)
    return out, summary


def _strip(df):
    """Rows without the timing column, sorted by id: what must agree between engines."""
    return df.drop(columns=["seconds"]).sort_values("id").reset_index(drop=True)


# ------------------------------------------------------------------ sources


def test_discover_folder_lists_images_recursively_not_hidden_or_other_files(shop):
    root, bad = shop
    items = discover(root)
    ids = [it.id for it in items]
    assert len(ids) == N_GOOD + len(bad)
    assert ids == sorted(ids)
    assert "README.txt" not in ids and not any(i.startswith(".hidden") for i in ids)
    assert "bad/folder.png" not in ids
    assert all(Path(it.path).is_absolute() for it in items)


def test_discover_glob_ids_relative_to_literal_root(shop):
    root, _ = shop
    items = discover(str(root / "dept1" / "*.jpg"))
    assert items and all(it.id.endswith(".jpg") and "/" not in it.id for it in items)
    deep = discover(str(root / "**" / "*.gif"))
    assert deep and all(it.id.startswith("dept") for it in deep)


def test_discover_rejects_missing_and_empty_sources(tmp_path):
    with pytest.raises(CatalogError, match="not found"):
        discover(tmp_path / "nope")
    with pytest.raises(CatalogError, match="no image"):
        discover(tmp_path)
    with pytest.raises(CatalogError, match="matches no files"):
        discover(str(tmp_path / "*.jpg"))


def test_manifest_csv_and_jsonl(tmp_path):
    Image.fromarray(_grating(64, 64, 8, 0, 0.9, 3)).save(tmp_path / "a.png")
    Image.fromarray(_grating(64, 64, 8, 90, 0.9, 4)).save(tmp_path / "b.png")
    (tmp_path / "m.csv").write_text(
        "id,path,width_mm,dpi\nsku-1,a.png,32,\nsku-2,b.png,,254\nsku-3,a.png,abc,\nsku-4,missing.png,,\n"
    )
    items = {it.id: it for it in discover(tmp_path / "m.csv")}
    assert items["sku-1"].width_mm == 32 and items["sku-1"].path == str(tmp_path / "a.png")
    assert items["sku-2"].dpi == 254
    assert "not a number" in items["sku-3"].problem

    settings = AnalysisSettings(Profile.preset("paper"))
    row1 = analyse_item(items["sku-1"], settings)
    assert row1["status"] == "ok" and row1["width_mm"] == pytest.approx(32.0)
    # 32 mm over 64 px is 0.5 mm a pixel: a period of 8 px is 4 mm, 250 cycles/m
    assert row1["spatial_frequency_per_m"] == pytest.approx(250.0, rel=1e-3)
    row2 = analyse_item(items["sku-2"], settings)
    assert row2["pitch_m"] == pytest.approx(1e-4)
    row3 = analyse_item(items["sku-3"], settings)
    assert row3["status"] == "error" and "width_mm" in row3["error"]
    row4 = analyse_item(items["sku-4"], settings)
    assert row4["status"] == "error" and "not found" in row4["error"]

    (tmp_path / "m.jsonl").write_text(
        json.dumps({"id": 17, "path": "a.png", "dpi": 127}) + "\n\n" + json.dumps({"path": str(tmp_path / "b.png")}) + "\n"
    )
    items = {it.id: it for it in discover(tmp_path / "m.jsonl")}
    assert sorted(items) == sorted(["17", str(tmp_path / "b.png")])  # no id: the path is the id
    assert items["17"].dpi == 127

    (tmp_path / "dup.csv").write_text("id,path\nx,a.png\nx,b.png\n")
    with pytest.raises(CatalogError, match="duplicate id"):
        discover(tmp_path / "dup.csv")
    (tmp_path / "broken.jsonl").write_text('{"path": "a.png"}\n{oops\n')
    with pytest.raises(CatalogError, match="broken.jsonl:2"):
        discover(tmp_path / "broken.jsonl")


# ------------------------------------------------------------------ the rows


def test_every_good_image_has_a_correct_row_and_every_bad_one_its_reason(shop, pooled):
    root, bad = shop
    out, summary = pooled
    assert (summary.total, summary.ok, summary.failed, summary.skipped) == (N_GOOD + len(bad), N_GOOD, len(bad), 0)
    df = read_catalog(out)
    assert len(df) == N_GOOD + len(bad) and df["id"].is_unique
    rows = {r["id"]: r for r in df.to_dict("records")}
    # The batch renders as every other command does by default (the surface rendering).
    profile = Profile.preset(DEFAULT_PRESET)

    for ident, word in bad.items():
        row = rows[ident]
        assert row["status"] == "error"
        with pytest.raises(ImageError) as exc:  # the loader's own reason, word for word
            load_image(root / ident)
        assert row["error"] == exc.value.fault and word in row["error"]

    good = [r for r in rows.values() if r["id"] not in bad]
    assert len(good) == N_GOOD
    for row in good:
        img = load_image(row["path"])
        feat = extract_features(img)
        assert row["status"] == "ok" and pd.isna(row["error"])
        assert (row["width_px"], row["height_px"], row["decode_scale"]) == (img.shape[1], img.shape[0], 1)
        assert row["pitch_m"] == pytest.approx(img.pitch_m[0], rel=1e-12)
        for key, value in feat.to_dict().items():
            if key == "pitch_m":
                continue
            assert row[key] == pytest.approx(value, rel=1e-9, abs=1e-12), (row["id"], key)
        for key, value in texture_map(img, sample_px="auto").summary().items():
            assert row[f"map_{key}"] == pytest.approx(value, rel=1e-9, abs=1e-12), (row["id"], key)
        for speed, label in zip(SPEEDS_M_S, ("30", "60", "120")):
            drv = rendered_drive(profile, img, feat, speed)
            assert row[f"drive_{label}mm_s_pulse_frequency_hz"] == pytest.approx(drv.pulse_frequency_hz, rel=1e-9)
            assert row[f"drive_{label}mm_s_pulse_width_s"] == pytest.approx(drv.pulse_width_s, rel=1e-9)
            assert row[f"drive_{label}mm_s_clamped"] == ",".join(drv.clamped)
    # PNGs saved at 150 dpi keep their pitch; the others fall back to 96 dpi
    png150 = rows["dept0/item0000.png"]
    assert png150["pitch_m"] == pytest.approx(0.0254 / 150, rel=1e-3)  # PNG stores whole pixels per metre


def test_rerun_skips_everything_done(shop, pooled):
    root, bad = shop
    out, _ = pooled
    parts_before = sorted(p.name for p in out.glob("part-*.parquet"))
    again = run_batch(root, out, workers=2, speeds_m_s=SPEEDS_M_S)
    assert (again.ok, again.failed, again.skipped) == (0, 0, N_GOOD + len(bad))
    assert sorted(p.name for p in out.glob("part-*.parquet")) == parts_before


def test_interrupted_batch_keeps_its_rows_and_resumes(shop, pooled, tmp_path):
    root, bad = shop
    items = discover(root)[:90]
    out = tmp_path / "crash.parquet"
    calls = []

    def crash(done, total, failed):
        calls.append(done)
        if len(calls) == 4:
            raise KeyboardInterrupt  # as if the user pressed Ctrl-C mid-batch

    with pytest.raises(KeyboardInterrupt):
        run_batch(items, out, workers=1, chunk_size=10, part_rows=25, progress=crash, speeds_m_s=SPEEDS_M_S)
    kept = read_catalog(out)
    assert len(kept) == 40  # the rows finished before the interrupt were written, none lost
    resumed = run_batch(items, out, workers=2, speeds_m_s=SPEEDS_M_S)
    assert resumed.skipped == 40 and resumed.ok + resumed.failed == 50
    full = _strip(read_catalog(out))
    reference = _strip(read_catalog(pooled[0]))
    assert full.equals(reference[reference["id"].isin(full["id"])].reset_index(drop=True))


def test_retry_failed_replaces_error_rows(tmp_path):
    (tmp_path / "src").mkdir()
    Image.fromarray(_grating(64, 64, 6, 0, 0.9, 5)).save(tmp_path / "src" / "a.png")
    (tmp_path / "src" / "b.png").write_bytes(b"garbage")
    for out in (tmp_path / "c.parquet", f"sqlite:///{tmp_path / 'c.db'}"):
        first = run_batch(tmp_path / "src", out, workers=1)
        assert (first.ok, first.failed) == (1, 1)
        Image.fromarray(_grating(64, 64, 6, 45, 0.9, 6)).save(tmp_path / "src" / "b.png")
        assert run_batch(tmp_path / "src", out, workers=1).skipped == 2  # errors count as done...
        fixed = run_batch(tmp_path / "src", out, workers=1, retry_failed=True)  # ...unless asked
        assert (fixed.ok, fixed.failed, fixed.skipped) == (1, 0, 1)
        df = read_catalog(out)
        assert len(df) == 2 and set(df["status"]) == {"ok"}
        (tmp_path / "src" / "b.png").write_bytes(b"garbage")


def test_a_worker_that_dies_costs_error_rows_not_the_batch(shop, tmp_path, monkeypatch):
    import os

    import tactilize.catalog.analysis as analysis

    root, bad = shop
    items = [it for it in discover(root) if it.id not in bad][:24]
    victim = items[5].id
    real = analysis.analyse_item

    def fragile(item, settings):
        if item.id == victim:
            os._exit(3)  # what the OOM killer does to a worker decoding a huge image
        return real(item, settings)

    # The pool forks after this, so its workers inherit the patched function.
    monkeypatch.setattr(analysis, "analyse_item", fragile)
    summary = run_batch(items, tmp_path / "die.parquet", workers=2, chunk_size=2)
    df = read_catalog(tmp_path / "die.parquet")
    assert len(df) == len(items) == summary.ok + summary.failed
    dead = df[df["status"] == "error"]
    assert victim in set(dead["id"]) and all("worker process died" in e for e in dead["error"])
    assert summary.ok >= len(items) // 2  # the pool was replaced and the rest went on


def test_other_settings_on_the_same_output_are_refused(shop, pooled):
    root, _ = shop
    with pytest.raises(CatalogError, match="profile"):
        run_batch(root, pooled[0], profile="physical", speeds_m_s=SPEEDS_M_S)
    with pytest.raises(CatalogError, match="speeds_m_s"):
        run_batch(root, pooled[0], speeds_m_s=(0.05,))


# ------------------------------------------------------------------ engines and stores


def test_process_pool_and_dask_local_cluster_give_the_same_rows(shop, pooled, tmp_path):
    distributed = pytest.importorskip("distributed")
    root, _ = shop
    items = discover(root)[::3]  # every third item: the same mix, a third of the time
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        summary = run_batch(items, tmp_path / "dask.parquet", scheduler=cluster.scheduler_address, speeds_m_s=SPEEDS_M_S)
    assert summary.ok + summary.failed == len(items)
    dask_rows = _strip(read_catalog(tmp_path / "dask.parquet"))
    pool_rows = _strip(read_catalog(pooled[0]))
    pool_rows = pool_rows[pool_rows["id"].isin(dask_rows["id"])].reset_index(drop=True)
    assert len(pool_rows) == len(items)
    assert dask_rows.drop(columns=["path"]).equals(pool_rows.drop(columns=["path"]))


def test_unreachable_scheduler_is_a_one_line_error(tmp_path, shop):
    root, _ = shop
    with pytest.raises(CatalogError, match="Dask scheduler"):
        run_batch(discover(root)[:3], tmp_path / "x.parquet", scheduler="tcp://127.0.0.1:9", scheduler_timeout_s=1)


def test_sql_output_matches_parquet(shop, pooled, tmp_path):
    root, _ = shop
    items = discover(root)[::10]
    url = f"sqlite:///{tmp_path / 'shop.db'}"
    summary = run_batch(items, url, workers=1, speeds_m_s=SPEEDS_M_S)
    assert summary.ok + summary.failed == len(items)
    assert run_batch(items, url, workers=1, speeds_m_s=SPEEDS_M_S).skipped == len(items)
    sql = _strip(read_catalog(url))
    ref = _strip(read_catalog(pooled[0]))
    ref = ref[ref["id"].isin(sql["id"])].reset_index(drop=True)
    assert list(sql["id"]) == list(ref["id"])
    ok = ref["status"] == "ok"
    for col in ("spatial_frequency_per_m", "spectral_intensity", "map_grid_rows", "drive_60mm_s_pulse_frequency_hz"):
        assert np.allclose(sql.loc[ok, col].astype(float), ref.loc[ok, col].astype(float), rtol=1e-12)
    assert list(sql["error"].fillna("")) == list(ref["error"].fillna(""))


def test_catalog_reader(shop, pooled):
    _, bad = shop
    cat = Catalog(pooled[0])
    assert cat.counts() == {"total": N_GOOD + len(bad), "ok": N_GOOD, "failed": len(bad)}
    assert cat.profile.name == DEFAULT_PRESET and cat.speeds_m_s == SPEEDS_M_S
    row = cat.get("dept1/item0001.jpg")
    assert row["status"] == "ok" and isinstance(row["width_px"], int)
    stored = dict(cat.stored_drives(row))
    assert cat.drive(row, 0.06) == stored[0.06]
    assert cat.get("bad/empty.png")["width_px"] is None
    assert cat.get("nope") is None
    assert cat.ids(limit=2, status="error") == sorted(bad)[:2]


# ------------------------------------------------------------------ decode at reduced size


def test_draft_decode_reduces_jpeg_resolution_within_the_target_pitch(tmp_path):
    grey = _grating(512, 512, 16, 0, 0.9, 8)
    Image.fromarray(grey).save(tmp_path / "big.jpg", quality=95, dpi=(600, 600))
    Image.fromarray(grey).save(tmp_path / "big.png", dpi=(600, 600))
    item = CatalogItem("big", str(tmp_path / "big.jpg"))
    full = analyse_item(item, AnalysisSettings())
    # analysis at no coarser than 150 dpi: the 600 dpi JPEG decodes at 1/4 size
    reduced = analyse_item(item, AnalysisSettings(analysis_pitch_m=0.0254 / 150))
    assert full["decode_scale"] == 1 and reduced["decode_scale"] == 4
    assert reduced["width_px"] == 128 and reduced["width_mm"] == pytest.approx(full["width_mm"])
    assert reduced["pitch_m"] == pytest.approx(4 * full["pitch_m"])
    # the physical spatial frequency survives; the size-dependent intensity does not
    assert reduced["spatial_frequency_per_m"] == pytest.approx(full["spatial_frequency_per_m"], rel=0.01)
    assert reduced["spectral_intensity"] < full["spectral_intensity"]
    # a target finer than twice the pitch, and non-JPEGs, decode in full
    luma = analyse_item(item, AnalysisSettings(analysis_pitch_m=0.0254 / 400))
    assert luma["decode_scale"] == 1 and luma["width_px"] == 512
    # full size, luma only: the stored Y channel is within a grey level of RGB -> L
    assert luma["spatial_frequency_per_m"] == pytest.approx(full["spatial_frequency_per_m"], rel=1e-4)
    assert luma["contrast"] == pytest.approx(full["contrast"], rel=0.01)
    png = analyse_item(CatalogItem("p", str(tmp_path / "big.png")), AnalysisSettings(analysis_pitch_m=0.0254 / 150))
    assert png["decode_scale"] == 1 and png["width_px"] == 512
    # a corrupt JPEG still gets the loader's own reason with draft mode on
    (tmp_path / "bad.jpg").write_bytes(b"\xff\xd8\xff" + b"x" * 50)
    bad = analyse_item(CatalogItem("b", str(tmp_path / "bad.jpg")), AnalysisSettings(analysis_pitch_m=0.0254 / 150))
    assert bad["status"] == "error" and bad["error"]


# ------------------------------------------------------------------ CLI and progress


def test_cli_batch_json_summary_and_bad_input(shop, tmp_path):
    root, bad = shop
    runner = CliRunner()
    src = root / "dept2"
    res = runner.invoke(main, ["batch", str(src), "--out", str(tmp_path / "c.parquet"), "--workers", "1", "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    n = len(list(src.iterdir()))
    assert doc["total"] == n and doc["ok"] == n and doc["failed"] == 0 and doc["skipped"] == 0 and doc["seconds"] > 0
    res = runner.invoke(main, ["batch", str(src), "--out", str(tmp_path / "c.parquet"), "--workers", "1", "--json"])
    assert json.loads(res.stdout)["skipped"] == n
    res = runner.invoke(main, ["batch", str(tmp_path / "missing"), "--out", str(tmp_path / "d.parquet")])
    assert res.exit_code == 2 and "not found" in res.stderr and "Traceback" not in res.stderr
    res = runner.invoke(main, ["batch", str(src), "--out", str(tmp_path / "e.parquet"), "--profile", "nonsense"])
    assert res.exit_code == 2 and "nonsense" in res.stderr


class _FakeTTY(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_only_on_a_terminal():
    pipe = io.StringIO()
    bar = TerminalProgress(pipe)
    bar(5, 10, 0)
    bar.close()
    assert pipe.getvalue() == ""
    tty = _FakeTTY()
    bar = TerminalProgress(tty, min_interval_s=0.0)
    bar(5, 10, 1)
    bar(10, 10, 1)
    bar.close()
    text = tty.getvalue()
    assert "10/10" in text and "img/s" in text and "ETA" in text and "1 failed" in text and text.endswith("\n")


def test_map_tiles_sampled_by_default_and_whole_on_request(tmp_path):
    # 768 x 1024 pictures have 128 px tiles: sampled on their centred 64 px by default
    src = tmp_path / "big"
    src.mkdir()
    for i, period in enumerate((6.0, 11.0, 20.0)):
        g = _grating(768, 1024, period, 25.0 * i, 0.5, seed=i)
        Image.fromarray(g).save(src / f"g{i}.png")
    fast = run_batch(src, tmp_path / "fast.parquet", workers=1, speeds_m_s=SPEEDS_M_S)
    full = run_batch(src, tmp_path / "full.parquet", workers=1, speeds_m_s=SPEEDS_M_S, full_map=True)
    assert fast.ok == full.ok == 3
    a = read_catalog(tmp_path / "fast.parquet").set_index("id").sort_index()
    b = read_catalog(tmp_path / "full.parquet").set_index("id").sort_index()
    pitch_mm = 25.4 / 96
    assert np.allclose(a["map_sample_mm"], 64 * pitch_mm) and np.allclose(b["map_sample_mm"], 128 * pitch_mm)
    assert np.allclose(a["map_tile_mm"], b["map_tile_mm"])
    for key in ("spatial_frequency_per_m_median", "spatial_frequency_per_m_min", "spatial_frequency_per_m_max"):
        assert np.allclose(a[f"map_{key}"], b[f"map_{key}"], rtol=0.01), key
    assert np.allclose(a["map_spectral_intensity_median"], b["map_spectral_intensity_median"], atol=0.005)
    # the whole-image features do not depend on it
    assert np.array_equal(a["spatial_frequency_per_m"], b["spatial_frequency_per_m"])
    # and a catalog made one way is not continued the other
    with pytest.raises(CatalogError, match="full_map"):
        run_batch(src, tmp_path / "fast.parquet", workers=1, speeds_m_s=SPEEDS_M_S, full_map=True)


# ------------------------------------------------------------------ versions


def test_every_row_and_the_fingerprint_carry_the_versions(shop, pooled):
    import tactilize
    from tactilize.catalog import ANALYSIS_VERSION, FORMAT_VERSION

    _, bad = shop
    df = read_catalog(pooled[0])
    assert set(df["tactilize_version"]) == {tactilize.__version__}
    assert set(df["analysis_version"]) == {ANALYSIS_VERSION}
    assert df.loc[df["id"].isin(list(bad)), "analysis_version"].notna().all()  # error rows too
    settings = json.loads((pooled[0] / "_catalog.json").read_text())["settings"]
    assert (settings["format"], settings["tactilize"], settings["analysis"]) == (4, tactilize.__version__, ANALYSIS_VERSION)
    assert FORMAT_VERSION == 4  # 4: every row has `material`; fc1de98 changed mean_level and i_s (format 2 before it)


def _as_previous_version(settings: dict, **versions) -> dict:
    """The fingerprint the previous version wrote: format 2, no versions recorded."""
    old = {k: v for k, v in settings.items() if k not in ("tactilize", "analysis")}
    old["format"] = 2
    old.update(versions)
    return old


def test_a_catalog_of_another_version_is_refused_with_one_line(tmp_path):
    import sqlite3

    import pyarrow.parquet as pq

    from tactilize.catalog import CatalogVersionError

    src = tmp_path / "src"
    src.mkdir()
    for i in range(3):
        Image.fromarray(_grating(64, 64, 5 + i, 30 * i, 0.8, i)).save(src / f"p{i}.png")
    out = tmp_path / "old.parquet"
    run_batch(list(discover(src))[:2], out, workers=1)
    # What the previous version left: its fingerprint and rows without version columns.
    meta = out / "_catalog.json"
    settings = json.loads(meta.read_text())["settings"]
    meta.write_text(json.dumps({"settings": _as_previous_version(settings)}))
    for part in out.glob("part-*.parquet"):
        pq.write_table(pq.read_table(part).drop(["tactilize_version", "analysis_version"]), part)
    parts_before = sorted((p.name, p.stat().st_mtime_ns) for p in out.glob("part-*.parquet"))

    with pytest.raises(CatalogVersionError) as exc:
        run_batch(src, out, workers=1)
    message = str(exc.value)
    assert "\n" not in message and message.startswith(str(out))
    assert "did not record its version" in message and "catalog format 2" in message and "--out" in message
    assert isinstance(exc.value, CatalogError)  # callers that catch CatalogError still do
    assert sorted((p.name, p.stat().st_mtime_ns) for p in out.glob("part-*.parquet")) == parts_before  # nothing added

    # The command line: one line on stderr, exit 2, no traceback.
    res = CliRunner().invoke(main, ["batch", str(src), "--out", str(out), "--workers", "1"])
    assert res.exit_code == 2 and "Traceback" not in res.stderr
    assert res.stderr.strip().count("\n") == 0 and "was written by" in res.stderr

    # Another tactilize release, or the same one with another analysis, is refused alike.
    import tactilize

    for versions, named in (({"tactilize": "0.0.9", "analysis": 2}, "tactilize 0.0.9"), ({"analysis": 1}, "analysis 1")):
        meta.write_text(json.dumps({"settings": _as_previous_version(settings, format=3, **versions)}))
        with pytest.raises(CatalogVersionError, match=named):
            run_batch(src, out, workers=1)
    assert tactilize.__version__ != "0.0.9"

    # Reading an old catalog still works: only adding to it is refused.
    assert len(read_catalog(out)) == 2 and Catalog(out).counts()["ok"] == 2

    # An SQL catalog written by the previous version.
    db = tmp_path / "old.db"
    run_batch(list(discover(src))[:2], f"sqlite:///{db}", workers=1)
    with sqlite3.connect(db) as conn:
        conn.execute("UPDATE catalog_meta SET value = ? WHERE key = 'settings'", (json.dumps(_as_previous_version(settings)),))
    with pytest.raises(CatalogVersionError, match="did not record its version"):
        run_batch(src, f"sqlite:///{db}", workers=1)
    assert len(read_catalog(f"sqlite:///{db}")) == 2
