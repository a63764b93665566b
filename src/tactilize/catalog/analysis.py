"""One image -> one catalog row: features, texture-map summary and drives at reference speeds.

The functions here run in workers (local processes or Dask): they take small,
picklable arguments, never raise for a bad image, and return plain dicts.

Every row records the tactilize version and :data:`ANALYSIS_VERSION`, and so
does the catalog's fingerprint (:meth:`AnalysisSettings.fingerprint`): a
catalog resumed by another version would mix rows computed two ways, and
:func:`~tactilize.catalog.run_batch` refuses it.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import __version__
from ..errors import CatalogError, ImageError, TactilizeError
from ..image import DEFAULT_MAX_PIXELS, TextureImage, load_image
from ..mapping import DEFAULT_PRESET, Profile
from ..surface.rendering import rendering_for
from .sources import CatalogItem

__all__ = [
    "ANALYSIS_VERSION",
    "DEFAULT_SPEEDS_M_S",
    "FORMAT_VERSION",
    "AnalysisSettings",
    "analyse_chunk",
    "analyse_item",
    "catalog_columns",
    "speed_label",
]

#: Reference stroking speeds [m/s] at which every row stores the drive: a slow,
#: the paper's centre (60 mm/s, where its sigmoid alpha is half way) and a fast stroke.
DEFAULT_SPEEDS_M_S: tuple[float, ...] = (0.030, 0.060, 0.120)

#: Version of the on-disk layout, kept in the catalog's metadata.  3: every row
#: and the fingerprint carry ``tactilize_version`` and ``analysis_version``; 4: every
#: row has ``material`` (what its picture was rendered as; empty for the picture alone).
FORMAT_VERSION = 4

#: Version of the numbers in a row for a given image and settings.  Bump it with
#: any change to the features, the texture map or the drives that moves a stored
#: value.  1 stands for every catalog written before the version was recorded
#: (format 2 and earlier); 2: ``mean_level`` is the plain mean, and i_s with it
#: (commit fc1de98); 3: a surface profile's drives are its rendering's (the equivalent Drive
#: of a steady stroke's events), not its laws'.
ANALYSIS_VERSION = 3


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
        1/8 of their size, in the DCT domain, so that the analysed pitch stays
        at or below this (``load_image(draft_pitch_m=...)``).  None: every
        image is decoded in full.
    max_pixels : int
        Images with more pixels are refused (decompression bombs).
    full_map : bool
        Measure every texture-map tile whole.  By default each tile is
        measured on its centred half-size square when that holds at least two
        periods of the image's texture (``texture_map(sample_px="auto")``): a
        quarter of the tile FFT work, local frequencies within 1 % of the
        whole-tile values on gratings of 4.5 to 31 pixels (docs/batch.md).
    relief_column : bool
        Rows have a ``relief_rms_m`` column [m] (the relief given to the picture, None when
        none was): set when a picture of the batch is given one.  Only then is it part of
        the fingerprint, so that a catalog without the column keeps its fingerprint and resumes.
    """

    profile: Profile = field(default_factory=lambda: Profile.preset(DEFAULT_PRESET))
    speeds_m_s: tuple[float, ...] = DEFAULT_SPEEDS_M_S
    dpi: float | None = None
    analysis_pitch_m: float | None = None
    max_pixels: int = DEFAULT_MAX_PIXELS
    full_map: bool = False
    relief_column: bool = False

    def __post_init__(self) -> None:
        speeds = tuple(float(v) for v in self.speeds_m_s)
        if not speeds or any(not math.isfinite(v) or v < 0 for v in speeds):
            raise CatalogError("<speeds>", f"reference speeds must be finite numbers >= 0 m/s, got {self.speeds_m_s!r}")
        if len({speed_label(v) for v in speeds}) != len(speeds):
            raise CatalogError("<speeds>", f"reference speeds must differ, got {self.speeds_m_s!r}")
        object.__setattr__(self, "speeds_m_s", speeds)
        for name in ("dpi", "analysis_pitch_m"):
            value = getattr(self, name)
            if value is not None and (not math.isfinite(value) or value <= 0):
                raise CatalogError(f"<{name}>", f"must be a positive number, got {value!r}")

    def fingerprint(self) -> dict[str, Any]:
        """What a catalog's rows depend on, versions included; a rerun must match it to resume."""
        doc: dict[str, Any] = {
            "format": FORMAT_VERSION,
            "tactilize": __version__,
            "analysis": ANALYSIS_VERSION,
            "profile": self.profile.to_dict(),
            "speeds_m_s": list(self.speeds_m_s),
            "dpi": self.dpi,
            "analysis_pitch_m": self.analysis_pitch_m,
            "max_pixels": self.max_pixels,
            "full_map": self.full_map,
        }
        if self.relief_column:
            # A catalog's columns are fixed when it is made (an SQL table cannot take one more).
            doc["relief_rms_m"] = True
        # Through JSON so that it compares equal to the copy read back from a store.
        return json.loads(json.dumps(doc))


