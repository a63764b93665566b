"""image.py: every Pillow mode, orientation, alpha, frames, pitch, and every bad input."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

import tactilize as tz
from tactilize.image import DEFAULT_DPI, METRES_PER_INCH


def _png_bytes(im: Image.Image, fmt: str = "PNG", **kw) -> bytes:
    buf = io.BytesIO()
    im.save(buf, format=fmt, **kw)
    return buf.getvalue()


RAMP = np.tile(np.arange(0, 256, 4, dtype=np.uint8), (16, 1))  # 16 x 64, known grey levels


@pytest.mark.parametrize(
    "mode, expected",
    [
        ("L", RAMP / 255.0),
        ("RGB", RAMP / 255.0),  # grey RGB: luma equals the grey level
        ("P", RAMP / 255.0),
        ("I;16", RAMP / 255.0),
        ("CMYK", RAMP / 255.0),
    ],
)
def test_modes_give_the_same_grey_levels(mode, expected, tmp_path):
    base = Image.fromarray(RAMP, "L")
    if mode == "I;16":
        im = Image.fromarray(RAMP.astype(np.uint16) * 257)
        assert im.mode.startswith("I;16")
        fmt = "PNG"
    elif mode == "CMYK":
        im = base.convert("RGB").convert("CMYK")
        fmt = "TIFF"
    else:
        im = base.convert(mode)
        fmt = "PNG"
    path = tmp_path / f"ramp.{fmt.lower()}"
    im.save(path, format=fmt)
    img = tz.load_image(path)
    assert img.pixels.dtype == np.float32
    assert img.shape == RAMP.shape
    np.testing.assert_allclose(img.pixels, expected, atol=1.5 / 255)


def test_mode_1_is_black_and_white(tmp_path):
    arr = np.zeros((8, 8), bool)
    arr[:, 4:] = True
    Image.fromarray(arr).convert("1").save(tmp_path / "bw.png")
    img = tz.load_image(tmp_path / "bw.png")
    assert set(np.unique(img.pixels)) == {0.0, 1.0}
    assert img.pixels[:, 4:].min() == 1.0 and img.pixels[:, :4].max() == 0.0


def test_modes_I_and_F_are_read(tmp_path):
    im_i = Image.fromarray(RAMP.astype(np.int32) * 257)
    assert im_i.mode == "I"
    im_i.save(tmp_path / "i.tif")
    img = tz.load_image(tmp_path / "i.tif")
    np.testing.assert_allclose(img.pixels, RAMP / 255.0, atol=2 / 255)
    im_f = Image.fromarray((RAMP / 255.0).astype(np.float32))
    im_f.save(tmp_path / "f.tif")
    np.testing.assert_allclose(tz.load_image(tmp_path / "f.tif").pixels, RAMP / 255.0, atol=1e-6)


@pytest.mark.parametrize("mode", ["RGBA", "LA"])
def test_transparent_pixels_are_white(mode):
    arr = np.zeros((4, 4, 4), np.uint8)  # black, fully transparent on the left
    arr[:, 2:, 3] = 255  # opaque black on the right
    im = Image.fromarray(arr, "RGBA")
    if mode == "LA":
        im = im.convert("LA")
    img = tz.load_image(_png_bytes(im))
    assert np.allclose(img.pixels[:, :2], 1.0)
    assert np.allclose(img.pixels[:, 2:], 0.0)


def test_exif_orientation_is_applied():
    arr = np.zeros((10, 20), np.uint8)
    arr[:, :5] = 255  # white band on the left of a landscape image
    im = Image.fromarray(arr, "L")
    exif = Image.Exif()
    exif[0x0112] = 6  # "rotate 90 CW to display"
    img = tz.load_image(_png_bytes(im, "JPEG", exif=exif.tobytes(), quality=95))
    assert img.shape == (20, 10)  # now portrait
    # rotating 90 degrees clockwise puts the left band at the top
    assert img.pixels[:4].mean() > 0.9 and img.pixels[-4:].mean() < 0.1


def test_first_frame_of_an_animation():
    frames = [Image.new("L", (8, 8), v) for v in (200, 20, 120)]
    buf = io.BytesIO()
    frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:], duration=50)
    img = tz.load_image(buf.getvalue())
    assert abs(float(img.pixels.mean()) - 200 / 255) < 2 / 255


def test_sources_path_bytes_fileobj_array_agree(tmp_path):
    im = Image.fromarray(RAMP, "L")
    path = tmp_path / "r.png"
    im.save(path)
    a = tz.load_image(path).pixels
    b = tz.load_image(path.read_bytes()).pixels
    with open(path, "rb") as fh:
        c = tz.load_image(fh).pixels
    d = tz.load_image(RAMP).pixels
    for other in (b, c, d):
        np.testing.assert_array_equal(a, other)


def test_rgb_array_uses_luma():
    arr = np.zeros((2, 2, 3), np.uint8)
    arr[..., 1] = 255  # pure green
    assert np.allclose(tz.load_image(arr).pixels, 0.587, atol=1e-6)


def test_pitch_precedence(tmp_path):
    im = Image.fromarray(RAMP, "L")
    path = tmp_path / "dpi.png"
    im.save(path, dpi=(300, 300))
    assert tz.load_image(path).pitch_m[0] == pytest.approx(METRES_PER_INCH / 300, rel=1e-3)
    assert tz.load_image(path, dpi=150).pitch_m[0] == pytest.approx(METRES_PER_INCH / 150)
    # width_mm: the 64-pixel-wide ramp shown 32 mm wide -> 0.5 mm pixels
    assert tz.load_image(path, width_mm=32).pitch_m == pytest.approx((5e-4, 5e-4))
    # dpi wins over width_mm
    assert tz.load_image(path, dpi=150, width_mm=32).pitch_m[0] == pytest.approx(METRES_PER_INCH / 150)
    # nothing known: a CSS pixel
    plain = tmp_path / "plain.png"
    im.save(plain)
    assert tz.load_image(plain).pitch_m[0] == pytest.approx(METRES_PER_INCH / DEFAULT_DPI)


# ---------------------------------------------------------------- bad input


def _write(path, data: bytes):
    path.write_bytes(data)
    return path


def _jpeg(tmp_path):
    im = Image.fromarray(np.random.default_rng(0).integers(0, 255, (64, 64), dtype=np.uint8), "L")
    p = tmp_path / "ok.jpg"
    im.save(p, quality=90)
    return p


@pytest.mark.parametrize(
    "make, fault",
    [
        (lambda tmp: tmp / "missing.png", "file not found"),
        (lambda tmp: _write(tmp / "empty.png", b""), "empty"),
        (lambda tmp: _write(tmp / "text.png", b"hello, not an image"), "not an image"),
        (lambda tmp: tmp, "directory"),
    ],
)
def test_bad_files_raise_image_error_naming_the_input(make, fault, tmp_path):
    path = make(tmp_path)
    with pytest.raises(tz.ImageError) as info:
        tz.load_image(path)
    assert fault in str(info.value)
    assert str(path) in str(info.value)


def test_truncated_file(tmp_path):
    good = _jpeg(tmp_path).read_bytes()
    bad = tmp_path / "cut.jpg"
    bad.write_bytes(good[: len(good) // 2])
    with pytest.raises(tz.ImageError, match="cut.jpg: .*(truncated|corrupt)"):
        tz.load_image(bad)


def test_truncated_png_bytes():
    data = _png_bytes(Image.fromarray(RAMP, "L"))
    with pytest.raises(tz.ImageError, match="<bytes>: .*(truncated|corrupt)"):
        tz.load_image(data[: len(data) - 30])


def test_pixel_limit_refuses_bombs_before_decoding():
    data = _png_bytes(Image.new("L", (2000, 2000)))
    with pytest.raises(tz.ImageError, match="too large"):
        tz.load_image(data, max_pixels=1_000_000)
    assert tz.load_image(data, max_pixels=4_000_000).shape == (2000, 2000)


def test_empty_bytes_and_zero_sized_arrays():
    with pytest.raises(tz.ImageError, match="empty"):
        tz.load_image(b"")
    with pytest.raises(tz.ImageError, match="empty"):
        tz.load_image(np.zeros((0, 5), np.float32))


def test_non_finite_float_images(tmp_path):
    arr = np.full((8, 8), 0.5, np.float32)
    arr[3, 3] = np.nan
    with pytest.raises(tz.ImageError, match="non-finite"):
        tz.load_image(arr)
    arr[3, 3] = np.inf
    Image.fromarray(arr).save(tmp_path / "inf.tif")
    with pytest.raises(tz.ImageError, match="inf.tif: .*non-finite"):
        tz.load_image(tmp_path / "inf.tif")


@pytest.mark.parametrize("kw", [{"dpi": 0}, {"dpi": -3}, {"dpi": float("nan")}, {"width_mm": 0}, {"width_mm": -1}])
def test_non_positive_dpi_or_width(kw):
    with pytest.raises(tz.ImageError, match="must be a positive number"):
        tz.load_image(RAMP, **kw)


def test_float_array_out_of_range():
    with pytest.raises(tz.ImageError, match=r"\[0, 1\]"):
        tz.load_image(np.full((4, 4), 2.0))


def test_colour_jpeg_luma_equals_pillows_grey_conversion():
    # load_image takes libjpeg's luma plane; it must equal Pillow's RGB -> L conversion.
    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:96, 0:128]
    rgb = np.stack([128 + 100 * np.sin(xx / 7.0), 128 + 80 * np.cos(yy / 5.0), rng.integers(0, 255, (96, 128))], -1)
    data = _png_bytes(Image.fromarray(rgb.astype(np.uint8)), "JPEG", quality=90)
    expected = np.asarray(Image.open(io.BytesIO(data)).convert("L"), dtype=np.float32) / 255.0
    np.testing.assert_allclose(tz.load_image(data).pixels, expected, atol=1.01 / 255)


def test_eight_bit_images_keep_their_levels_and_convert_on_demand():
    img = tz.load_image(_png_bytes(Image.fromarray(RAMP)), dpi=200)
    levels, scale = img.analysis_data()
    assert levels.dtype == np.uint8 and scale == pytest.approx(1 / 255)
    assert np.array_equal(levels, RAMP)
    # pixels: exactly the float decode (the same division), made once and kept
    assert img.pixels.dtype == np.float32
    assert np.array_equal(img.pixels, RAMP.astype(np.float32) / np.float32(255.0))
    assert img.pixels is img.pixels
    assert img.shape == RAMP.shape and img.width_m == pytest.approx(64 * METRES_PER_INCH / 200)
    # a uint8 array is copied: changing the caller's array changes nothing
    arr = RAMP.copy()
    from_array = tz.load_image(arr)
    arr[:] = 0
    assert np.array_equal(from_array.analysis_data()[0], RAMP)
    # float data stays float
    f = tz.load_image(RAMP / 255.0)
    assert f.analysis_data()[1] == 1.0 and f.analysis_data()[0].dtype == np.float32


def test_texture_image_is_immutable_and_pickles():
    import pickle

    img = tz.load_image(RAMP, dpi=150).with_source("ramp")
    with pytest.raises(AttributeError, match="immutable"):
        img.pitch_m = (1.0, 1.0)
    back = pickle.loads(pickle.dumps(img))
    assert back.source == "ramp" and back.pitch_m == img.pitch_m
    assert np.array_equal(back.pixels, img.pixels) and back.analysis_data()[0].dtype == np.uint8
    moved = img.with_pitch(1e-4)
    assert moved.pitch_m == (1e-4, 1e-4) and moved.analysis_data()[0] is img.analysis_data()[0]


def test_features_from_levels_equal_features_from_floats():
    from conftest import grating_array

    g8 = (grating_array((256, 320), 2000.0, 30.0, 300, noise=0.05) * 255).round().astype(np.uint8)
    from_levels = tz.extract_features(tz.load_image(g8, dpi=300))
    from_floats = tz.extract_features(tz.load_image(g8.astype(np.float32) / 255, dpi=300))
    for key, value in from_floats.to_dict().items():
        assert from_levels.to_dict()[key] == pytest.approx(value, rel=1e-5, abs=1e-7), key


# ---------------------------------------------------------------- reduced JPEG decode


def _grating_jpeg(path, h: int, w: int, *, dpi=None, orientation=None, mode="L"):
    rows, cols = np.mgrid[0:h, 0:w]
    grey = (127.5 + 100 * np.cos(2 * np.pi * (cols / 16.0 + rows / 32.0))).astype(np.uint8)
    im = Image.fromarray(grey, "L").convert(mode)
    kw = {"quality": 95}
    if dpi is not None:
        kw["dpi"] = (dpi, dpi)
    if orientation is not None:
        exif = Image.Exif()
        exif[0x0112] = orientation
        kw["exif"] = exif.tobytes()
    im.save(path, **kw)
    return path


@pytest.mark.parametrize(
    "file_dpi, orientation, kw, target_dpi, scale",
    [
        (600, None, {}, 150, 4),  # the file's DPI metadata
        (None, None, {}, 24, 4),  # no metadata: 96 DPI
        (None, None, {"dpi": 300}, 150, 2),  # an explicit dpi wins over the file's
        (600, None, {"width_mm": 21.67}, 150, 2),  # the whole width [mm] wins over the file's 600 DPI: 300 DPI
        # shown rotated, 128 px wide: 200 DPI, so 1/2 for 75 DPI (the stored 256 px width would say 1/4)
        (None, 6, {"width_mm": 16.256}, 75, 2),
        (600, None, {}, 37.5, 8),
        (600, None, {}, 400, 1),  # a target finer than twice the pitch: no reduction
    ],
)
def test_draft_decode_keeps_the_pitch_rule_of_a_full_decode(tmp_path, file_dpi, orientation, kw, target_dpi, scale):
    path = _grating_jpeg(tmp_path / "g.jpg", 128, 256, dpi=file_dpi, orientation=orientation, mode="RGB")
    full = tz.load_image(path, **kw)
    drafted = tz.load_image(path, draft_pitch_m=METRES_PER_INCH / target_dpi, **kw)
    assert full.decode_scale == 1 and drafted.decode_scale == scale
    assert drafted.shape == (-(-full.shape[0] // scale), -(-full.shape[1] // scale))
    # the picture keeps its displayed size: the same rule, applied to the file's full width
    assert drafted.width_m == pytest.approx(full.width_m, rel=1e-12)
    assert drafted.height_m == pytest.approx(full.height_m, rel=1e-12)
    assert drafted.pitch_m[0] == pytest.approx(scale * full.pitch_m[0], rel=1e-12)
    assert drafted.pitch_m[0] <= METRES_PER_INCH / target_dpi * (1 + 1e-9)
    if scale == 1:
        assert np.array_equal(drafted.analysis_data()[0], full.analysis_data()[0])
    else:
        # the same picture, averaged: within a few grey levels of the full decode averaged alike
        h, w = drafted.shape
        pooled = full.pixels[: h * scale, : w * scale].reshape(h, scale, w, scale).mean(axis=(1, 3))
        assert np.abs(drafted.pixels - pooled).mean() < 0.03


def test_draft_decode_limits(tmp_path):
    # a 40 px short side stops at 1/2 (20 px): 1/4 would leave fewer than 16 px
    small = _grating_jpeg(tmp_path / "small.jpg", 40, 80, dpi=600)
    assert tz.load_image(small, draft_pitch_m=METRES_PER_INCH / 37.5).decode_scale == 2
    # CMYK and grey JPEGs reduce too; other formats never do
    cmyk = _grating_jpeg(tmp_path / "cmyk.jpg", 128, 128, dpi=600, mode="CMYK")
    assert tz.load_image(cmyk, draft_pitch_m=METRES_PER_INCH / 150).shape == (32, 32)
    grey = _grating_jpeg(tmp_path / "grey.jpg", 128, 128, dpi=600, mode="L")
    assert tz.load_image(grey, draft_pitch_m=METRES_PER_INCH / 150).decode_scale == 4
    png = tmp_path / "g.png"
    Image.open(grey).save(png, dpi=(600, 600))
    drafted = tz.load_image(png, draft_pitch_m=METRES_PER_INCH / 150)
    assert drafted.decode_scale == 1 and drafted.shape == (128, 128)
    # the reduction survives renaming, re-pitching and pickling
    import pickle

    img = tz.load_image(grey, draft_pitch_m=METRES_PER_INCH / 150)
    assert pickle.loads(pickle.dumps(img.with_source("x").with_pitch(1e-4))).decode_scale == 4
    for bad in (0.0, -1e-4, float("nan")):
        with pytest.raises(tz.ImageError, match="draft_pitch_m"):
            tz.load_image(grey, draft_pitch_m=bad)
