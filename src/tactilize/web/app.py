"""The ASGI application behind ``tactilize serve``.

Routes
------
``GET /``                              the page
``GET /static/...``                    its ES modules and stylesheet (no build step)
``GET /api/config``                    defaults: mm per CSS px, profile, output, channels
``GET /api/constants``                 the numbers of the server's rules the page needs (web/constants.py)
``GET /api/textures``                  the gallery: built-ins and uploads, with features
``GET /api/textures/{id}.png``         a picture (grey PNG carrying its DPI)
``GET /api/textures/{id}/features``    whole-picture features and the tile map
``POST /api/textures``                 upload a picture (multipart ``file``, optional
                                       ``width_mm`` or ``dpi``, ``material``); size-limited, validated
                                       by :func:`tactilize.image.load_image`
``GET /api/materials``                 the page's material picker: the library, the server's choice
``POST /api/textures/{id}/rendered``   a picture rendered as another material (JSON ``material``)
``GET /api/profiles``                  the profiles the page may pick
``GET /api/stats``                     server-side latency percentiles and counters
``GET /api/export/formats``            export formats; ``POST /api/export/stroke``: a stroke as a file
                                       (see :mod:`.stroke_export`)
``WS  /ws``                            pen samples in, drives out (see :mod:`.session`)

Extending
---------
Pass routers to :func:`create_app` (``extra_routers=[router]``) or call
``app.include_router(router)`` on the returned app; the shared state (output,
profile, textures) is ``app.state.tactilize`` (a :class:`ServerState`), reachable
from a request as ``request.app.state.tactilize``.
"""

from __future__ import annotations

import asyncio
import logging
from contextlib import asynccontextmanager
from importlib import resources
from pathlib import Path
from typing import Callable, Iterable

from fastapi import APIRouter, FastAPI, WebSocket
from fastapi.responses import FileResponse, Response
from fastapi.staticfiles import StaticFiles

from ..actuators.base import Output
from ..errors import TactilizeError
from ..mapping import Profile
from ..materials import MaterialChoice
from .api import api_router
from ..http import settle_heap
from .limits import MAX_UPLOAD_BYTES, MAX_UPLOAD_PIXELS
from .rows import DEFAULT_M_PER_CSS_PX
from .state import ServerState, TextureEntry

__all__ = ["create_app", "ServerState", "TextureEntry", "MAX_UPLOAD_BYTES", "MAX_UPLOAD_PIXELS"]

log = logging.getLogger("tactilize.web")


_STATIC = Path(str(resources.files("tactilize.web").joinpath("static")))


def _default_output() -> tuple[Output, str]:
    """The simulated wire through the output factory; a recorder if it is not built yet."""
    try:
        from ..actuators.factory import open_output

        return open_output("simulated"), "simulated"
    except (ImportError, TactilizeError) as exc:
        from ..actuators.recording import RecordingOutput

        log.warning("simulated output unavailable (%s); drives are only recorded", exc)
        return RecordingOutput(), "recorder"


def _simulated() -> Output:
    from ..actuators.factory import open_output

    return open_output("simulated")


def create_app(
    output: Output | None = None,
    profile: Profile | str | None = None,
    *,
    output_name: str | None = None,
    m_per_px: float = DEFAULT_M_PER_CSS_PX,
    extra_routers: Iterable[APIRouter] = (),
    warm: bool = True,
    close_output: bool | None = None,
    hosts: Iterable[str] | None = None,
    max_sockets: int | None = None,
    page_outputs: Callable[[], Output] | None = None,
    material: MaterialChoice | str | None = None,
) -> FastAPI:
    """Build the tactile pen application.

    Parameters
    ----------
    output : Output, optional
        Where drives go.  By default the simulated SMA wire from
        ``open_output("simulated")``.
    profile : Profile or str, optional
        The default profile, or a preset name / TOML path; the paper's by default.
    output_name : str, optional
        How the page names the output (e.g. ``"serial:/dev/ttyACM0"``).
    m_per_px : float
        Size of a CSS pixel [m] before the page is calibrated (1/96 inch).
    extra_routers : iterable of APIRouter
        Mounted as they are (experiments, catalogs...).
    warm : bool
        Generate the built-in pictures at startup (in a thread, not blocking requests).
    close_output : bool, optional
        Close the output at shutdown; by default only when the app opened it.
    hosts : iterable of str, optional
        The host names the app answers to (:func:`.guard.accepted_hosts` of the
        bind address); the loopback names by default.  Requests and sockets naming
        another host, and sockets or state-changing requests from another site's
        page, are refused (:mod:`.guard`).
    max_sockets : int, optional
        WebSockets open at once, at most (:data:`.guard.DEFAULT_MAX_SOCKETS`).
    page_outputs : callable, optional
        Makes one output per page (a simulated wire: each page feels its own).
        Without it ``output`` is one device the pages take turns on
        (:mod:`.ownership`).  By default per page when the app opens the
        simulated wire itself.
    material : MaterialChoice or str, optional
        What the built-in pictures and uploads are rendered as (a library name, or a
        :class:`~tactilize.materials.MaterialChoice` with a given relief); the page's picker
        may render a picture as another.  Picture only by default.

    Returns
    -------
    FastAPI
        ``app.state.tactilize`` is the :class:`ServerState`.
    """
    if profile is None or isinstance(profile, str):
        profile = Profile.resolve(profile)
    owned = output is None
    if output is None:
        output, default_name = _default_output()
        output_name = output_name or default_name
        if page_outputs is None and default_name == "simulated":
            page_outputs = _simulated
    if not isinstance(material, MaterialChoice):
        material = MaterialChoice.of(material)  # an unknown name fails here, before anything is served
    state = ServerState(output, profile, m_per_px, output_name or "", material)
    state.page_output_factory = page_outputs
    if close_output is None:
        close_output = owned

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        warm_task = None
        if warm:
            warm_task = asyncio.get_running_loop().run_in_executor(None, state.warm)
            warm_task.add_done_callback(lambda _: settle_heap())
        try:
            yield
        finally:
            if warm_task is not None:
                try:
                    await asyncio.wait_for(asyncio.shield(warm_task), 5.0)
                except Exception:
                    pass
            try:
                state.output.stop()
            finally:
                from .ownership import close_outputs

                close_outputs(state)  # the pages' own simulated wires
                if close_output:
                    state.output.close()

    app = FastAPI(title="tactilize", lifespan=lifespan, docs_url="/api/docs", redoc_url=None)
    app.state.tactilize = state
    from . import guard

    guard.install(app, hosts, guard.DEFAULT_MAX_SOCKETS if max_sockets is None else max_sockets)

    @app.get("/", include_in_schema=False)
    async def index() -> FileResponse:
        return FileResponse(_STATIC / "index.html", media_type="text/html", headers={"Cache-Control": "no-cache"})

    @app.get("/favicon.ico", include_in_schema=False)
    async def favicon() -> Response:
        return Response(status_code=204)

    app.mount("/static", StaticFiles(directory=_STATIC), name="static")
    app.include_router(api_router())
    from .stroke_export import stroke_export_router

    app.include_router(stroke_export_router())
    from .session import websocket_endpoint

    @app.websocket("/ws")
    async def ws(websocket: WebSocket) -> None:
        await websocket_endpoint(websocket, state)

    for router in extra_routers:
        app.include_router(router)
    return app
