"""Batch analysis of whole image catalogs, resumable, on local cores or a Dask cluster.

A shop has hundreds of thousands of product pictures; their tactile profiles are
computed once, kept, and served (``tactilize serve --catalog``).  This module
turns a *source* (a folder, a glob or a manifest) into a *catalog*: one row per
image with its features, a summary of its texture map, the drive at a few
reference stroking speeds for a profile, a status and, for an image that could
not be analysed, the reason.

The flow is the package's own, one direction::

    discover(source) -> [CatalogItem] -> analyse_chunk (in workers) -> rows -> store

* A bad image never stops a batch: it becomes a row with ``status == "error"``.
* Output is a Parquet dataset (a directory of ``part-NNNNN.parquet`` files,
  written atomically every few hundred rows) or any SQLAlchemy URL.  A rerun on
  the same output skips every id already there, so a crash loses at most the
  rows not yet written.
* Work runs in local processes by default; given a Dask scheduler address (or a
  :class:`distributed.Client`) the same function runs on the cluster.

Units: SI inside (metres, seconds, cycles/m); the few columns in mm or mm/s say
so in their names.  See ``docs/batch.md`` for the columns and the options.
"""

from __future__ import annotations

import csv
import glob
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ImageError, TactilizeError
from .features import warm_up
from .image import (
    DEFAULT_DPI,
    DEFAULT_MAX_PIXELS,
    METRES_PER_INCH,
    TextureImage,
    load_image,
)
from .mapping import Drive, Profile

__all__ = [
    "CatalogItem",
    "AnalysisSettings",
    "BatchSummary",
    "Catalog",
    "CatalogError",
    "StoredFeatures",
    "DEFAULT_SPEEDS_M_S",
    "IMAGE_SUFFIXES",
    "discover",
    "analyse_item",
    "analyse_chunk",
    "catalog_columns",
    "run_batch",
    "read_catalog",
    "is_sql_url",
    "TerminalProgress",
]

#: Reference stroking speeds [m/s] at which every row stores the drive: a slow,
#: the paper's centre (60 mm/s, where its sigmoid alpha is half way) and a fast stroke.
DEFAULT_SPEEDS_M_S: tuple[float, ...] = (0.030, 0.060, 0.120)

#: File name endings taken as images when the source is a folder (case-insensitive).
IMAGE_SUFFIXES = frozenset(
    {".jpg", ".jpeg", ".jpe", ".png", ".bmp", ".gif", ".tif", ".tiff", ".webp", ".pgm", ".ppm", ".pbm", ".pnm", ".tga"}
)

#: Version of the on-disk layout, kept in the catalog's metadata.
FORMAT_VERSION = 2

_META_FILE = "_catalog.json"
_PART_PREFIX = "part-"


class CatalogError(TactilizeError):
    """A source, manifest, output or scheduler that a batch cannot use."""


# ============================================================================ items


@dataclass(frozen=True)
class CatalogItem:
    """One image to analyse.

    Attributes
    ----------
    id : str
        The product's key in the catalog (unique within a source).
    path : str
        Absolute path of the image file (absolute so that workers with another
        working directory find it).
    width_mm : float, optional
        Displayed width of the whole image [mm], from a manifest.
    dpi : float, optional
        Displayed pixels per inch, from a manifest.
    problem : str, optional
        Why the item cannot be analysed although it was listed (a manifest value
        that is not a number...): it becomes an error row, not a stopped batch.
    """

    id: str
    path: str
    width_mm: float | None = None
    dpi: float | None = None
    problem: str | None = None


def discover(source: str | os.PathLike) -> list[CatalogItem]:
    """List the images of a source, sorted by id.

    Parameters
    ----------
    source : str or path
        * a folder: every file below it (recursively) whose name ends in one of
          :data:`IMAGE_SUFFIXES`; hidden files and folders are left out; the id is
          the path relative to the folder, with ``/`` separators;
        * a glob (``shop/**/*.jpg``; ``**`` recurses): the id is the path relative
          to the part of the pattern before its first wildcard;
        * a manifest, ``.csv`` or ``.jsonl``: one image per row with ``path``
          (or ``file``/``image``), and optionally ``id`` (default: the path as
          written), ``width_mm`` and ``dpi``; relative paths are relative to the
          manifest's folder;
        * a single image file (its name is its id).

    Returns
    -------
    list of CatalogItem

    Raises
    ------
    CatalogError
        The source does not exist, matches nothing, or the manifest is malformed
        (no path column, invalid line, duplicate id).  Bad *values* in a manifest
        row do not raise: the item carries a ``problem`` and becomes an error row.
    """
    text = os.fspath(source)
    path = Path(text)
    if path.is_dir():
        items = _from_folder(path)
        if not items:
            raise CatalogError(text, "folder holds no image files (" + ", ".join(sorted(IMAGE_SUFFIXES)) + ")")
    elif path.is_file() and path.suffix.lower() == ".csv":
        items = _from_manifest_rows(path, _csv_rows(path))
    elif path.is_file() and path.suffix.lower() in (".jsonl", ".ndjson"):
        items = _from_manifest_rows(path, _jsonl_rows(path))
    elif path.is_file():
        items = [CatalogItem(path.name, os.path.abspath(path))]
    elif glob.has_magic(text):
        items = _from_glob(text)
        if not items:
            raise CatalogError(text, "the pattern matches no files")
    else:
        raise CatalogError(text, "not found: give a folder, a glob, or a manifest (.csv, .jsonl)")
    items.sort(key=lambda it: it.id)
    return items


def _visible(rel: Path) -> bool:
    return not any(part.startswith(".") for part in rel.parts)


def _from_folder(root: Path) -> list[CatalogItem]:
    out = []
    for p in root.rglob("*"):
        rel = p.relative_to(root)
        if p.suffix.lower() in IMAGE_SUFFIXES and _visible(rel) and p.is_file():
            out.append(CatalogItem(rel.as_posix(), os.path.abspath(p)))
    return out


