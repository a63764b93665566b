"""The pen app's ``/api`` routes: configuration, the gallery, pictures, features,
Fig. 5, uploads, profiles and statistics (the route table is in :mod:`.app`).

Every handler reads the shared :class:`~.state.ServerState` from
``request.app.state.tactilize`` and refuses a request by raising
:class:`~tactilize.errors.RequestError`.
"""

from __future__ import annotations

import asyncio
import json
import math
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, Response

from ..errors import ImageError, MaterialError, RequestError
from ..encode import jsonable
from ..http import ErrorAnsweringRoute

from ..pen.display import CARD_MM
from .constants import page_constants
from .limits import MAX_UPLOAD_BYTES, MAX_UPLOAD_PIXELS, read_body
from .state import ServerState, TextureEntry

__all__ = ["api_router", "MAX_UPLOAD_BYTES", "MAX_UPLOAD_PIXELS"]

#: Room for the multipart framing and the small form fields around the file [bytes].
_FORM_OVERHEAD = 64 * 1024


def api_router() -> APIRouter:
    """The ``/api`` routes of the pen app (listed in :mod:`.app`); the state is
    ``request.app.state.tactilize``, a :class:`~.state.ServerState`."""
    # Handlers refuse a request by raising RequestError.
    r = APIRouter(prefix="/api", route_class=ErrorAnsweringRoute)

    def st(request: Request) -> ServerState:
        return request.app.state.tactilize

    def texture(request: Request, texture_id: str) -> TextureEntry:
        try:
            return st(request).texture(texture_id)
        except KeyError:
            raise RequestError(texture_id, f"no texture {texture_id!r}", 404) from None

    @r.get("/config")
    async def config(request: Request) -> dict[str, Any]:
        s = st(request)
        return {
            "default_mm_per_px": s.m_per_px * 1e3,
            "profile": s.profile.name,
            "output": s.output_name,
            "channels": int(s.output.channels),
            "max_upload_bytes": MAX_UPLOAD_BYTES,
            "card_mm": list(CARD_MM),
        }

    @r.get("/constants")
    async def constants() -> dict[str, Any]:
        """The numbers of the server's rules the page needs (:func:`.constants.page_constants`)."""
        return page_constants()

    @r.get("/textures")
    async def textures(request: Request) -> list[dict[str, Any]]:
        s = st(request)
        # The first call may have to generate pictures: keep the loop free.
        entries = list(s.textures.values())
        return await asyncio.get_running_loop().run_in_executor(None, lambda: [e.describe() for e in entries])

    @r.get("/textures/{texture_id}.png")
    async def texture_png(texture_id: str, request: Request) -> Response:
        e = texture(request, texture_id)
        png = await asyncio.get_running_loop().run_in_executor(None, lambda: e.png)
        return Response(png, media_type="image/png", headers={"Cache-Control": "max-age=3600"})

    @r.get("/textures/{texture_id}/features")
    async def texture_features(texture_id: str, request: Request) -> Any:
        e = texture(request, texture_id)
        m = await asyncio.get_running_loop().run_in_executor(None, lambda: e.map)
        return jsonable(
            {
                **e.describe(with_features=False),
                "features": m.whole.to_dict(),
                "map": {
                    **m.summary(),
                    "spatial_frequency_per_m": m.field("spatial_frequency_per_m").tolist(),
                    "spectral_intensity": m.field("spectral_intensity").tolist(),
                    "orientation_deg": m.field("orientation_deg").tolist(),
                },
            }
        )

    @r.get("/textures/{texture_id}/spectrum")
    async def texture_spectrum(texture_id: str, request: Request) -> Any:
        """The paper's Fig. 5 for one picture: log spectrum (PNG data URL), the peak, the tiles."""
        e = texture(request, texture_id)
        doc = await asyncio.get_running_loop().run_in_executor(None, lambda: _spectrum_doc(e))
        return jsonable(doc)

    @r.get("/materials")
    async def materials(request: Request) -> dict[str, Any]:
        """The page's picker: the library's materials, and what the server renders pictures as."""
        from ..materials import PICTURE_ONLY, library

        s = st(request)
        return {
            "default": s.material.name,
            "default_rendered_as": s.material.label(),
            "picture_only": PICTURE_ONLY,
            "materials": [{"name": m.name, "description": m.description,
                           "rendered_as": s.material_named(m.name).label()} for m in library().values()],
        }

    @r.post("/textures/{texture_id}/rendered")
    async def rendered(texture_id: str, request: Request) -> Any:
        """JSON ``{"material": NAME}`` (``""`` or null: picture only): the picture of
        ``texture_id`` rendered as that material, as a gallery entry of its own id (its
        ``base`` is the picture's); 404 an unknown texture, 422 an unknown material."""
        s = st(request)
        texture(request, texture_id)
        body = await read_body(request, 4096, "material choice")
        try:
            doc = json.loads(body or b"{}")
        except ValueError:
            raise RequestError("material choice", "send JSON {\"material\": NAME}", 400) from None
        name = doc.get("material") if isinstance(doc, dict) else None
        if name is not None and not isinstance(name, str):
            raise RequestError("material", "the material must be a name (a string) or null", 422)
        try:
            entry = await s.upload_gate.run(s.rendered, texture_id, name or "")
        except MaterialError as exc:
            raise RequestError("material", f"{exc.source}: {exc.fault}", 422) from None
        except KeyError:
            raise RequestError(texture_id, f"no texture {texture_id!r}", 404) from None
        return entry.describe()

    @r.post("/textures")
    async def upload(request: Request) -> Any:
        """Multipart form: ``file`` (the picture), optional ``width_mm`` or ``dpi`` and
        ``material`` (a library name, ``""`` for picture only; the server's choice when
        absent); 503 while :data:`.limits.UPLOADS_ADMITTED` others are inside (before the
        body is read)."""
        s = st(request)
        try:
            async with s.upload_gate.admit():
                return await _upload(s, request)
        except RequestError as exc:
            if exc.status == 503:
                s.counters["uploads_busy"] += 1
            raise

    async def _upload(s: ServerState, request: Request) -> Any:
        too_large = f"file too large (limit {MAX_UPLOAD_BYTES // (1024 * 1024)} MB)"
        # The body is bounded *before* the multipart parser sees it: a parser
        # left alone would spool any size to disk before the handler could refuse.
        try:
            body = await read_body(request, MAX_UPLOAD_BYTES + _FORM_OVERHEAD, "upload", too_large)
        except RequestError as exc:
            if exc.status == 413:
                s.counters["uploads_refused"] += 1
            raise
        request._body = body  # Starlette's form parser reads the cached body
        try:
            form = await request.form(max_files=1, max_fields=8)
        except Exception as exc:  # malformed multipart: say so, never a 500
            raise RequestError("upload", f"not a valid multipart form ({exc.__class__.__name__})", 400) from None
        file = form.get("file")
        if file is None or isinstance(file, str):
            raise RequestError("file", "send the picture as the form field 'file'", 422)
        src = Path(file.filename or "upload").name or "upload"
        w_mm, dpi = _number(form.get("width_mm"), "width_mm"), _number(form.get("dpi"), "dpi")
        if w_mm is not None and dpi is not None:
            raise RequestError("width_mm/dpi", "give width_mm or dpi, not both", 422)
        material_field = form.get("material")
        if material_field is not None and not isinstance(material_field, str):
            raise RequestError("material", "material must be a name, got a file", 422)
        try:
            choice = s.material_named(material_field)
        except MaterialError as exc:
            raise RequestError("material", f"{exc.source}: {exc.fault}", 422) from None
        data = await file.read()
        # The messages name the file: the page shows them as they are.
        if len(data) > MAX_UPLOAD_BYTES:
            s.counters["uploads_refused"] += 1
            raise RequestError(src, f"{src}: {too_large}", 413)
        if not data:
            raise RequestError(src, f"{src}: empty file", 422)
        try:
            entry = await s.upload_gate.run(s.add_upload, data, src, w_mm, dpi, choice)
        except ImageError as exc:
            s.counters["uploads_refused"] += 1
            raise RequestError(src, f"{src}: {exc.fault}", 415 if "not an image" in exc.fault else 422) from None
        s.counters["uploads"] += 1
        return JSONResponse(entry.describe(), status_code=201)

    @r.get("/profiles")
    async def profiles(request: Request) -> dict[str, Any]:
        s = st(request)
        return {
            "default": s.profile.name,
            "profiles": [
                {"name": name, "description": p.description, "limits": p.limits.to_dict(), "laws": jsonable(p.to_dict())}
                for name, p in s.profiles().items()
            ],
        }

    @r.get("/stats")
    async def stats(request: Request, last: int | None = None) -> dict[str, Any]:
        return st(request).stats(last)

    return r


