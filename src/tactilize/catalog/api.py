"""The read API of a catalog: a product's tactile profile by id, and its exports.

``tactilize serve --catalog PATH`` mounts :func:`catalog_router` on the web app;
:func:`create_catalog_app` serves it alone.  Every route is described in the
OpenAPI schema (``/openapi.json``; ``/api/docs`` on the web app).

Routes (prefix ``/api/catalog``)
--------------------------------
``GET  /api/catalog``                                    counts, profile, reference speeds
``GET  /api/catalog/products``                           ids, a page at a time
``GET  /api/catalog/products/{id}``                      the tactile profile of a product
``GET  /api/catalog/products/{id}/drive?speed_mm_s=``    the drive at any stroking speed
``GET  /api/catalog/products/{id}/export/ahap``          Apple Core Haptics pattern (JSON)
``GET  /api/catalog/products/{id}/export/android``       Android VibrationEffect waveform (JSON)
``GET  /api/catalog/products/{id}/export/wav``           the pulse train as 16-bit PCM WAV
``GET  /api/catalog/products/{id}/export/{format}``      any other format of the export registry (hjif, haptic, ...)

A product's row names what its picture is rendered as (``material``, from the manifest):
with a surface profile its drive at any speed and its exports are that material's, as
``--material`` renders the picture (:meth:`~tactilize.catalog.Catalog.drive`), like the
drives the batch stored.

Ids may contain ``/`` (a folder catalog's ids are relative paths).  A product
whose image could not be analysed has a profile with ``status == "error"`` and
its reason; its drive and exports answer 409.
"""

from __future__ import annotations

import os
from typing import Any, Literal

from fastapi import APIRouter, FastAPI, Query
from fastapi.responses import Response
from pydantic import BaseModel, Field

from ..drive import Drive
from ..errors import MaterialError, RequestError
from ..http import ErrorAnsweringRoute
from .reader import Catalog

__all__ = ["PREFIX", "catalog_router", "create_catalog_app"]

PREFIX = "/api/catalog"

#: Longest export a request may ask for [s]: a WAV of 30 s at 48 kHz is 2.9 MB.
MAX_EXPORT_S = 30.0


# ----------------------------------------------------------------- response models


class CatalogInfo(BaseModel):
    """What the catalog holds."""

    profile: str = Field(description="Name of the profile the stored drives were computed with.")
    speeds_mm_s: list[float] = Field(description="Reference stroking speeds of the stored drives [mm/s].")
    total: int
    ok: int
    failed: int


class ProductPage(BaseModel):
    """A page of product ids, in id order."""

    ids: list[str]
    offset: int
    limit: int


class DriveAtSpeed(BaseModel):
    """One actuator drive at a stroking speed (SI units, plus mm/s and ms for display)."""

    speed_mm_s: float
    pulse_frequency_hz: float
    pulse_width_s: float
    pulse_width_ms: float
    duty_ratio: float
    amplitude: float = Field(description="Fraction of the actuator's rated peak current, 0..1.")
    clamped: list[str] = Field(description="Actuator limits that changed this drive.")


class TactileProfile(BaseModel):
    """Everything the catalog knows about a product's texture."""

    id: str
    status: Literal["ok", "error"]
    error: str | None = Field(None, description="Why the image could not be analysed (status 'error').")
    profile: str = Field(description="Profile of the stored drives.")
    material: str | None = Field(None, description="The library material the picture is rendered as (null: the picture alone).")
    rendered_as: str | None = Field(None, description="What the picture is rendered as, in words (null when the row's material is not in the library).")
    tactilize_version: str | None = Field(None, description="tactilize version that computed the row (null in catalogs of format 2 and earlier).")
    analysis_version: int | None = Field(None, description="Version of the analysis that computed the row (null in catalogs of format 2 and earlier).")
    image: dict[str, Any] = Field(default_factory=dict, description="width_px, height_px, width_mm, height_mm, pitch_m, decode_scale.")
    features: dict[str, Any] = Field(default_factory=dict, description="Whole-image features (spatial_frequency_per_m, spectral_intensity, ...).")
    texture_map: dict[str, Any] = Field(default_factory=dict, description="How the texture varies across the picture (tile grid summary).")
    drives: list[DriveAtSpeed] = Field(default_factory=list, description="Drives at the reference speeds.")


