"""The shop site of a catalogue ``tactilize batch`` wrote: what ``tactilize serve --catalog`` shows at ``/shop/``.

A catalogue keeps each product's analysis and the path of its source picture, not the
picture itself (docs/batch.md), so the site is built from those pictures where they
still are, each rendered as its row's material (:meth:`~tactilize.catalog.Catalog.choice_of`),
as the catalogue's API renders it.  It is built once into a cache folder and built again
only when the catalogue's products, their pictures or materials, or this package's version change.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..catalog.reader import Catalog
from ..catalog.sources import CatalogItem
from ..catalog.stores import is_sql_url, safe_url
from ..errors import CatalogError
from .builder import MAX_MODEL_BYTES, MODEL_PX, PHOTO_PX, _build, static_files
from .model_file import FORMAT_VERSION

__all__ = ["CatalogSite", "catalog_site", "cache_root"]

_STATE = "catalog-state.json"


@dataclass(frozen=True)
class CatalogSite:
    """A built site of a catalogue: its folder, products shown, and ids whose picture is not here."""

    folder: Path
    products: int
    missing: tuple[str, ...]
    reused: bool

    def note(self, location: str) -> str | None:
        """One line on the products the site cannot show, or None when it shows them all."""
        if not self.missing:
            return None
        where = safe_url(location) if is_sql_url(location) else location
        return (f"{where}: {len(self.missing)} of {len(self.missing) + self.products} products have no source picture "
                f"here (a catalogue keeps the pictures' paths, not the pictures); /shop/ shows the other {self.products}")


def cache_root() -> Path:
    """Where catalogue sites are built: the user's cache folder for tactilize."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("tactilize", appauthor=False)) / "shop"


def _rows(location: str) -> list[dict[str, Any]]:
    from ..catalog.reader import read_catalog

    import pandas as pd

    df = read_catalog(location)
    keep = [c for c in ("id", "path", "status", "width_mm", "material", "relief_rms_m") if c in df.columns]
    return [{k: (None if pd.isna(v) else v) for k, v in r.items()} for r in df[keep].to_dict("records")]


def catalog_site(location: str | os.PathLike, *, cache: str | Path | None = None, title: str = "Products") -> CatalogSite:
    """Build (or reuse) the shop site of the catalogue at ``location``.

    Parameters
    ----------
    location : str or path
        The Parquet folder or SQLAlchemy URL given to ``tactilize batch``.
    cache : str or path, optional
        The folder the sites are built under (:func:`cache_root` by default); each
        catalogue gets a sub-folder named by a hash of its location.
    title : str
        The product grid's title.

    Returns
    -------
    CatalogSite

    Raises
    ------
    CatalogError
        Not a catalogue, or the cache folder cannot be written.
    MaterialError
        An ok row names a material this library does not hold (a catalogue of another version).
    """
    from .. import __version__

    loc = os.fspath(location)
    rows = _rows(loc)
    items, missing, state_rows, choices = [], [], [], {}
    for r in rows:
        if r.get("status") != "ok" or not r.get("path"):
            continue
        choice = Catalog.choice_of(r)  # an ok row's material is the library's (the batch checked it)
        path = str(r["path"])
        try:
            st = os.stat(path)
        except OSError:
            missing.append(str(r["id"]))
            continue
        width = float(r["width_mm"]) if r.get("width_mm") else None
        items.append(CatalogItem(str(r["id"]), path, width_mm=width, material=choice.name))
        choices[str(r["id"])] = choice
        state_rows.append([str(r["id"]), path, st.st_mtime_ns, st.st_size, width, choice.name, choice.relief_rms_m])
    own = [[f.name, f.stat().st_mtime_ns] for f in static_files()]
    state = {"version": __version__, "model_format": FORMAT_VERSION, "title": title, "products": state_rows,
             "static": own}
    root = Path(cache) if cache is not None else cache_root()
    key = loc if is_sql_url(loc) else os.path.abspath(loc)
    folder = root / hashlib.sha1(key.encode("utf-8")).hexdigest()[:16]
    marker = folder / _STATE
    try:
        if marker.is_file() and json.loads(marker.read_text("utf-8")) == state:
            return CatalogSite(folder, len(items), tuple(missing), True)
    except (OSError, ValueError):
        pass
    summary = _build(items, choices, folder, title=title, model_px=MODEL_PX, photo_px=PHOTO_PX,
                     max_model_bytes=MAX_MODEL_BYTES, progress=None)
    try:
        marker.write_text(json.dumps(state), encoding="utf-8")
    except OSError as exc:
        raise CatalogError(str(folder), f"cannot write ({exc.strerror or exc.__class__.__name__})") from None
    return CatalogSite(folder, len(summary.products), tuple(missing), False)