def _spectrum_doc(e: TextureEntry) -> dict[str, Any]:
    import base64

    from ..data import png_bytes
    from ..image import load_image
    from ..maps.spectrumview import spectrum_view

    img = load_image(e.png)
    m = e.map
    d = spectrum_view(img.pixels, m.whole, m)
    u8 = d.pop("spectrum_u8")
    d["spectrum_url"] = "data:image/png;base64," + base64.b64encode(png_bytes(u8, 96.0)).decode()
    d["id"] = e.id
    return d


def _number(text: object, name: str) -> float | None:
    """A positive form number, or None when absent.

    Raises
    ------
    RequestError
        Not a number (a file part included), or out of its range (422).
    """
    if text is None or str(text).strip() == "":
        return None
    if not isinstance(text, str):
        raise RequestError(name, f"{name} must be a number, got a file", 422)
    try:
        v = float(text)
    except ValueError:
        raise RequestError(name, f"{name} must be a number, got {text!r}", 422) from None
    if not math.isfinite(v) or v <= 0:
        raise RequestError(name, f"{name} must be a positive number, got {text!r}", 422)
    if name == "width_mm" and v > 2000:
        raise RequestError(name, f"{name} must be at most 2000 mm, got {text!r}", 422)
    if name == "dpi" and not 10 <= v <= 10000:
        raise RequestError(name, f"{name} must be between 10 and 10000, got {text!r}", 422)
    return v
