"""A shop's catalogue as a static site: a product grid, a page per product, the surface models, one ES module.

:func:`build_site` reads a catalogue source the way ``tactilize batch`` does
(:func:`tactilize.catalog.sources.discover`: a folder, a glob or a manifest), and
writes a folder any web server hosts (docs/shop.md):

* ``index.html``: every product as a card, its photo strokable in place;
* ``p/<slug>.html``: one page per product;
* ``models/<slug>.tsf``: the surface model (:mod:`.model_file`);
* ``img/<slug>.jpg``: the photo as shown;
* ``tactile-surface.js`` and the modules it imports: the ``<tactile-surface>`` element,
  the surface rule in JavaScript, the phone's motor and the audio wavelets.

The model is made at the resolution the page renders at: the picture is averaged down
to at most ``model_px`` pixels on its long side (about one model pixel per CSS pixel of a
phone-wide element; a finger's samples address the picture no finer), keeping its real
size, then seen through the stylus tip as :func:`tactilize.surface.model.surface_model`
does.  A model whose file would pass ``max_model_bytes`` is made again at 85 % of the
resolution until it fits.

A product of a material (a manifest's or a catalogue row's ``material``, docs/surfaces.md,
"Materials") is rendered as ``--material`` renders its picture: the relief scale is the whole
picture's (:func:`tactilize.materials.relief_for` at its own resolution, as the server's
surface has it), and the averaged picture is seen through the tip and the material's contact
at that scale, so its heights are the server's in metres; the micro-roughness goes into the
model file as parameters (:mod:`.model_file`).

Units: SI (m); sizes in bytes.
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..catalog.sources import CatalogItem, discover
from ..errors import CatalogError, TactilizeError
from ..image import load_image
from ..materials import MaterialChoice, relief_for
from ..surface.model import TIP_RADIUS_M, surface_model
from .model_file import encode_model

__all__ = ["build_site", "model_bytes", "SiteSummary", "MODEL_PX", "PHOTO_PX", "MAX_MODEL_BYTES", "STATIC_DIR", "static_files"]

#: Long side of a model [px]: about a phone-wide element's CSS pixels (docs/shop.md).
MODEL_PX = 384
#: Long side of the photo shown [px]: sharp on a phone's 2.6 to 3 device pixels per CSS pixel.
PHOTO_PX = 1024
#: Products whose model is written into the product grid's page itself (each product page holds its own).
INLINE_MODELS = 1
#: A model file is made smaller until it is at most this big [bytes].
MAX_MODEL_BYTES = 64 * 1024
#: This package's page modules.
STATIC_DIR = Path(__file__).with_name("static")
#: The pen page's modules the element imports as they are (one copy of each rule in JavaScript).
_WEB_STATIC = Path(__file__).resolve().parent.parent / "web" / "static"
_SHARED = ("vibrate.js", "pulse-worklet.js", "pen-input.js")


def static_files() -> list[Path]:
    """Every file the element needs, in the order they are copied."""
    own = sorted(p for p in STATIC_DIR.iterdir() if p.suffix in (".js", ".css"))
    return own + [_WEB_STATIC / name for name in _SHARED]


@dataclass
class SiteSummary:
    """What :func:`build_site` wrote: products, failures (id, reason), model sizes [bytes]."""

    out: Path
    products: list[dict[str, Any]] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)

    @property
    def largest_model_bytes(self) -> int:
        return max((p["model_bytes"] for p in self.products), default=0)


def _slug(ident: str) -> str:
    base = re.sub(r"[^A-Za-z0-9]+", "-", ident).strip("-").lower()[:48] or "product"
    return f"{base}-{hashlib.sha1(ident.encode('utf-8')).hexdigest()[:6]}"


def _downsampled(pixels: np.ndarray, pitch: tuple[float, float], long_px: int) -> tuple[np.ndarray, tuple[float, float]]:
    """``pixels`` averaged down to at most ``long_px`` on the long side, and the pitch [m] of the result."""
    from PIL import Image

    rows, cols = pixels.shape
    f = long_px / max(rows, cols)
    if f >= 1.0:
        return pixels, pitch
    nc, nr = max(1, round(cols * f)), max(1, round(rows * f))
    img = Image.fromarray(np.ascontiguousarray(pixels, dtype=np.float32), mode="F")
    small = np.asarray(img.resize((nc, nr), Image.Resampling.BOX), dtype=np.float32)
    return small, (pitch[0] * cols / nc, pitch[1] * rows / nr)


def model_bytes(pixels: np.ndarray, pitch: tuple[float, float], *, model_px: int = MODEL_PX,
                max_bytes: int = MAX_MODEL_BYTES, tip_radius_m: float = TIP_RADIUS_M,
                material: MaterialChoice | str | None = None, product_id: str | None = None) -> bytes:
    """The model file of a picture (grey levels 0 .. 1 at ``pitch`` [m]) at the page's resolution,
    at most ``max_bytes`` long.

    Parameters
    ----------
    material : MaterialChoice or str, optional
        What the picture is rendered as (a library name, or a choice with its relief); None or
        ``"picture only"``: the picture alone, heights in luminance units.

    Raises
    ------
    MaterialError
        An unknown material name.
    """
    choice = material if isinstance(material, MaterialChoice) else MaterialChoice.of(material)
    kw: dict[str, Any] = {}
    if not choice.picture_only:
        # The whole picture's relief scale: averaging it down must not deepen its relief.
        relief = relief_for(pixels, pitch, choice.material, relief_rms_m=choice.relief_rms_m)
        assert relief is not None
        kw = {"material": choice.material, "relief_scale_m": relief.scale_m}
    label = None if choice.picture_only else choice.label()
    long_px = model_px
    while True:
        small, p = _downsampled(pixels, pitch, long_px)
        data = encode_model(surface_model(small, pitch_m=p, tip_radius_m=tip_radius_m, **kw),
                            product_id=product_id, rendered_as=label)
        if len(data) <= max_bytes or long_px <= 16:
            return data
        long_px = int(long_px * 0.85)


def _photo(path: str, out: Path, photo_px: int) -> tuple[int, int]:
    from PIL import Image, ImageOps

    with Image.open(path) as opened:
        im = ImageOps.exif_transpose(opened).convert("RGB")
        im.thumbnail((photo_px, photo_px), Image.Resampling.LANCZOS)
        im.save(out, "JPEG", quality=82, optimize=True, progressive=True)
        return im.size


_PAGE_HEAD = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<link rel="icon" href="data:,">
{preload}<link rel="stylesheet" href="{root}shop.css">
<script type="module" src="{root}tactile-surface.js"></script>
<link rel="modulepreload" href="{root}surface-rule.js">
<link rel="modulepreload" href="{root}pen-input.js">
<link rel="modulepreload" href="{root}vibrate.js">
</head>
<body>
"""


