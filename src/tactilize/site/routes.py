"""A built site served by ``tactilize serve --site DIR``: its files as they are, under ``/shop/``.

The site needs nothing from the server but its static files (docs/shop.md), so the
pen page's server only hands them out: no route of its own renders anything.
"""

from __future__ import annotations

import mimetypes
import os
from pathlib import Path
from typing import Any

from ..errors import CatalogError

__all__ = ["site_router", "PREFIX"]

#: Where the site lives on the server.
PREFIX = "/shop"
_TYPES = {".js": "text/javascript", ".tsf": "application/octet-stream", ".css": "text/css", ".html": "text/html"}


def site_router(folder: str | os.PathLike, *, prefix: str = PREFIX) -> Any:
    """A FastAPI router serving the files of ``folder`` (a site ``tactilize site`` wrote) under ``prefix``.

    Raises
    ------
    CatalogError
        ``folder`` holds no built site (no ``index.html`` and ``tactile-surface.js``).
    """
    from fastapi import APIRouter, HTTPException
    from fastapi.responses import FileResponse, RedirectResponse

    root = Path(folder).resolve()
    if not (root / "index.html").is_file() or not (root / "tactile-surface.js").is_file():
        raise CatalogError(str(folder), "is not a site written by `tactilize site` (no index.html and tactile-surface.js)")
    r = APIRouter(prefix=prefix, tags=["site"])

    @r.get("", include_in_schema=False)
    def index_redirect() -> Any:
        return RedirectResponse(prefix + "/")

    @r.get("/{path:path}", include_in_schema=False)
    def file(path: str = "") -> Any:
        target = (root / (path or "index.html")).resolve()
        if target.is_dir():
            target = target / "index.html"
        if root not in target.parents or not target.is_file():
            raise HTTPException(404, "no such file in the site")
        kind = _TYPES.get(target.suffix) or mimetypes.guess_type(target.name)[0] or "application/octet-stream"
        return FileResponse(target, media_type=kind)

    return r
