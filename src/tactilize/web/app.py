"""The ASGI application behind ``tactilize serve``.

Routes
------
``GET /``                              the page
``GET /static/...``                    its ES modules and stylesheet (no build step)
``GET /api/config``                    defaults: mm per CSS px, profile, output, channels
``GET /api/textures``                  the gallery: built-ins and uploads, with features
``GET /api/textures/{id}.png``         a picture (grey PNG carrying its DPI)
``GET /api/textures/{id}/features``    whole-picture features and the tile map
``POST /api/textures``                 upload a picture (multipart ``file``, optional
                                       ``width_mm`` or ``dpi``); size-limited, validated
                                       by :func:`tactilize.image.load_image`
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
import collections
import hashlib
import logging
import threading
from contextlib import asynccontextmanager
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Iterable

from fastapi import APIRouter, FastAPI, WebSocket
from fastapi.responses import FileResponse, Response
from fastapi.staticfiles import StaticFiles

from ..errors import ProfileError, TactilizeError
from ..mapping import Profile, preset_names
from .api import MAX_UPLOAD_BYTES, MAX_UPLOAD_PIXELS, api_router
from .encode import jsonable
from .http import settle_heap
from .rows import DEFAULT_M_PER_CSS_PX

__all__ = ["create_app", "ServerState", "TextureEntry", "MAX_UPLOAD_BYTES", "MAX_UPLOAD_PIXELS"]

log = logging.getLogger("tactilize.web")

#: Uploads kept in memory; the oldest is forgotten first.
MAX_UPLOADS = 24

_STATIC = Path(str(resources.files("tactilize.web").joinpath("static")))


class TextureEntry:
    """A picture the page can show: a built-in or an upload.

    The PNG and the texture map are made on first use (thread-safe, once), so
    listing textures is cheap and the server starts at once.

    Attributes
    ----------
    id, name, description : str
    width_m, height_m : float
        Physical size it is shown at [m].
    width_px, height_px : int
    builtin : bool
    """

    def __init__(
        self,
        id: str,
        name: str,
        description: str,
        width_m: float,
        height_m: float,
        width_px: int,
        height_px: int,
        builtin: bool,
        make_png: Callable[[], bytes],
        make_map: Callable[[], Any],
        make_surface: Callable[[], Any] | None = None,
    ) -> None:
        self.id, self.name, self.description = id, name, description
        self.width_m, self.height_m = float(width_m), float(height_m)
        self.width_px, self.height_px = int(width_px), int(height_px)
        self.builtin = builtin
        self._make_png, self._make_map = make_png, make_map
        self._make_surface = make_surface
        self._surface: Any = None
        self._png: bytes | None = None
        self._map: Any = None
        self._lock = threading.Lock()

    @property
    def png(self) -> bytes:
        """The grey picture as PNG carrying its DPI (what was analysed is what is shown)."""
        if self._png is None:
            with self._lock:
                if self._png is None:
                    self._png = self._make_png()
        return self._png

    @property
    def map(self):
        """The :class:`~tactilize.texturemap.TextureMap` at the displayed size."""
        if self._map is None:
            with self._lock:
                if self._map is None:
                    self._map = self._make_map()
        return self._map

    @property
    def surface(self):
        """The :class:`~tactilize.surface.SurfaceModel` at the displayed size (None when the
        entry has no picture to make one from)."""
        if self._surface is None and self._make_surface is not None:
            with self._lock:
                if self._surface is None:
                    self._surface = self._make_surface()
        return self._surface

    def describe(self, with_features: bool = True) -> dict[str, Any]:
        """JSON-ready listing entry (sizes in mm for the page, SI features)."""
        d: dict[str, Any] = {
            "id": self.id,
            "name": self.name,
            "description": self.description,
            "builtin": self.builtin,
            "width_mm": self.width_m * 1e3,
            "height_mm": self.height_m * 1e3,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "url": f"/api/textures/{self.id}.png",
        }
        if with_features:
            d["features"] = jsonable(self.map.whole.to_dict())
        return d


class ServerState:
    """What every request and session shares.

    Parameters
    ----------
    output : Output
        Where drives go; shared by all sessions (it is one device).
    profile : Profile
        The default profile.
    m_per_px : float
        Default size of a CSS pixel [m] until the page sends its calibration.
    """

    def __init__(self, output: Any, profile: Profile, m_per_px: float = DEFAULT_M_PER_CSS_PX, output_name: str = "") -> None:
        self.output = output
        self.output_name = output_name or type(output).__name__
        self.profile = profile
        self.m_per_px = float(m_per_px)
        self.textures: "collections.OrderedDict[str, TextureEntry]" = collections.OrderedDict()
        self.uploads: "collections.deque[str]" = collections.deque()
        self._builtin_ids: list[str] = []
        # Server-side latency of each rendered batch [ns]: arrival of the
        # message to its drive handed to the socket.  Bounded ring.
        self.latency_ns: "collections.deque[int]" = collections.deque(maxlen=20_000)
        self.counters: dict[str, int] = collections.Counter()
        self.sessions = 0
        #: makes one output per page (a simulated wire), or None: the pages take
        #: turns on ``output`` (web/ownership.py)
        self.page_output_factory: Callable[[], Any] | None = None
        from .limits import EXPORTS_ADMITTED, EXPORTS_RUNNING, UPLOADS_ADMITTED, UPLOADS_RUNNING, WorkGate

        #: heavy requests, bounded (web/limits.py)
        self.upload_gate = WorkGate("upload", UPLOADS_ADMITTED, UPLOADS_RUNNING)
        self.export_gate = WorkGate("stroke export", EXPORTS_ADMITTED, EXPORTS_RUNNING)
        from ..data import builtin_textures

        for t in builtin_textures():
            # The PNG and the map are built lazily (warm() does it at startup
            # off the event loop); only cheap metadata here.
            self.textures[t.id] = _builtin_entry(t, self.tip_radius_m)
            self._builtin_ids.append(t.id)

    @property
    def tip_radius_m(self) -> float:
        """The stylus tip radius [m] of every surface the server makes: its profile's
        (``serve --profile``; the presets' default otherwise)."""
        return float(self.profile.tip_radius_m)

    # ----------------------------------------------------------- profiles

    def profiles(self) -> dict[str, Profile]:
        """Profiles the page may pick: the presets plus the default (maybe a file)."""
        out = {}
        for name in preset_names():
            try:
                out[name] = Profile.preset(name)
            except ProfileError:  # a broken preset must not take the page down
                log.warning("preset %s does not load", name)
        out[self.profile.name] = self.profile
        return out

    def profile_named(self, name: str) -> Profile:
        """A profile by name (only presets and the default: the page cannot read files)."""
        if name == self.profile.name:
            return self.profile
        if name in preset_names():
            return Profile.preset(name)
        raise ProfileError(name, f"unknown profile (known: {', '.join(self.profiles())})")

    # ----------------------------------------------------------- textures

    def texture(self, texture_id: str) -> TextureEntry:
        """A texture by id; KeyError when unknown."""
        return self.textures[texture_id]

    def add_upload(self, data: bytes, filename: str, width_mm: float | None, dpi: float | None) -> TextureEntry:
        """Validate, analyse and keep an uploaded picture (blocking: run in a thread)."""
        from ..image import load_image
        from ..texturemap import texture_map
        from ..data import png_bytes

        name = Path(filename or "upload").name[:80] or "upload"
        img = load_image(data, dpi=dpi, width_mm=width_mm, max_pixels=MAX_UPLOAD_PIXELS)
        digest = hashlib.sha256(data + repr((width_mm, dpi)).encode()).hexdigest()[:12]
        tid = f"upload-{digest}"
        if tid in self.textures:
            return self.textures[tid]
        grey = (img.pixels * 255.0 + 0.5).astype("uint8")
        png = png_bytes(grey, img.dpi[0])
        tmap = texture_map(img)  # now, in the upload's thread: the first stroke must not wait
        from ..surface import surface_model

        surface = surface_model(img, tip_radius_m=self.tip_radius_m)  # likewise (bench/bench_surfaces.py measures it)
        entry = TextureEntry(
            tid, name, f"Uploaded picture {name}", img.width_m, img.height_m, img.shape[1], img.shape[0], False,
            lambda: png, lambda: tmap, lambda: surface,
        )
        self.textures[tid] = entry
        self.uploads.append(tid)
        while len(self.uploads) > MAX_UPLOADS:
            self.textures.pop(self.uploads.popleft(), None)
        return entry

    def warm(self) -> None:
        """Generate every built-in picture, its map and its surface (about a second, once)."""
        from ..surface.path import warm as warm_search  # scipy.signal and numba: not on a pen batch's path

        warm_search()  # the window's compiled search, loaded (or compiled once per machine) now

        for tid in self._builtin_ids:
            e = self.textures.get(tid)
            if e is not None:
                _ = e.png, e.map, e.surface

    # ----------------------------------------------------------- stats

    def stats(self, last: int | None = None) -> dict[str, Any]:
        """Latency percentiles [us] (over the ``last`` batches, or all kept) and counters."""
        lat = list(self.latency_ns)
        if last is not None and last > 0:
            lat = lat[-last:]
        lat.sort()

        def pct(p: float) -> float | None:
            if not lat:
                return None
            return lat[min(len(lat) - 1, int(p / 100.0 * len(lat)))] / 1e3

        return {
            "batches": len(lat),
            "server_latency_us": {"p50": pct(50), "p90": pct(90), "p99": pct(99), "max": lat[-1] / 1e3 if lat else None},
            "counters": dict(self.counters),
            "sessions": self.sessions,
        }


def _builtin_entry(t: Any, tip_radius_m: float) -> TextureEntry:
    from ..data import TEXTURE_SIZE_PX, builtin_map

    return TextureEntry(
        t.id, t.name, t.description, t.width_m, t.height_m, *TEXTURE_SIZE_PX, True,
        lambda: t.png, lambda: builtin_map(t.id), lambda: _surface_of(t, tip_radius_m),
    )


def _surface_of(t: Any, tip_radius_m: float) -> Any:
    from ..surface import surface_model

    return surface_model(t.image, tip_radius_m=tip_radius_m)


def _default_output() -> tuple[Any, str]:
    """The simulated wire through the output factory; a recorder if it is not built yet."""
    try:
        from ..actuators.factory import open_output

        return open_output("simulated"), "simulated"
    except (ImportError, TactilizeError) as exc:
        from ..pen import _Recorder

        log.warning("simulated output unavailable (%s); drives are only recorded", exc)
        return _Recorder(), "recorder"


def _simulated() -> Any:
    from ..actuators.factory import open_output

    return open_output("simulated")


def create_app(
    output: Any = None,
    profile: Profile | str | None = None,
    *,
    output_name: str | None = None,
    m_per_px: float = DEFAULT_M_PER_CSS_PX,
    extra_routers: Iterable[APIRouter] = (),
    warm: bool = True,
    close_output: bool | None = None,
    hosts: Iterable[str] | None = None,
    max_sockets: int | None = None,
    page_outputs: Callable[[], Any] | None = None,
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
    state = ServerState(output, profile, m_per_px, output_name or "")
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