def speed_label(speed_m_s: float) -> str:
    """Column-safe label of a speed [m/s] in mm/s: 0.06 -> '60mm_s', 0.0075 -> '7p5mm_s'."""
    return f"{speed_m_s * 1e3:.6g}".replace(".", "p") + "mm_s"


def base_row(item: CatalogItem, settings: AnalysisSettings) -> dict[str, Any]:
    """The columns every row has, ok or not, before its status is known."""
    row: dict[str, Any] = {
        "id": item.id,
        "path": item.path,
        "status": "ok",
        "error": None,
        "profile": settings.profile.name,
        "material": item.material or "",
        "tactilize_version": __version__,
        "analysis_version": ANALYSIS_VERSION,
    }
    if settings.relief_column:
        row["relief_rms_m"] = item.relief_rms_m
    return row


def _load(item: CatalogItem, settings: AnalysisSettings) -> TextureImage:
    # The manifest row's dpi or width_mm first, then the batch's --dpi; load_image does the rest.
    if item.dpi is not None or item.width_mm is not None:
        dpi, width_mm = item.dpi, item.width_mm
    else:
        dpi, width_mm = settings.dpi, None
    return load_image(
        item.path, dpi=dpi, width_mm=width_mm, max_pixels=settings.max_pixels, draft_pitch_m=settings.analysis_pitch_m
    )


def _row_from_image(img: TextureImage, settings: AnalysisSettings, material: str | None = None,
                    relief_rms_m: float | None = None) -> dict[str, Any]:
    from ..maps.texturemap import texture_map

    tmap = texture_map(img, sample_px=None if settings.full_map else "auto")
    # The map analyses the whole image as well; reuse it rather than a second FFT.
    feat = tmap.whole
    row: dict[str, Any] = {
        "width_px": int(img.shape[1]),
        "height_px": int(img.shape[0]),
        "decode_scale": int(img.decode_scale),
        "pitch_m": float(img.pitch_m[0]),
        "width_mm": img.width_m * 1e3,
        "height_mm": img.height_m * 1e3,
    }
    for key, value in feat.to_dict().items():
        if isinstance(value, (bool, int, float, str)):
            row[key] = value
    for key, value in tmap.summary().items():
        row[f"map_{key}"] = value
    # Made once per picture.
    rendering = rendering_for(settings.profile, image=img, material=material, relief_rms_m=relief_rms_m)
    if (material is not None or relief_rms_m is not None) and not rendering.reads_surface:
        # A rendering that does not read the picture as a surface would ignore the material and relief.
        what = "a material" if material is not None else "a relief"
        raise CatalogError(material or "relief_mm", f"{what} needs a surface profile (this one's rendering is "
                                                    f"{rendering.name!r})")
    for speed in settings.speeds_m_s:
        # What every command renders for this picture stroked steadily at this speed.
        drv = rendering.steady_drive(feat, speed)
        prefix = f"drive_{speed_label(speed)}_"
        row[prefix + "pulse_frequency_hz"] = drv.pulse_frequency_hz
        row[prefix + "pulse_width_s"] = drv.pulse_width_s
        row[prefix + "duty_ratio"] = drv.duty_ratio
        row[prefix + "amplitude"] = drv.amplitude
        row[prefix + "clamped"] = ",".join(drv.clamped)
        # Where the width law puts the texture in an actuator's felt band (None when off).
        row[prefix + "strength"] = float(drv.strength) if drv.strength is not None else None
        row[prefix + "regularity"] = float(drv.regularity) if drv.regularity is not None else None
    return row


def analyse_item(item: CatalogItem, settings: AnalysisSettings) -> dict[str, Any]:
    """One catalog row for one item; never raises for a bad image.

    Returns
    -------
    dict
        ``id``, ``path``, ``status`` (``"ok"`` or ``"error"``), ``error`` (the
        reason, None when ok), ``profile``, ``material`` (the manifest's, empty for the
        picture alone), ``relief_rms_m`` [m] (with ``settings.relief_column``: the relief
        given, None when none was), ``tactilize_version``,
        ``analysis_version``, ``seconds`` (analysis time [s]) and, when ok, the
        image, feature, ``map_*`` and ``drive_<speed>mm_s_*`` columns.
    """
    t0 = time.perf_counter()
    row = base_row(item, settings)
    try:
        if item.problem:
            raise ImageError(item.path or item.id, item.problem)
        row.update(_row_from_image(_load(item, settings), settings, item.material, item.relief_rms_m))
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
    probe = _row_from_image(load_image(grating, dpi=96.0), settings)
    # A relief given, so that its column's kind is a float's.
    head = base_row(CatalogItem("", "", relief_rms_m=1e-5), settings)
    cols = [(key, _KIND_OF[type(value)] if value is not None else "str") for key, value in head.items()]
    cols.append(("seconds", "float"))
    for key, value in probe.items():
        kind = _KIND_OF.get(type(value), "float")
        cols.append((key, kind))
    return cols