class AndroidWaveform(BaseModel):
    """Arguments of ``VibrationEffect.createWaveform(timings, amplitudes, repeat)``."""

    timings_ms: list[int]
    amplitudes: list[int] = Field(description="0..255 per segment.")
    repeat: int = Field(-1, description="Index to repeat from; -1 plays once.")
    envelope: list[dict[str, float]] = Field(
        default_factory=list, description="API 36 envelope control points: amplitude 0..1, frequency_hz, duration_ms."
    )
    drive: dict[str, Any] = Field(default_factory=dict, description="The drive the waveform renders.")


class ErrorMessage(BaseModel):
    error: str


_IMAGE_KEYS = ("width_px", "height_px", "width_mm", "height_mm", "pitch_m", "decode_scale")
_ROW_KEYS = {"id", "path", "status", "error", "profile", "material", "relief_rms_m", "seconds", "tactilize_version",
             "analysis_version"}


def _profile_doc(catalog: Catalog, row: dict[str, Any]) -> TactileProfile:
    image = {k: row.get(k) for k in _IMAGE_KEYS}
    texture_map = {k[4:]: v for k, v in row.items() if k.startswith("map_")}
    features = {
        k: v
        for k, v in row.items()
        if k not in _ROW_KEYS and k not in _IMAGE_KEYS and not k.startswith(("map_", "drive_"))
    }
    drives = [_drive_doc(drv, speed) for speed, drv in catalog.stored_drives(row)]
    try:
        choice = catalog.choice_of(row)
        material, rendered_as = choice.name, choice.label()
    except MaterialError:  # an error row of a name the library does not hold: said as written
        material, rendered_as = str(row.get("material")), None
    return TactileProfile(
        id=str(row["id"]),
        status=row.get("status") or "error",
        error=row.get("error"),
        profile=str(row.get("profile") or catalog.profile.name),
        material=material,
        rendered_as=rendered_as,
        tactilize_version=row.get("tactilize_version"),
        analysis_version=row.get("analysis_version"),
        image=image,
        features=features,
        texture_map=texture_map,
        drives=drives,
    )


def _drive_doc(drv: Drive, speed_m_s: float) -> DriveAtSpeed:
    return DriveAtSpeed(speed_mm_s=speed_m_s * 1e3, **drv.to_dict())


def _export_response(drive: Drive, fmt: str, product_id: str, duration_s: float, sample_rate_hz: int) -> Response:
    """One export, in the format tactilize.export defines (the one registry of formats)."""
    from ..export import export_format, render

    spec = export_format(fmt)
    data = render(drive, spec.name, duration_s, sample_rate_hz=sample_rate_hz)
    name = f"{_file_stem(product_id)}{spec.file_tail}"
    return Response(data, media_type=spec.media_type, headers={"Content-Disposition": f'attachment; filename="{name}"'})


# ----------------------------------------------------------------- the router