def _card(p: dict[str, Any], root: str, link: bool, inline: bytes | None = None) -> str:
    name = html.escape(p["id"])
    material = f'<p class="material">{html.escape(p["material"])}</p>' if p.get("material") else ""
    title = f'<a href="{root}p/{p["slug"]}.html">{name}</a>' if link else name
    # The model in the page itself: decoded as the element is made, before the load event.
    held = ("" if inline is None else
            f'<script type="application/octet-stream">{base64.b64encode(inline).decode("ascii")}</script>')
    return (f'<article class="product">\n<tactile-surface model="{root}models/{p["slug"]}.tsf" '
            f'image="{root}img/{p["slug"]}.jpg" label="{name}">{held}</tactile-surface>\n'
            f'<h2>{title}</h2>\n{material}\n<p class="size">{p["width_mm"]:.0f} x {p["height_mm"]:.0f} mm</p>\n'
            '</article>\n')


def _preload(products: list[dict[str, Any]], root: str) -> str:
    return "".join(f'<link rel="preload" href="{root}models/{p["slug"]}.tsf" as="fetch" crossorigin>\n' for p in products)


def _write_pages(out: Path, products: list[dict[str, Any]], title: str) -> None:
    # The first product's model is in the page (a phone's first screen shows one card); the
    # next ones' load with the page, not after its first layout.
    def held(p: dict[str, Any]) -> bytes:
        return (out / "models" / f"{p['slug']}.tsf").read_bytes()

    head = _PAGE_HEAD.format(title=html.escape(title), root="", preload=_preload(products[INLINE_MODELS:4], ""))
    cards = "".join(_card(p, "", True, held(p) if i < INLINE_MODELS else None) for i, p in enumerate(products))
    (out / "index.html").write_text(
        head + f"<header><h1>{html.escape(title)}</h1><p>Press and drag on a photo to feel it.</p></header>\n"
        f'<main class="grid">\n{cards}</main>\n</body>\n</html>\n', encoding="utf-8")
    (out / "p").mkdir(exist_ok=True)
    for p in products:
        page = _PAGE_HEAD.format(title=html.escape(p["id"]), root="../", preload="")
        (out / "p" / f"{p['slug']}.html").write_text(
            page + f'<header><a href="../index.html">All products</a></header>\n<main class="one">\n'
            f'{_card(p, "../", False, held(p))}</main>\n</body>\n</html>\n', encoding="utf-8")


