"""The pen page's stroke export: a stroke in, a file out.

Routes (mounted by :func:`tactilize.web.app.create_app`)
--------------------------------------------------------
``GET  /api/export/formats``   the export formats (the one registry, :data:`tactilize.export.FORMATS`)
``POST /api/export/stroke``    JSON ``{"texture": ID, "format": NAME, "samples": [[t_s, x_mm, y_mm, pressure?], ...],
                               "profile": NAME?, "drive": "profile"|"wire"?}``; answers the file
                               (``Content-Disposition: attachment``), or 422 with one line naming the fault;
                               413 beyond :data:`.limits.MAX_EXPORT_BODY_BYTES`, 503 while
                               :data:`.limits.EXPORTS_ADMITTED` others are inside.

The stroke runs through the same path as ``tactilize export --stroke``
(:func:`tactilize.export.run_stroke`): the server's tracker, the texture's
map at its displayed size, the profile, a fresh simulated SMA wire (the
server's own output is not disturbed), and for the ``surface`` rendering the
texture's surface, whose bumps the parametric formats play and whose tip
acceleration the WAV carries (:func:`tactilize.export.wav.stroke_wav_source`, the
CLI's very file).
"""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import Response

from ..errors import RequestError
from ..http import ErrorAnsweringRoute
from .limits import MAX_EXPORT_BODY_BYTES, read_body
from .state import ServerState

__all__ = ["stroke_export_router", "MAX_STROKE_SAMPLES"]

#: Samples in one exported stroke, at most (a minute of a 1 kHz pen).
MAX_STROKE_SAMPLES = 60_000


def _export(state: ServerState, body: dict[str, Any]) -> tuple[bytes, Any, str]:
    from ..export import export_format, parse_stroke, render, run_stroke

    tid = body.get("texture")
    if not isinstance(tid, str):
        raise RequestError("texture", "give the texture id as 'texture'", 422)
    try:
        entry = state.texture(tid)
    except KeyError:
        raise RequestError(tid, f"no texture {tid!r}", 404) from None
    spec = export_format(str(body.get("format", "")))
    kind = body.get("drive", "profile")
    profile = state.profile_named(body["profile"]) if isinstance(body.get("profile"), str) else state.profile
    rows = body.get("samples")
    if not isinstance(rows, list):
        raise RequestError("samples", "give the stroke as 'samples': [[t_s, x_mm, y_mm, pressure?], ...]", 422)
    if len(rows) > MAX_STROKE_SAMPLES:
        raise RequestError("samples", f"too many samples ({len(rows)}, limit {MAX_STROKE_SAMPLES})", 422)
    tmap = entry.map
    stroke = parse_stroke(rows, "stroke", tmap.width_m, tmap.height_m)
    meta: dict[str, Any] = {"image": entry.name, "profile": profile.name}
    # The surface rendering's bumps go into the parametric formats (docs/surfaces.md, "Exports").
    surface = entry.surface  # the profile's rendering decides whether it is read
    tl = run_stroke(stroke, tmap, profile, meta=meta, surface=surface)
    source: Any = tl
    if spec.name == "wav":  # the tip's acceleration for a surface profile, as `export --stroke` writes it
        from ..export.wav import stroke_wav_source

        source = stroke_wav_source(tl, stroke, surface, str(kind))
    data = render(source, spec.name, drive=kind, **meta)
    return data, spec, f"stroke-{entry.id}{spec.file_tail}"


def stroke_export_router() -> APIRouter:
    """The routes of the module docstring, as a router."""
    r = APIRouter(prefix="/api/export", tags=["export"], route_class=ErrorAnsweringRoute)

    @r.get("/formats")
    async def formats() -> list[dict[str, Any]]:
        from ..export import FORMATS

        return [{"name": f.name, "suffix": f.suffix, "media_type": f.media_type, "description": f.description}
                for f in FORMATS.values()]

    @r.post("/stroke")
    async def export_stroke(request: Request) -> Response:
        state = request.app.state.tactilize
        # Bounded before parsing: at most EXPORTS_ADMITTED inside (else 503), a
        # body of at most MAX_EXPORT_BODY_BYTES (else 413), one rendered at a time.
        async with state.export_gate.admit():
            raw = await read_body(request, MAX_EXPORT_BODY_BYTES, "stroke",
                                  f"stroke too large (limit {MAX_EXPORT_BODY_BYTES // (1024 * 1024)} MB of JSON, "
                                  f"{MAX_STROKE_SAMPLES} samples)")
            try:
                body = json.loads(raw)
            except (ValueError, RecursionError):
                raise RequestError("body", "send the stroke as a JSON object", 400) from None
            if not isinstance(body, dict):
                raise RequestError("body", "send the stroke as a JSON object", 400)
            data, spec, name = await state.export_gate.run(_export, state, body)
        return Response(data, media_type=spec.media_type, headers={"Content-Disposition": f'attachment; filename="{name}"'})

    return r