def catalog_router(catalog: Catalog | str | os.PathLike, *, prefix: str = PREFIX) -> APIRouter:
    """The catalog read API as a FastAPI router.

    Parameters
    ----------
    catalog : Catalog, str or path
        An open :class:`~tactilize.catalog.Catalog`, or its Parquet folder / SQLAlchemy URL.
    prefix : str
        Where the routes live.

    Returns
    -------
    APIRouter
        Mount it with ``app.include_router(router)`` (or ``create_app(extra_routers=[router])``).
    """
    cat = catalog if isinstance(catalog, Catalog) else Catalog(catalog)
    # Routes raise RequestError (404, 409) or any TactilizeError (422): answered as JSON.
    r = APIRouter(prefix=prefix, tags=["catalog"], route_class=ErrorAnsweringRoute)
    missing: dict[int | str, dict[str, Any]] = {404: {"model": ErrorMessage, "description": "No product with this id."}}
    failed: dict[int | str, dict[str, Any]] = {409: {"model": ErrorMessage, "description": "The product's image could not be analysed."}}

    def lookup(product_id: str) -> dict[str, Any]:
        row = cat.get(product_id)
        if row is None:
            raise RequestError(product_id, f"no product {product_id!r} in the catalog", 404)
        return row

    def ok_row(product_id: str) -> dict[str, Any]:
        row = lookup(product_id)
        if row.get("status") != "ok":
            raise RequestError(product_id, f"product {product_id!r} has no tactile profile: {row.get('error')}", 409)
        return row

    speed_q = Query(60.0, ge=0.0, le=5000.0, description="Stroking speed [mm/s].")
    duration_q = Query(1.0, gt=0.0, le=MAX_EXPORT_S, description="Length of the export [s].")

    @r.get("", response_model=CatalogInfo, summary="What the catalog holds")
    def info() -> CatalogInfo:
        return CatalogInfo(profile=cat.profile.name, speeds_mm_s=[v * 1e3 for v in cat.speeds_m_s], **cat.counts())

    @r.get("/products", response_model=ProductPage, summary="Product ids, a page at a time")
    def products(
        offset: int = Query(0, ge=0),
        limit: int = Query(100, ge=1, le=10_000),
        status: Literal["ok", "error"] | None = Query(None, description="Only products with this status."),
    ) -> ProductPage:
        return ProductPage(ids=cat.ids(offset=offset, limit=limit, status=status), offset=offset, limit=limit)

    # The specific routes come before the plain one: ids may contain "/", so
    # "/products/{id:path}" would otherwise swallow ".../drive" and ".../export/...".
    @r.get(
        "/products/{product_id:path}/drive",
        response_model=DriveAtSpeed,
        responses={**missing, **failed},
        summary="The drive of a product at any stroking speed",
    )
    def product_drive(product_id: str, speed_mm_s: float = speed_q) -> Any:
        row = ok_row(product_id)
        return _drive_doc(cat.drive(row, speed_mm_s * 1e-3), speed_mm_s * 1e-3)

    @r.get(
        "/products/{product_id:path}/export/ahap",
        responses={200: {"content": {"application/json": {}}, "description": "An AHAP file (Apple Core Haptics)."}, **missing, **failed},
        summary="Apple AHAP pattern of the product stroked at a speed",
    )
    def export_ahap(product_id: str, speed_mm_s: float = speed_q, duration_s: float = duration_q) -> Any:
        return _export_response(cat.drive(ok_row(product_id), speed_mm_s * 1e-3), "ahap", product_id, duration_s, 48_000)

    @r.get(
        "/products/{product_id:path}/export/android",
        response_model=AndroidWaveform,
        responses={**missing, **failed},
        summary="Android VibrationEffect waveform of the product stroked at a speed",
    )
    def export_android(product_id: str, speed_mm_s: float = speed_q, duration_s: float = duration_q) -> Any:
        return _export_response(cat.drive(ok_row(product_id), speed_mm_s * 1e-3), "android", product_id, duration_s, 48_000)

    @r.get(
        "/products/{product_id:path}/export/wav",
        response_class=Response,
        responses={
            200: {"content": {"audio/wav": {"schema": {"type": "string", "format": "binary"}}}, "description": "16-bit mono PCM."},
            **missing,
            **failed,
        },
        summary="The product's pulse train at a speed as a WAV file",
    )
    def export_wav(
        product_id: str,
        speed_mm_s: float = speed_q,
        duration_s: float = duration_q,
        sample_rate_hz: int = Query(48_000, ge=8_000, le=192_000, description="Samples per second [Hz]."),
    ) -> Any:
        return _export_response(cat.drive(ok_row(product_id), speed_mm_s * 1e-3), "wav", product_id, duration_s, sample_rate_hz)

    @r.get(
        "/products/{product_id:path}/export/{fmt}",
        responses={200: {"description": "The file, in a format of tactilize.export.FORMATS."}, **missing, **failed},
        summary="The product stroked at a speed, in any export format (hjif, haptic, log, ...)",
    )
    def export_any(product_id: str, fmt: str, speed_mm_s: float = speed_q, duration_s: float = duration_q) -> Any:
        from ..export import FORMATS

        if fmt not in FORMATS:
            raise RequestError(fmt, f"unknown export format {fmt!r} (use one of: {', '.join(FORMATS)})", 404)
        return _export_response(cat.drive(ok_row(product_id), speed_mm_s * 1e-3), fmt, product_id, duration_s, 48_000)

    @r.get(
        "/products/{product_id:path}",
        response_model=TactileProfile,
        responses=missing,
        summary="The tactile profile of a product",
    )
    def product(product_id: str) -> Any:
        return _profile_doc(cat, lookup(product_id))

    return r


def _file_stem(product_id: str) -> str:
    """A download name from an id ("sub/shirt.jpg" -> "sub_shirt")."""
    stem = os.path.splitext(product_id)[0] if "." in product_id[-6:] else product_id
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in stem).strip("_")
    return safe or "product"


def create_catalog_app(location: str | os.PathLike | Catalog) -> FastAPI:
    """A FastAPI app serving only the catalog read API (``uvicorn`` can run it).

    Parameters
    ----------
    location : str, path or Catalog
        The Parquet folder or SQLAlchemy URL made by ``tactilize batch``.
    """
    app = FastAPI(title="tactilize catalog", docs_url="/api/docs", redoc_url=None)
    app.include_router(catalog_router(location))
    return app
