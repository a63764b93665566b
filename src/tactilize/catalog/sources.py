"""What a batch analyses: a folder, a glob, a manifest or one file -> :class:`CatalogItem` list.

Listing never opens an image; a bad *value* in a manifest row travels with its
item (:attr:`CatalogItem.problem`) and becomes that product's error row, while
a manifest that cannot be read at all stops the batch before any work starts.
"""

from __future__ import annotations

import csv
import glob
import json
import math
import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..errors import CatalogError, MaterialError, TactilizeError, check_finite, path_fault, special_file_fault

__all__ = ["IMAGE_SUFFIXES", "MAX_RELIEF_MM", "CatalogItem", "check_relief_mm", "discover", "with_defaults"]

#: File name endings taken as images when the source is a folder (case-insensitive).
IMAGE_SUFFIXES = frozenset(
    {".jpg", ".jpeg", ".jpe", ".png", ".bmp", ".gif", ".tif", ".tiff", ".webp", ".pgm", ".ppm", ".pbm", ".pnm", ".tga"}
)

# Manifest columns that may hold the image's path, in order of preference.
_PATH_KEYS = ("path", "file", "image", "filename")

#: Largest relief RMS [mm] a picture may be given (``--relief-mm``, a manifest's ``relief_mm``):
#: a texture stroked by a pen tip, not a landscape.
MAX_RELIEF_MM = 10.0


def check_relief_mm(value: object, source: str, error: type[TactilizeError] = TactilizeError) -> float:
    """A relief RMS in millimetres [mm], as ``--relief-mm`` and a manifest's ``relief_mm`` take it:
    a positive finite number, at most :data:`MAX_RELIEF_MM`.

    Raises
    ------
    TactilizeError
        Of type ``error``, naming ``source``: anything else (a string, a bool, NaN...).
    """
    return check_finite(value, source, error=error, above=0.0, maximum=MAX_RELIEF_MM, unit="mm")


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
        that is not a number, an unknown material...): it becomes an error row, not a
        stopped batch.
    material : str, optional
        What the picture is of, from a manifest's ``material`` column: a library name
        (:mod:`tactilize.materials`), or the cell as written when it names none (then
        ``problem`` says so); None for the picture alone.
    relief_rms_m : float, optional
        RMS height of the picture's visible relief [m], from a manifest's ``relief_mm``
        column (or the batch's ``--relief-mm``); None: the material's typical relief, or
        the picture alone.
    """

    id: str
    path: str
    width_mm: float | None = None
    dpi: float | None = None
    problem: str | None = None
    material: str | None = None
    relief_rms_m: float | None = None


def with_defaults(items: Sequence[CatalogItem], material: str | None = None,
                  relief_rms_m: float | None = None) -> list[CatalogItem]:
    """``items`` with ``material`` (a library name) and ``relief_rms_m`` [m] where an item has
    none of its own (its own value wins)."""
    return [replace(it, material=material if it.material is None else it.material,
                    relief_rms_m=relief_rms_m if it.relief_rms_m is None else it.relief_rms_m) for it in items]


def discover(source: str | os.PathLike, *, material: str | None = None,
             relief_rms_m: float | None = None) -> list[CatalogItem]:
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
          written), ``width_mm``, ``dpi``, ``material`` (a library name; ``picture
          only``: the picture alone) and ``relief_mm`` (the relief RMS [mm], as
          ``--relief-mm``); relative paths are relative to the manifest's folder;
        * a single image file (its name is its id).
    material : str, optional
        Library name of the material of every picture whose manifest cell is absent or
        empty (every picture of a folder, glob or file).
    relief_rms_m : float, optional
        Relief RMS [m] of every picture whose manifest cell is absent or empty.

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
        items = _from_manifest_rows(path, _csv_rows(path), material, relief_rms_m)
    elif path.is_file() and path.suffix.lower() in (".jsonl", ".ndjson"):
        items = _from_manifest_rows(path, _jsonl_rows(path), material, relief_rms_m)
    elif path.is_file():
        items = [CatalogItem(path.name, os.path.abspath(path), material=material, relief_rms_m=relief_rms_m)]
    elif glob.has_magic(text):
        items = _from_glob(text)
        if not items:
            raise CatalogError(text, "the pattern matches no files")
    else:
        fault = path_fault(text)
        if fault not in (None, "file not found"):  # a link loop is not a missing file
            raise CatalogError(text, fault)
        raise CatalogError(text, "not found: give a folder, a glob, or a manifest (.csv, .jsonl)")
    if not path.is_file():
        items = with_defaults(items, material, relief_rms_m)
    items.sort(key=lambda it: it.id)
    return items


def _visible(rel: Path) -> bool:
    return not any(part.startswith(".") for part in rel.parts)


def _from_folder(root: Path) -> list[CatalogItem]:
    out = []
    for p in root.rglob("*"):
        rel = p.relative_to(root)
        if p.suffix.lower() in IMAGE_SUFFIXES and _visible(rel) and (item := _item(rel.as_posix(), p)) is not None:
            out.append(item)
    return out


def _item(item_id: str, p: Path) -> CatalogItem | None:
    """What a folder's or a glob's entry ``p`` lists: a file as an item; a FIFO, device or
    socket named in its own error row, not left out without a word (nor read: it may never
    end); nothing for a folder or a dangling link."""
    if p.is_file():
        return CatalogItem(item_id, os.path.abspath(p))
    special = special_file_fault(p)
    return None if special is None else CatalogItem(item_id, os.path.abspath(p), problem=special)


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
        if (item := _item(Path(os.path.relpath(p, root)).as_posix(), p)) is not None:
            out.append(item)
    return out


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


def _blank(value: Any) -> bool:
    return value is None or (isinstance(value, str) and not value.strip())


def _relief(value: Any, default: float | None) -> tuple[float | None, str | None]:
    """Manifest ``relief_mm`` cell -> (relief RMS [m], or ``default`` when blank; problem or None)."""
    if _blank(value):
        return default, None
    if isinstance(value, str):
        try:
            value = float(value.strip())
        except ValueError:
            pass  # refused below, as written
    try:
        return check_relief_mm(value, "relief_mm") * 1e-3, None
    except TactilizeError as exc:
        return None, f"manifest relief_mm {exc.fault}"


def _material(value: Any, default: str | None = None) -> tuple[str | None, str | None]:
    """Manifest cell -> (library name, the cell as written, or None; problem or None); a blank
    cell is ``default``, ``picture only`` is None."""
    from ..materials import MaterialChoice

    if _blank(value):
        return default, None
    try:
        return MaterialChoice.of(str(value)).name, None
    except MaterialError as exc:
        return str(value).strip(), f"manifest {exc.source}: {exc.fault}"


def _from_manifest_rows(manifest: Path, rows: Iterable[tuple[int, dict[str, Any]]], material: str | None = None,
                        relief_rms_m: float | None = None) -> list[CatalogItem]:
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
        mat, bad_m = _material(row.get("material"), material)
        if bad_m:
            problems.append(bad_m)
        relief, bad_r = _relief(row.get("relief_mm"), relief_rms_m)
        if bad_r:
            problems.append(bad_r)
        items[ident] = CatalogItem(ident, full, width_mm, dpi, "; ".join(problems) or None, mat, relief)
    if not items:
        raise CatalogError(str(manifest), "manifest lists no images")
    if not any(it.path for it in items.values()):
        raise CatalogError(str(manifest), f"manifest has no path column (one of {', '.join(_PATH_KEYS)})")
    return list(items.values())