def _from_glob(pattern: str) -> list[CatalogItem]:
    # Ids are relative to the literal part of the pattern, so that "shop/**/*.jpg"
    # gives the same ids as the folder "shop".
    parts = Path(pattern).parts
    literal = []
    for part in parts:
        if glob.has_magic(part):
            break
        literal.append(part)
    root = Path(*literal) if literal else Path(".")
    out = []
    for match in glob.glob(pattern, recursive=True):
        p = Path(match)
        if p.is_file():
            out.append(CatalogItem(Path(os.path.relpath(p, root)).as_posix(), os.path.abspath(p)))
    return out


_PATH_KEYS = ("path", "file", "image", "filename")


def _csv_rows(path: Path) -> Iterator[tuple[int, dict[str, Any]]]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.DictReader(fh)
            if not reader.fieldnames:
                raise CatalogError(str(path), "manifest is empty (no header line)")
            for n, row in enumerate(reader, start=2):
                yield n, {str(k).strip().lower(): v for k, v in row.items() if k is not None}
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise CatalogError(str(path), f"cannot read manifest ({exc.__class__.__name__}: {exc})") from None


def _jsonl_rows(path: Path) -> Iterator[tuple[int, dict[str, Any]]]:
    try:
        with open(path, encoding="utf-8-sig") as fh:
            for n, line in enumerate(fh, start=1):
                if not line.strip():
                    continue
                try:
                    obj = json.loads(line)
                except json.JSONDecodeError as exc:
                    raise CatalogError(f"{path}:{n}", f"invalid JSON ({exc.msg})") from None
                if not isinstance(obj, dict):
                    raise CatalogError(f"{path}:{n}", "each line must be a JSON object")
                yield n, {str(k).strip().lower(): v for k, v in obj.items()}
    except (OSError, UnicodeDecodeError) as exc:
        raise CatalogError(str(path), f"cannot read manifest ({exc.__class__.__name__})") from None