def build_site(source: str, out: str | Path, *, title: str = "Products", model_px: int = MODEL_PX,
               photo_px: int = PHOTO_PX, max_model_bytes: int = MAX_MODEL_BYTES,
               progress: Callable[[str], None] | None = None) -> SiteSummary:
    """Write the static site of a catalogue source.

    Parameters
    ----------
    source : str
        A folder, glob or manifest (``.csv``/``.jsonl``), as ``tactilize batch`` takes;
        a manifest's ``width_mm``/``dpi`` set the real size, its ``material`` what the picture is
        rendered as (the product's heights in metres, its hardness and micro-roughness).
    out : str or path
        The folder to write (made if missing; files it already holds are replaced).
    model_px, photo_px : int
        Long side of the models and of the photos shown [px].
    max_model_bytes : int
        Largest model file [bytes].

    Returns
    -------
    SiteSummary

    Raises
    ------
    CatalogError
        The source cannot be read, or the output is not a folder that can be written.
    """
    items = discover(source)
    # discover() has checked each row's material and relief: a bad one is that product's problem.
    choices = {it.id: MaterialChoice.of(it.material, it.relief_rms_m) for it in items if not it.problem}
    return _build(items, choices, out, title=title, model_px=model_px, photo_px=photo_px,
                  max_model_bytes=max_model_bytes, progress=progress)


def _build(items: list[CatalogItem], choices: dict[str, MaterialChoice], out: str | Path, *, title: str,
           model_px: int, photo_px: int, max_model_bytes: int,
           progress: Callable[[str], None] | None) -> SiteSummary:
    target = Path(out)
    if target.exists() and not target.is_dir():
        raise CatalogError(str(target), "exists and is not a folder")
    try:
        for sub in ("models", "img"):
            (target / sub).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CatalogError(str(target), f"cannot write ({exc.strerror or exc.__class__.__name__})") from None
    summary = SiteSummary(target)
    for item in items:
        if item.problem:
            summary.failed.append((item.id, item.problem))
            continue
        try:
            img = load_image(item.path, dpi=item.dpi, width_mm=item.width_mm)
        except TactilizeError as exc:
            summary.failed.append((item.id, exc.fault))
            continue
        slug = _slug(item.id)
        choice = choices.get(item.id, MaterialChoice())
        data = model_bytes(img.pixels, img.pitch_m, model_px=model_px, max_bytes=max_model_bytes,
                           material=choice, product_id=item.id)
        (target / "models" / f"{slug}.tsf").write_bytes(data)
        _photo(item.path, target / "img" / f"{slug}.jpg", photo_px)
        rows, cols = img.pixels.shape
        summary.products.append({
            "id": item.id, "slug": slug, "material": choice.name, "rendered_as": choice.label(),
            "model_bytes": len(data),
            "width_mm": cols * img.pitch_m[0] * 1e3, "height_mm": rows * img.pitch_m[1] * 1e3,
        })
        if progress is not None:
            progress(item.id)
    for f in static_files():
        shutil.copyfile(f, target / f.name)
    _write_pages(target, summary.products, title)
    (target / "products.json").write_text(json.dumps(summary.products, indent=1), encoding="utf-8")
    return summary