def _number(value: Any) -> tuple[float | None, str | None]:
    """Manifest cell -> (positive float or None, problem or None)."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return None, None
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None, f"{value!r} is not a number"
    if not math.isfinite(x) or x <= 0:
        return None, f"{value!r} is not a positive number"
    return x, None


def _from_manifest_rows(manifest: Path, rows: Iterable[tuple[int, dict[str, Any]]]) -> list[CatalogItem]:
    base = manifest.parent
    items: dict[str, CatalogItem] = {}
    for line, row in rows:
        where = f"{manifest}:{line}"
        raw_path = next((row[k] for k in _PATH_KEYS if row.get(k) not in (None, "")), None)
        raw_id = row.get("id")
        ident = str(raw_id).strip() if raw_id not in (None, "") else None
        if raw_path is None and ident is None:
            raise CatalogError(where, "row has neither an id nor a path")
        if ident is None:
            ident = str(raw_path)
        if ident in items:
            raise CatalogError(where, f"duplicate id {ident!r}")
        problems = []
        if raw_path is None:
            problems.append("manifest row has no path")
            full = ""
        else:
            p = Path(str(raw_path))
            full = os.path.abspath(p if p.is_absolute() else base / p)
        width_mm, bad_w = _number(row.get("width_mm"))
        dpi, bad_d = _number(row.get("dpi"))
        if bad_w:
            problems.append(f"manifest width_mm {bad_w}")
        if bad_d:
            problems.append(f"manifest dpi {bad_d}")
        if width_mm is not None and dpi is not None:
            problems.append("manifest gives both width_mm and dpi")
        items[ident] = CatalogItem(ident, full, width_mm, dpi, "; ".join(problems) or None)
    if not items:
        raise CatalogError(str(manifest), "manifest lists no images")
    if not any(it.path for it in items.values()):
        raise CatalogError(str(manifest), f"manifest has no path column (one of {', '.join(_PATH_KEYS)})")
    return list(items.values())


# ============================================================================ analysis


@dataclass(frozen=True)
class AnalysisSettings:
    """Everything a worker needs to turn an item into a row (small, picklable).

    Attributes
    ----------
    profile : Profile
        The laws that give the stored drives.
    speeds_m_s : tuple of float
        Reference stroking speeds [m/s] at which drives are stored.
    dpi : float, optional
        Displayed pixels per inch for images whose manifest row says nothing;
        otherwise the file's DPI metadata, else 96 (as :func:`load_image`).
    analysis_pitch_m : float, optional
        Coarsest pixel pitch [m] the analysis may use.  When set, JPEGs whose
        displayed pitch is at least two times finer are decoded at 1/2, 1/4 or
        1/8 of their size (Pillow's draft mode, in the DCT domain), so that the
        analysed pitch stays at or below this, and as luma only (the stored Y
        channel, not RGB converted back to grey).  None: every image is decoded
        exactly as :func:`load_image` does it.
    max_pixels : int
        Images with more pixels are refused (decompression bombs).
    full_map : bool
        Measure every texture-map tile whole.  By default each tile is
        measured on its centred half-size square when that holds at least two
        periods of the image's texture (``texture_map(sample_px="auto")``): a
        quarter of the tile FFT work, local frequencies within 1 % of the
        whole-tile values on gratings of 4.5 to 31 pixels (docs/batch.md).
    """

    profile: Profile = field(default_factory=lambda: Profile.preset("paper"))
    speeds_m_s: tuple[float, ...] = DEFAULT_SPEEDS_M_S
    dpi: float | None = None
    analysis_pitch_m: float | None = None
    max_pixels: int = DEFAULT_MAX_PIXELS
    full_map: bool = False

    def __post_init__(self) -> None:
        speeds = tuple(float(v) for v in self.speeds_m_s)
        if not speeds or any(not math.isfinite(v) or v < 0 for v in speeds):
            raise CatalogError("<speeds>", f"reference speeds must be finite numbers >= 0 m/s, got {self.speeds_m_s!r}")
        if len({_speed_label(v) for v in speeds}) != len(speeds):
            raise CatalogError("<speeds>", f"reference speeds must differ, got {self.speeds_m_s!r}")
        object.__setattr__(self, "speeds_m_s", speeds)
        for name in ("dpi", "analysis_pitch_m"):
            value = getattr(self, name)
            if value is not None and (not math.isfinite(value) or value <= 0):
                raise CatalogError(f"<{name}>", f"must be a positive number, got {value!r}")

    def fingerprint(self) -> dict[str, Any]:
        """What a catalog's rows depend on; a rerun must match it to resume."""
        return json.loads(
            json.dumps(
                {
                    "format": FORMAT_VERSION,
                    "profile": self.profile.to_dict(),
                    "speeds_m_s": list(self.speeds_m_s),
                    "dpi": self.dpi,
                    "analysis_pitch_m": self.analysis_pitch_m,
                    "max_pixels": self.max_pixels,
                    "full_map": self.full_map,
                }
            )
        )


def _speed_label(speed_m_s: float) -> str:
    """Column-safe label of a speed in mm/s: 0.06 -> '60mm_s', 0.0075 -> '7p5mm_s'."""
    return f"{speed_m_s * 1e3:.6g}".replace(".", "p") + "mm_s"


def _pitch_of(item: CatalogItem, settings: AnalysisSettings) -> tuple[float | None, float | None]:
    """(dpi, width_mm) for load_image: the manifest row first, then the batch's --dpi."""
    if item.dpi is not None or item.width_mm is not None:
        return item.dpi, item.width_mm
    return settings.dpi, None


def _load(item: CatalogItem, settings: AnalysisSettings) -> tuple[TextureImage, int]:
    """Load an item, reduced in the DCT domain when the target pitch allows it.

    Returns the image and the decode reduction factor (1, 2, 4 or 8).
    """
    dpi, width_mm = _pitch_of(item, settings)
    if settings.analysis_pitch_m is not None and item.path.lower().endswith((".jpg", ".jpeg", ".jpe")):
        try:
            drafted = _draft_decode(item.path, dpi, width_mm, settings)
        except Exception:
            # Whatever went wrong, the loader proper decides and says it in its own words.
            drafted = None
        if drafted is not None:
            grey, dpi_reduced, scale = drafted
            img = load_image(grey, dpi=dpi_reduced, max_pixels=settings.max_pixels)
            return img.with_source(item.path), scale
    return load_image(item.path, dpi=dpi, width_mm=width_mm, max_pixels=settings.max_pixels), 1


def _draft_decode(
    path: str, dpi: float | None, width_mm: float | None, settings: AnalysisSettings
) -> tuple[np.ndarray, float, int] | None:
    """Decode a JPEG's luma, at 1/2, 1/4 or 1/8 size when the analysis pitch allows.

    Returns (grey uint8 array, its dpi, reduction factor), or None for a file this
    path does not handle (not a JPEG, too large), which then goes to :func:`load_image`.
    """
    from PIL import Image, ImageOps

    from .image import _file_dpi

    target = settings.analysis_pitch_m
    assert target is not None
    with Image.open(path) as im:
        if im.format != "JPEG":
            return None
        w, h = im.size
        if w * h > settings.max_pixels or w == 0 or h == 0:
            return None
        # The displayed width is after EXIF rotation (orientations 5..8 swap the axes).
        orientation = im.getexif().get(0x0112, 1)
        shown_w = h if orientation in (5, 6, 7, 8) else w
        if dpi is not None:
            pitch = METRES_PER_INCH / dpi
        elif width_mm is not None:
            pitch = width_mm * 1e-3 / shown_w
        else:
            pitch = METRES_PER_INCH / (_file_dpi(im) or DEFAULT_DPI)
        scale = 1
        # libjpeg scales by 1/2, 1/4, 1/8 only; keep at least 16 px on the short side
        # so that the spectrum still has a few bins to find a peak in.
        while scale < 8 and pitch * scale * 2 <= target * (1 + 1e-9) and min(w, h) // (scale * 2) >= 16:
            scale *= 2
        # Even at full size only the luma is decoded: the analysis is grey, and skipping
        # the chroma upsampling and colour conversion saves about a third of the decode.
        im.draft("L", (-(-w // scale), -(-h // scale)))
        im.load()
        ImageOps.exif_transpose(im, in_place=True)
        if im.mode != "L":  # CMYK JPEGs do not draft to grey
            im = im.convert("L")
        grey = np.asarray(im, dtype=np.uint8)
    shown_w_reduced = grey.shape[1]
    # The picture keeps its physical size: fewer pixels, each larger.
    pitch_reduced = pitch * shown_w / shown_w_reduced
    return grey, METRES_PER_INCH / pitch_reduced, int(round(shown_w / shown_w_reduced))


def _row_from_image(img: TextureImage, scale: int, settings: AnalysisSettings) -> dict[str, Any]:
    from .texturemap import texture_map

    tmap = texture_map(img, sample_px=None if settings.full_map else "auto")
    # The map analyses the whole image as well; reuse it rather than a second FFT.
    feat = tmap.whole
    row: dict[str, Any] = {
        "width_px": int(img.shape[1]),
        "height_px": int(img.shape[0]),
        "decode_scale": int(scale),
        "pitch_m": float(img.pitch_m[0]),
        "width_mm": img.width_m * 1e3,
        "height_mm": img.height_m * 1e3,
    }
    for key, value in feat.to_dict().items():
        if isinstance(value, (bool, int, float, str)):
            row[key] = value
    for key, value in tmap.summary().items():
        row[f"map_{key}"] = value
    for speed in settings.speeds_m_s:
        drv = settings.profile.drive(feat, speed_m_s=speed)
        prefix = f"drive_{_speed_label(speed)}_"
        row[prefix + "pulse_frequency_hz"] = drv.pulse_frequency_hz
        row[prefix + "pulse_width_s"] = drv.pulse_width_s
        row[prefix + "duty_ratio"] = drv.duty_ratio
        row[prefix + "amplitude"] = drv.amplitude
        row[prefix + "clamped"] = ",".join(drv.clamped)
    return row


def analyse_item(item: CatalogItem, settings: AnalysisSettings) -> dict[str, Any]:
    """One catalog row for one item; never raises for a bad image.

    Returns
    -------
    dict
        ``id``, ``path``, ``status`` (``"ok"`` or ``"error"``), ``error`` (the
        reason, None when ok), ``profile``, ``seconds`` (analysis time [s]) and,
        when ok, the image, feature, ``map_*`` and ``drive_<speed>mm_s_*`` columns.
    """
    t0 = time.perf_counter()
    row: dict[str, Any] = {"id": item.id, "path": item.path, "status": "ok", "error": None, "profile": settings.profile.name}
    try:
        if item.problem:
            raise ImageError(item.path or item.id, item.problem)
        img, scale = _load(item, settings)
        row.update(_row_from_image(img, scale, settings))
    except TactilizeError as exc:
        row.update(status="error", error=exc.fault)
    except MemoryError:
        row.update(status="error", error="not enough memory to analyse")
    except Exception as exc:  # an unforeseen failure is still one row, never a stopped batch
        row.update(status="error", error=f"internal error: {exc.__class__.__name__}: {exc}")
    row["seconds"] = time.perf_counter() - t0
    return row


def analyse_chunk(items: Sequence[CatalogItem], settings: AnalysisSettings) -> list[dict[str, Any]]:
    """Rows for a few items: the unit of work sent to a process or a Dask worker."""
    return [analyse_item(it, settings) for it in items]


_KIND_OF = {bool: "bool", int: "int", float: "float", str: "str"}


def catalog_columns(settings: AnalysisSettings) -> list[tuple[str, str]]:
    """The catalog's columns as (name, kind), kind in {"str", "float", "int", "bool"}.

    Derived by analysing a small generated grating with the current code, so the
    schema follows :meth:`TextureFeatures.to_dict` and the texture-map summary
    without a second list to keep in step.
    """
    y, x = np.mgrid[0:64, 0:64]
    grating = (0.5 + 0.4 * np.cos(2 * np.pi * (x / 8.0 + y / 16.0))).astype(np.float32)
    probe = _row_from_image(load_image(grating, dpi=96.0), 1, settings)
    cols = [("id", "str"), ("path", "str"), ("status", "str"), ("error", "str"), ("profile", "str"), ("seconds", "float")]
    for key, value in probe.items():
        kind = _KIND_OF[type(value)] if type(value) in _KIND_OF else "float"
        cols.append((key, kind))
    return cols


# ============================================================================ stores


def is_sql_url(out: str | os.PathLike) -> bool:
    """True when ``out`` names a database (``sqlite:///x.db``, ``postgresql://...``)."""
    text = os.fspath(out)
    head = text.split("://", 1)[0] if "://" in text else ""
    return bool(head) and all(c.isalnum() or c in "+_" for c in head)


class _ParquetStore:
    """A directory of Parquet parts plus ``_catalog.json``; each part is written atomically."""

    def __init__(self, path: Path, columns: list[tuple[str, str]]):
        import pyarrow as pa

        self.path = path
        types = {"str": pa.string(), "float": pa.float64(), "int": pa.int64(), "bool": pa.bool_()}
        self.schema = pa.schema([(name, types[kind]) for name, kind in columns])

    def open(self, fingerprint: dict[str, Any]) -> None:
        if self.path.exists() and not self.path.is_dir():
            raise CatalogError(str(self.path), "exists and is not a directory (a Parquet catalog is a folder of parts)")
        self.path.mkdir(parents=True, exist_ok=True)
        meta = self.path / _META_FILE
        if meta.exists():
            old = json.loads(meta.read_text("utf-8"))
            _check_fingerprint(str(self.path), old.get("settings"), fingerprint)
        else:
            _atomic_write(meta, json.dumps({"settings": fingerprint}, indent=2).encode("utf-8"))
        self._next = max((_part_number(p) for p in self._parts()), default=-1) + 1

    def _parts(self) -> list[Path]:
        return sorted(self.path.glob(f"{_PART_PREFIX}*.parquet"))

    def done_ids(self, retry_failed: bool) -> set[str]:
        import pyarrow.parquet as pq

        status: dict[str, str] = {}
        for part in self._parts():
            t = pq.read_table(part, columns=["id", "status"])
            status.update(zip(t.column("id").to_pylist(), t.column("status").to_pylist()))
        return {i for i, s in status.items() if s == "ok" or not retry_failed}

    def write(self, rows: list[dict[str, Any]]) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        # Column lists, not from_pylist: the latter costs ~1 ms a row in this process,
        # which the workers need.
        table = pa.Table.from_pydict({n: [r.get(n) for r in rows] for n in self.schema.names}, schema=self.schema)
        # Dot-prefixed temporaries are ignored by Parquet readers.
        tmp = self.path / f".{_PART_PREFIX}{os.getpid()}-{self._next:05d}.parquet.tmp"
        pq.write_table(table, tmp)
        try:
            while True:
                final = self.path / f"{_PART_PREFIX}{self._next:05d}.parquet"
                self._next += 1
                try:
                    # link, unlike rename, refuses to replace: a second batch writing
                    # into the same folder takes the next number instead of a part.
                    os.link(tmp, final)
                    break
                except FileExistsError:
                    continue
                except OSError:  # a file system without hard links
                    if final.exists():
                        continue
                    os.replace(tmp, final)
                    break
        finally:
            tmp.unlink(missing_ok=True)

    def close(self) -> None:
        pass


def _part_number(p: Path) -> int:
    try:
        return int(p.stem[len(_PART_PREFIX) :])
    except ValueError:
        return -1


def _atomic_write(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _check_fingerprint(where: str, old: Any, new: dict[str, Any]) -> None:
    if old is None or old == new:
        return
    differ = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    raise CatalogError(
        where,
        f"was built with other settings ({', '.join(differ)} differ); resume with the same ones or give another --out",
    )


class _SqlStore:
    """One table (``id`` primary key) plus ``<table>_meta``; one transaction per write."""

    def __init__(self, url: str, columns: list[tuple[str, str]], table: str):
        import sqlalchemy as sa

        self.url = url
        try:
            self.engine = sa.create_engine(url)
        except Exception as exc:  # unknown dialect, missing driver, malformed URL
            raise CatalogError(_safe_url(url), f"cannot use this database URL ({exc.__class__.__name__}: {exc})") from None
        types = {"str": sa.Text, "float": sa.Float, "int": sa.BigInteger, "bool": sa.Boolean}
        md = sa.MetaData()
        self.table = sa.Table(
            table,
            md,
            *[sa.Column(name, sa.String(512) if name == "id" else types[kind](), primary_key=(name == "id")) for name, kind in columns],
        )
        self.meta = sa.Table(f"{table}_meta", md, sa.Column("key", sa.String(64), primary_key=True), sa.Column("value", sa.Text))
        self.md = md

    def open(self, fingerprint: dict[str, Any]) -> None:
        import sqlalchemy as sa

        try:
            self.md.create_all(self.engine)
            with self.engine.begin() as conn:
                old = conn.execute(sa.select(self.meta.c.value).where(self.meta.c.key == "settings")).scalar()
                if old is None:
                    conn.execute(self.meta.insert(), [{"key": "settings", "value": json.dumps(fingerprint)}])
                else:
                    _check_fingerprint(_safe_url(self.url), json.loads(old), fingerprint)
        except sa.exc.SQLAlchemyError as exc:
            raise CatalogError(_safe_url(self.url), f"database error ({exc.__class__.__name__}: {exc.orig if hasattr(exc, 'orig') else exc})") from None

    def done_ids(self, retry_failed: bool) -> set[str]:
        import sqlalchemy as sa

        q = sa.select(self.table.c.id)
        if retry_failed:
            q = q.where(self.table.c.status == "ok")
        with self.engine.connect() as conn:
            return {r[0] for r in conn.execute(q)}

    def write(self, rows: list[dict[str, Any]]) -> None:
        names = [c.name for c in self.table.columns]
        clean = [{n: _sql_value(r.get(n)) for n in names} for r in rows]
        with self.engine.begin() as conn:
            # A retried id replaces its earlier (failed) row in the same transaction.
            conn.execute(self.table.delete().where(self.table.c.id.in_([r["id"] for r in clean])))
            conn.execute(self.table.insert(), clean)

    def close(self) -> None:
        self.engine.dispose()


def _sql_value(v: Any) -> Any:
    # Not every database stores NaN/inf; NULL means "no value" in every one of them.
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _safe_url(url: str) -> str:
    """The URL without its password, for messages."""
    try:
        import sqlalchemy as sa

        return sa.engine.make_url(url).render_as_string(hide_password=True)
    except Exception:
        return url.split("@")[-1]


def _open_store(out: str | os.PathLike, columns: list[tuple[str, str]], table: str) -> _ParquetStore | _SqlStore:
    if is_sql_url(out):
        return _SqlStore(os.fspath(out), columns, table)
    return _ParquetStore(Path(out), columns)


# ============================================================================ running


@dataclass(frozen=True)
class BatchSummary:
    """What a batch did.

    Attributes
    ----------
    total : int
        Items in the source.
    ok, failed : int
        Rows written by this run, by status.
    skipped : int
        Items already in the output (not analysed again).
    seconds : float
        Wall-clock time of the run [s].
    out : str
        Where the rows went (a folder or a database URL without password).
    """

    total: int
    ok: int
    failed: int
    skipped: int
    seconds: float
    out: str

    @property
    def images_per_second(self) -> float:
        done = self.ok + self.failed
        return done / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "total": self.total,
            "ok": self.ok,
            "failed": self.failed,
            "skipped": self.skipped,
            "seconds": self.seconds,
            "images_per_second": self.images_per_second,
            "out": self.out,
        }


def default_workers() -> int:
    """Cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _init_worker() -> None:
    """Process-pool initialiser: one core per process, and Ctrl-C is the parent's business."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        # Several processes each starting a BLAS thread per core would fight over the cores.
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except Exception:
        pass
    # Nothing to do in a worker forked from a parent that warmed up (see _run_processes);
    # a worker started afresh loads the compiled passes now, not inside its first task.
    warm_up()


class _Feeder:
    """Hands out tasks of a size that adapts to how long an image takes.

    A task should last about ``target_s``: long enough that sending it and its
    rows costs little beside the analysis (tiny thumbnails need hundreds per
    task), short enough that progress moves and, near the end, no worker waits
    for another's long task (no task takes more than a share of what is left).
    """

    def __init__(self, items: Sequence[CatalogItem], slots: int, fixed: int | None = None, target_s: float = 0.15):
        self.items = items
        self.slots = max(1, slots)
        self.fixed = fixed
        self.target_s = target_s
        self.pos = 0
        self.size = fixed or 2  # small first tasks give a first estimate quickly
        self.per_image_s: float | None = None

    def __bool__(self) -> bool:
        return self.pos < len(self.items)

    def next(self) -> list[CatalogItem] | None:
        remaining = len(self.items) - self.pos
        if remaining <= 0:
            return None
        size = self.fixed or max(1, min(self.size, remaining // (2 * self.slots) or 1))
        chunk = list(self.items[self.pos : self.pos + size])
        self.pos += len(chunk)
        return chunk

    def observe(self, rows: list[dict[str, Any]]) -> None:
        if self.fixed:
            return
        secs = [r["seconds"] for r in rows if r.get("seconds")]
        if not secs:
            return
        t = sum(secs) / len(secs)
        # A moving average: one slow image must not swing the task size.
        self.per_image_s = t if self.per_image_s is None else 0.7 * self.per_image_s + 0.3 * t
        self.size = int(min(512, max(1, self.target_s / max(self.per_image_s, 1e-6))))


def _run_serial(feed: _Feeder, settings: AnalysisSettings) -> Iterator[list[dict[str, Any]]]:
    while (chunk := feed.next()) is not None:
        rows = analyse_chunk(chunk, settings)
        feed.observe(rows)
        yield rows


def _error_rows(chunk: Sequence[CatalogItem], settings: AnalysisSettings, reason: str) -> list[dict[str, Any]]:
    """Error rows for a task whose worker died: the batch goes on, --retry-failed redoes them."""
    return [
        {"id": it.id, "path": it.path, "status": "error", "error": reason, "profile": settings.profile.name, "seconds": None}
        for it in chunk
    ]


_WORKER_DIED = (
    "the worker process died during this task (out of memory, or a crash in a decoder); "
    "innocent images of the same task are marked too: rerun with --retry-failed"
)


def _run_processes(feed: _Feeder, settings: AnalysisSettings, workers: int) -> Iterator[list[dict[str, Any]]]:
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # Ready in the parent, the compiled analysis is inherited by every forked worker:
    # loading it costs each fresh process a few tenths of a second, as much as 40 images.
    warm_up()

    def new_pool() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=workers, initializer=_init_worker)

    pool = new_pool()
    chunk_of: dict[Any, list[CatalogItem]] = {}

    def submit(chunk: list[CatalogItem]) -> None:
        nonlocal pool
        try:
            fut = pool.submit(analyse_chunk, chunk, settings)
        except BrokenProcessPool:
            # A worker was killed (say by the OOM killer): the pool is unusable, start another.
            pool.shutdown(wait=False, cancel_futures=True)
            pool = new_pool()
            fut = pool.submit(analyse_chunk, chunk, settings)
        chunk_of[fut] = chunk

    try:
        # A bounded number in flight keeps memory flat for a catalog of any size.
        while len(chunk_of) < 2 * workers and (chunk := feed.next()) is not None:
            submit(chunk)
        while chunk_of:
            done, _ = wait(list(chunk_of), return_when=FIRST_COMPLETED)
            for fut in done:
                chunk = chunk_of.pop(fut)
                try:
                    rows = fut.result()
                except BrokenProcessPool:
                    rows = _error_rows(chunk, settings, _WORKER_DIED)
                feed.observe(rows)
                nxt = feed.next()
                if nxt is not None:
                    submit(nxt)
                yield rows
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _run_dask(feed: _Feeder, settings: AnalysisSettings, scheduler: Any, timeout_s: float) -> Iterator[list[dict[str, Any]]]:
    try:
        from distributed import Client, as_completed
        from distributed.scheduler import KilledWorker
    except ImportError:  # pragma: no cover - the batch extra is not installed
        raise CatalogError("--scheduler", "needs dask[distributed] (pip install 'tactilize[batch]')") from None

    own = not isinstance(scheduler, Client)
    if own:
        try:
            client = Client(str(scheduler), timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise CatalogError(str(scheduler), f"cannot reach the Dask scheduler ({exc.__class__.__name__}: {exc})") from None
    else:
        client = scheduler
    try:
        feed.slots = max(1, sum(client.nthreads().values()))
        chunk_of: dict[Any, list[CatalogItem]] = {}
        queue = as_completed([], loop=client.loop)  # this client need not be the default one

        def submit(chunk: list[CatalogItem]) -> None:
            f = client.submit(analyse_chunk, chunk, settings, pure=False)
            chunk_of[f] = chunk
            queue.add(f)

        while len(chunk_of) < 2 * feed.slots and (first := feed.next()) is not None:
            submit(first)
        for fut in queue:
            chunk = chunk_of.pop(fut)
            try:
                rows = fut.result()
            except KilledWorker:
                # Dask already retried the task on other workers; each of them died.
                rows = _error_rows(chunk, settings, _WORKER_DIED)
            except Exception as exc:  # analyse_chunk never raises: this is the cluster
                raise CatalogError(
                    str(scheduler) if own else "<dask client>",
                    f"the Dask cluster failed ({exc.__class__.__name__}: {exc}); the rows finished so far are kept, rerun to resume",
                ) from None
            feed.observe(rows)
            nxt = feed.next()
            if nxt is not None:
                submit(nxt)
            yield rows
            fut.release()
    finally:
        if own:
            client.close()


ProgressCallback = Callable[[int, int, int], None]


def run_batch(
    source: str | os.PathLike | Sequence[CatalogItem],
    out: str | os.PathLike,
    *,
    profile: Profile | str | os.PathLike | None = None,
    speeds_m_s: Sequence[float] = DEFAULT_SPEEDS_M_S,
    dpi: float | None = None,
    analysis_pitch_m: float | None = None,
    full_map: bool = False,
    workers: int | None = None,
    scheduler: Any = None,
    scheduler_timeout_s: float = 10.0,
    retry_failed: bool = False,
    chunk_size: int | None = None,
    part_rows: int = 500,
    part_seconds: float = 20.0,
    table: str = "catalog",
    progress: ProgressCallback | None = None,
) -> BatchSummary:
    """Analyse every image of a source into a catalog; resumes a previous run.

    Parameters
    ----------
    source : str, path or sequence of CatalogItem
        A folder, glob or manifest (see :func:`discover`), or items already listed.
    out : str or path
        A Parquet catalog folder (created if needed), or an SQLAlchemy URL
        (``sqlite:///shop.db``, ``postgresql://...``).
    profile : Profile, preset name or TOML path, optional
        Laws for the stored drives; the ``paper`` preset by default.
    speeds_m_s : sequence of float
        Reference stroking speeds [m/s] (default 30, 60 and 120 mm/s).
    dpi : float, optional
        Displayed pixels per inch for images whose manifest row gives neither
        ``dpi`` nor ``width_mm`` (those win); else file metadata, else 96.
    analysis_pitch_m : float, optional
        Coarsest pixel pitch [m] the analysis may use; lets JPEGs be decoded at
        reduced size (see :class:`AnalysisSettings` and ``docs/batch.md``).
    full_map : bool
        Measure every texture-map tile whole rather than on its centred
        half-size square (see :class:`AnalysisSettings`).
    workers : int, optional
        Local processes (default: the cores this process may use).  1 runs in
        this process.  Ignored with ``scheduler``.
    scheduler : str or distributed.Client, optional
        A Dask scheduler address (``tcp://host:8786``) or a connected client:
        the work runs on that cluster, whose workers must see the image paths.
    scheduler_timeout_s : float
        How long to try to reach the scheduler [s].
    retry_failed : bool
        Also analyse again the ids whose earlier row is an error.
    chunk_size : int, optional
        Images per task.  By default it adapts so that a task lasts about
        0.15 s (many thumbnails, or one large photo per task), smaller near
        the end so that every worker stays busy.
    part_rows, part_seconds : int, float
        Rows are written when this many are waiting or this many seconds [s]
        have passed, whichever comes first: what a crash can lose at most.
    table : str
        Table name for an SQL output.
    progress : callable, optional
        ``progress(done, total, failed)`` after every finished task.

    Returns
    -------
    BatchSummary

    Raises
    ------
    CatalogError
        Unusable source, output, settings mismatch on resume, or scheduler.
    ProfileError
        Unknown profile.
    """
    t0 = time.perf_counter()
    prof = profile if isinstance(profile, Profile) else Profile.resolve(None if profile is None else os.fspath(profile))
    settings = AnalysisSettings(prof, tuple(speeds_m_s), dpi, analysis_pitch_m, full_map=full_map)
    items = list(source) if not isinstance(source, (str, os.PathLike)) else discover(source)
    ids = [it.id for it in items]
    if len(set(ids)) != len(ids):
        raise CatalogError("<items>", "ids must be unique")

    store = _open_store(out, catalog_columns(settings), table)
    store.open(settings.fingerprint())
    try:
        done_before = store.done_ids(retry_failed)
        todo = [it for it in items if it.id not in done_before]
        skipped = len(items) - len(todo)
        n_workers = max(1, int(workers)) if workers else default_workers()
        feed = _Feeder(todo, n_workers, chunk_size)
        if scheduler is not None:
            results = _run_dask(feed, settings, scheduler, scheduler_timeout_s)
        elif n_workers == 1 or len(todo) <= 1:
            results = _run_serial(feed, settings)
        else:
            results = _run_processes(feed, settings, n_workers)

        ok = failed = 0
        buffer: list[dict[str, Any]] = []
        last_write = time.monotonic()
        try:
            for rows in results:
                buffer.extend(rows)
                for r in rows:
                    if r["status"] == "ok":
                        ok += 1
                    else:
                        failed += 1
                if len(buffer) >= part_rows or time.monotonic() - last_write >= part_seconds:
                    store.write(buffer)
                    buffer, last_write = [], time.monotonic()
                if progress is not None:
                    progress(ok + failed, len(todo), failed)
        finally:
            # Also on Ctrl-C or a lost cluster: what is finished is kept, so a rerun resumes.
            if buffer:
                store.write(buffer)
            close = getattr(results, "close", None)
            if close is not None:
                close()
    finally:
        store.close()
    where = _safe_url(os.fspath(out)) if is_sql_url(out) else os.fspath(out)
    return BatchSummary(len(items), ok, failed, skipped, time.perf_counter() - t0, where)


# ============================================================================ reading


def read_catalog(location: str | os.PathLike, *, table: str = "catalog"):
    """A catalog as a pandas DataFrame, one row per id (the latest when an id was retried).

    Parameters
    ----------
    location : str or path
        The Parquet folder or SQLAlchemy URL given to :func:`run_batch`.
    """
    import pandas as pd

    if is_sql_url(location):
        import sqlalchemy as sa

        engine = sa.create_engine(os.fspath(location))
        try:
            with engine.connect() as conn:
                return pd.read_sql_table(table, conn)
        except (sa.exc.SQLAlchemyError, ValueError) as exc:
            raise CatalogError(_safe_url(os.fspath(location)), f"cannot read table {table!r} ({exc.__class__.__name__})") from None
        finally:
            engine.dispose()
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(location)
    if not (path / _META_FILE).exists():
        raise CatalogError(str(path), "not a catalog (no _catalog.json): make one with `tactilize batch`")
    parts = sorted(path.glob(f"{_PART_PREFIX}*.parquet"))
    if not parts:
        return pd.DataFrame({"id": pd.Series([], dtype=object), "status": pd.Series([], dtype=object)})
    # Nullable integer and boolean columns: an error row has no width_px, and that
    # must not turn every width into a float.
    nullable = {pa.int64(): pd.Int64Dtype(), pa.bool_(): pd.BooleanDtype()}
    df = pa.concat_tables([pq.read_table(p) for p in parts]).to_pandas(types_mapper=nullable.get)
    # Parts are in write order, so the last row of an id is its latest analysis.
    df = df.drop_duplicates("id", keep="last")
    return df.sort_values("id", kind="stable").reset_index(drop=True)


@dataclass(frozen=True)
class StoredFeatures:
    """The features a stored row keeps that :meth:`Profile.drive` reads.

    Enough to compute a drive at any speed from a catalog row without the image.
    """

    spatial_frequency_per_m: float
    spectral_intensity: float
    orientation_deg: float = 0.0
    anisotropy: float = 0.0


class Catalog:
    """Read access to a catalog made by :func:`run_batch` (for the web API and scripts).

    Parameters
    ----------
    location : str or path
        The Parquet folder or SQLAlchemy URL.
    table : str
        Table name for an SQL catalog.

    Notes
    -----
    A Parquet catalog is read into memory (a few hundred bytes per product) and
    read again when its parts change, so a batch still running is seen as it
    grows.  An SQL catalog is queried per request.
    """

    def __init__(self, location: str | os.PathLike, *, table: str = "catalog"):
        self.location = os.fspath(location)
        self.table = table
        self.is_sql = is_sql_url(self.location)
        self._df = None
        self._parts_seen: tuple = ()
        self._checked = 0.0
        if self.is_sql:
            import sqlalchemy as sa

            self._engine = sa.create_engine(self.location)
            try:
                md = sa.MetaData()
                self._table = sa.Table(table, md, autoload_with=self._engine)
                meta = sa.Table(f"{table}_meta", md, autoload_with=self._engine)
                with self._engine.connect() as conn:
                    raw = conn.execute(sa.select(meta.c.value).where(meta.c.key == "settings")).scalar()
            except sa.exc.SQLAlchemyError as exc:
                raise CatalogError(_safe_url(self.location), f"not a catalog ({exc.__class__.__name__})") from None
            self.settings = json.loads(raw) if raw else {}
        else:
            meta_path = Path(self.location) / _META_FILE
            if not meta_path.exists():
                raise CatalogError(self.location, "not a catalog (no _catalog.json): make one with `tactilize batch`")
            self.settings = json.loads(meta_path.read_text("utf-8")).get("settings", {})
        try:
            self.profile = Profile.from_dict(self.settings["profile"], source=f"{self.location} profile")
        except KeyError:
            self.profile = Profile.preset("paper")
        self.speeds_m_s: tuple[float, ...] = tuple(self.settings.get("speeds_m_s", DEFAULT_SPEEDS_M_S))

    # -- Parquet: an in-memory index, refreshed when the parts change

    def _frame(self):
        now = time.monotonic()
        if self._df is None or now - self._checked > 2.0:
            self._checked = now
            parts = tuple(sorted((p.name, p.stat().st_mtime_ns) for p in Path(self.location).glob(f"{_PART_PREFIX}*.parquet")))
            if self._df is None or parts != self._parts_seen:
                df = read_catalog(self.location)
                self._df = df.set_index("id", drop=False)
                self._parts_seen = parts
        return self._df

    def counts(self) -> dict[str, int]:
        """``total``, ``ok`` and ``failed`` rows."""
        if self.is_sql:
            import sqlalchemy as sa

            with self._engine.connect() as conn:
                rows = conn.execute(sa.select(self._table.c.status, sa.func.count()).group_by(self._table.c.status)).all()
            by = {s: int(n) for s, n in rows}
        else:
            by = self._frame()["status"].value_counts().to_dict() if len(self._frame()) else {}
        ok = int(by.get("ok", 0))
        total = int(sum(by.values()))
        return {"total": total, "ok": ok, "failed": total - ok}

    def ids(self, *, offset: int = 0, limit: int = 100, status: str | None = None) -> list[str]:
        """Product ids in order, a page at a time."""
        if self.is_sql:
            import sqlalchemy as sa

            q = sa.select(self._table.c.id).order_by(self._table.c.id).offset(offset).limit(limit)
            if status:
                q = q.where(self._table.c.status == status)
            with self._engine.connect() as conn:
                return [r[0] for r in conn.execute(q)]
        df = self._frame()
        if status:
            df = df[df["status"] == status]
        return df["id"].iloc[offset : offset + limit].tolist()  # read_catalog sorts by id

    def get(self, product_id: str) -> dict[str, Any] | None:
        """The stored row of a product (missing values as None), or None if unknown."""
        if self.is_sql:
            import sqlalchemy as sa

            with self._engine.connect() as conn:
                r = conn.execute(sa.select(self._table).where(self._table.c.id == product_id)).mappings().first()
            row = dict(r) if r is not None else None
        else:
            df = self._frame()
            if product_id not in df.index:
                return None
            row = df.loc[product_id].to_dict()
        if row is None:
            return None
        return {k: _plain(v) for k, v in row.items()}

    @staticmethod
    def features_of(row: dict[str, Any]) -> StoredFeatures:
        """What :meth:`Profile.drive` needs, from a row with ``status == "ok"``."""
        return StoredFeatures(
            float(row.get("spatial_frequency_per_m") or 0.0),
            float(row.get("spectral_intensity") or 0.0),
            float(row.get("orientation_deg") or 0.0),
            float(row.get("anisotropy") or 0.0),
        )

    def stored_drives(self, row: dict[str, Any]) -> list[tuple[float, Drive]]:
        """(speed [m/s], drive) at the catalog's reference speeds, as the batch stored them."""
        out = []
        if row.get("status") != "ok":
            return out
        for speed in self.speeds_m_s:
            p = f"drive_{_speed_label(speed)}_"
            clamped = row.get(p + "clamped") or ""
            out.append(
                (
                    speed,
                    Drive(
                        float(row[p + "pulse_frequency_hz"]),
                        float(row[p + "pulse_width_s"]),
                        float(row[p + "amplitude"]),
                        tuple(c for c in clamped.split(",") if c),
                    ),
                )
            )
        return out

    def drive(self, row: dict[str, Any], speed_m_s: float, profile: Profile | None = None) -> Drive:
        """The drive of a stored product at any speed [m/s] (the catalog's profile by default)."""
        return (profile or self.profile).drive(self.features_of(row), speed_m_s=speed_m_s)

    def close(self) -> None:
        if self.is_sql:
            self._engine.dispose()


def _pd_na() -> Any:
    try:
        import pandas as pd

        return pd.NA
    except ImportError:  # pragma: no cover
        return None


def _plain(v: Any) -> Any:
    """numpy scalars -> Python, NaN -> None (a missing value in an error row)."""
    if v is None or v is _pd_na():
        return None
    if hasattr(v, "item") and callable(v.item):
        v = v.item()
    if isinstance(v, float) and math.isnan(v):
        return None
    return v


# ============================================================================ progress


class TerminalProgress:
    """A one-line progress bar with rate and ETA, on a terminal only.

    Parameters
    ----------
    stream : file, optional
        Where to draw (stderr by default).  Nothing is drawn unless it is a TTY,
        so logs and pipes stay clean.
    """

    def __init__(self, stream: Any = None, *, min_interval_s: float = 0.1):
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.min_interval_s = min_interval_s
        self._t0 = time.monotonic()
        self._last = 0.0
        self._drawn = False

    def __call__(self, done: int, total: int, failed: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if done < total and now - self._last < self.min_interval_s:
            return
        self._last = now
        elapsed = now - self._t0
        rate = done / elapsed if elapsed > 0 else 0.0
        eta = (total - done) / rate if rate > 0 else math.inf
        width = 24
        filled = int(width * done / total) if total else width
        bar = "#" * filled + "." * (width - filled)
        eta_text = "--:--" if not math.isfinite(eta) else f"{int(eta // 60):02d}:{int(eta % 60):02d}"
        fail_text = f"  {failed} failed" if failed else ""
        line = f"\r{done}/{total} [{bar}] {100.0 * done / max(total, 1):5.1f}%  {rate:6.1f} img/s  ETA {eta_text}{fail_text}"
        self.stream.write(line + "\x1b[K")
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        """End the bar's line."""
        if self.enabled and self._drawn:
            self.stream.write("\n")
            self.stream.flush()
