"""HTTP and WebSocket routes of the participant flow and the experimenter view.

:func:`experiment_router` returns a FastAPI ``APIRouter`` (mounted under
``/experiment`` in ``tactilize serve``'s app, or standalone by
:func:`create_experiment_app`).  Participant routes (``/experiment/api/...``)::

    GET  api/protocol                         title, description, questions (no conditions: blind)
    GET  api/constants                        the pen page's constants (web/constants.py)
    POST api/sessions        {participant_id, consent, demographics} -> state   (409: ID taken)
    POST api/resume          {participant_id, token?}          -> state   (404: unknown ID;
                             only with the experimenter token: an ID is guessable,
                             the page resumes by its session token)
    GET  api/sessions/{s}                                       -> state
    POST api/sessions/{s}/calibration {card_width_px|mm_per_px, felt}
    POST api/sessions/{s}/break       {trial}
    POST api/sessions/{s}/answers     {trial, ratings, response_time_s, submission_id, comment}
    GET  api/images/{id}.png
    WS   ws/{s}          pen samples in, drives out, acks after the commit (see .strokes)

Experimenter routes (``api/admin/...``: sessions, export.csv, export.json,
analysis) need the admin token, on loopback too (a page on another site can
reach loopback through DNS rebinding); :func:`serve_flow` and
:func:`create_experiment_app` make one when none is given, and a flow without
one keeps them closed.  Pass it as ``Authorization: Bearer <token>``,
``X-Tactilize-Token`` or ``?token=``.

The store is synchronous: a route that writes (start, resume, calibration,
break, answers, opening the pen socket) runs in a worker thread, a few at a
time (:func:`.strokes.in_store_thread`), and the answer route returns only
after the commit; pen messages have threads of their own (:func:`.strokes.pump`).  A refusal is
a :class:`~.flow.FlowError` raised by the route, answered with its status and
``{"error", "source"}`` (:class:`tactilize.http.ErrorAnsweringRoute`).
"""

from __future__ import annotations

import hmac
import json
import re
import secrets
import sys
from contextlib import asynccontextmanager
from importlib import resources
from typing import Any

from fastapi import APIRouter, FastAPI, Request, WebSocket
from fastapi.responses import (
    FileResponse,
    JSONResponse,
    PlainTextResponse,
    RedirectResponse,
    Response,
)

from ..encode import jsonable
from ..http import ErrorAnsweringRoute, is_loopback, settle_heap
from ..redact import redact_url
from ..web.constants import page_constants
from ..web.guard import accepted_hosts, install
from ..web.limits import read_body
from ..web.ownership import TRIAL, page_output
from .analysis import analyze, export_answers
from .design import Design
from .design_toml import load_design
from .errors import FlowError
from .flow import Flow
from .pen_socket import in_store_thread, pump
from .store import Store
from .visit import Visit

__all__ = ["experiment_router", "create_experiment_app", "serve_flow", "is_loopback", "PREFIX"]

PREFIX = "/experiment"
_STATIC_FILES = {"index.html", "experiment.js", "experiment.css", "admin.html", "admin.js"}
#: The pen page's modules the participant's page uses as they are (one pointer handling, one calibration).
_PEN_PAGE_FILES = {"pen-input.js", "calibrate.js", "constants.js"}
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8"}


def _static_dir():
    return resources.files("tactilize.experiments").joinpath("static")


#: Longest body of a participant's request [bytes]: an answer with its 2000-character comment is a few KiB.
MAX_REQUEST_BYTES = 256 * 1024


async def _json_body(request: Request) -> Any:
    # Bounded in size and time (web/limits.py): a slow body frees its request's place.
    raw = await read_body(request, MAX_REQUEST_BYTES, "request", f"request too large (limit {MAX_REQUEST_BYTES} bytes)")
    try:
        return json.loads(raw)
    except (json.JSONDecodeError, UnicodeDecodeError, ValueError, RecursionError):
        raise FlowError("request", "the body must be JSON", 400) from None


async def _json_object(request: Request) -> dict[str, Any]:
    body = await _json_body(request)
    if not isinstance(body, dict):
        raise FlowError("request", "expected a JSON object", 400)
    return body


def experiment_router(flow: Flow | Visit) -> APIRouter:
    """The routes of one protocol's flow, under ``/experiment`` (include as it is)."""
    router = APIRouter(prefix=PREFIX, route_class=ErrorAnsweringRoute)

    def require_admin(request: Request, given: Any = None) -> None:
        if not flow.admin_token:
            raise FlowError("token", "the experimenter routes are closed: this server has no experimenter token", 403)
        if not isinstance(given, str):
            given = request.headers.get("x-tactilize-token") or request.query_params.get("token") or ""
        auth = request.headers.get("authorization", "")
        if auth.lower().startswith("bearer "):
            given = auth[7:].strip()
        if not hmac.compare_digest(given.encode(), flow.admin_token.encode()):
            raise FlowError("token", "experimenter token required (see the server's start-up message)", 401)

    # ------------------------------------------------------------ pages

    @router.get("/", include_in_schema=False)
    def index() -> Response:
        return FileResponse(str(_static_dir().joinpath("index.html")), media_type=_TYPES[".html"])

    @router.get("/admin", include_in_schema=False)
    def admin_page() -> Response:
        return FileResponse(str(_static_dir().joinpath("admin.html")), media_type=_TYPES[".html"])

    @router.get("/static/{name}", include_in_schema=False)
    def static(name: str) -> Response:
        if name not in _STATIC_FILES and name not in _PEN_PAGE_FILES:  # a whitelist: no path tricks possible
            return PlainTextResponse("not found", status_code=404)
        ext = name[name.rindex("."):]
        folder = _static_dir() if name in _STATIC_FILES else resources.files("tactilize.web").joinpath("static")
        return FileResponse(str(folder.joinpath(name)), media_type=_TYPES[ext], headers={"Cache-Control": "no-cache"})

    @router.get("/api/constants")
    def constants() -> dict:
        # The pen page's; each picture's size on screen comes with its trial.
        return page_constants()

    # ------------------------------------------------------------ participant API

    @router.get("/api/protocol")
    def protocol_info() -> dict:
        p = flow.design
        return {"name": p.name, "title": p.title, "description": p.description, "consent": p.consent,
                "demographics": [d.to_dict() for d in p.demographics],
                "questions": [q.to_dict() for q in p.questions], "calibration_card_mm": p.calibration_card_mm,
                "trials": len(p.plan(1))}

    @router.post("/api/sessions")
    async def start(request: Request) -> Response:
        body = await _json_object(request)
        return JSONResponse(await in_store_thread(lambda: flow.start(body.get("participant_id"), body.get("consent"),
                                                                      demographics=body.get("demographics"))))

    @router.post("/api/resume")
    async def resume(request: Request) -> Response:
        body = await _json_object(request)
        # An ID is short and guessable, and a page on another site reaches even
        # loopback (DNS rebinding): an ID alone must not open someone's session.
        # The page resumes by its unguessable session token; resuming by ID needs
        # the experimenter (their token, in the body or as for the admin routes).
        require_admin(request, body.get("token"))
        return JSONResponse(await in_store_thread(flow.resume, body.get("participant_id")))

    @router.get("/api/sessions/{token}")
    def state(token: str) -> Response:
        return JSONResponse(flow.state(token))

    @router.post("/api/sessions/{token}/calibration")
    async def calibrate(token: str, request: Request) -> Response:
        body = await _json_body(request)
        return JSONResponse(await in_store_thread(flow.calibrate, token, body))

    @router.post("/api/sessions/{token}/break")
    async def end_break(token: str, request: Request) -> Response:
        body = await _json_body(request)
        idx = body.get("trial") if isinstance(body, dict) else None
        return JSONResponse(await in_store_thread(flow.end_break, token, idx))

    @router.post("/api/sessions/{token}/answers")
    async def answers(token: str, request: Request) -> Response:
        body = await _json_object(request)
        doc = await in_store_thread(
            lambda: flow.submit(token, body.get("trial"), body.get("ratings"),
                                response_time_s=body.get("response_time_s"),
                                submission_id=body.get("submission_id"), comment=body.get("comment")))
        return JSONResponse(doc)

    @router.get("/api/images/{image_id}.png")
    def image(image_id: str, protocol: str | None = None) -> Response:
        # A visit (several protocols) names the protocol: image ids may repeat across them.
        if protocol and not isinstance(flow, Visit):  # one protocol: the name must be its own
            if protocol != flow.design.name:
                raise FlowError("protocol", f"no protocol {protocol!r} here (this server runs {flow.design.name!r})", 404)
            protocol = None
        png = flow.image_png(image_id, protocol) if isinstance(flow, Visit) else flow.image_png(image_id)
        return Response(png, media_type="image/png", headers={"Cache-Control": "max-age=3600"})

    @router.websocket("/ws/{token}")
    async def pen(ws: WebSocket, token: str) -> None:
        await ws.accept()
        # Inside ``tactilize serve``'s app the pen's actuators are its output: a
        # trial holds a device before any pen page; a simulated wire is its own.
        server_state = getattr(ws.app.state, "tactilize", None)
        output = None if server_state is None else page_output(server_state, TRIAL)
        try:
            handler = await in_store_thread(flow.stroke_handler, token, output)
        except FlowError as exc:
            if output is not None:
                output.close()
            await ws.send_json({"type": "error", **exc.to_dict()})
            await ws.close(code=4404)
            return
        try:
            await pump(ws, handler)
        finally:
            if output is not None:
                output.close()

    # ------------------------------------------------------------ experimenter API

    @router.get("/api/admin/sessions")
    def admin_sessions(request: Request) -> Response:
        require_admin(request)
        names = getattr(flow, "protocol_names", [flow.design.name])
        return JSONResponse({"protocol": flow.design.to_dict(), "protocols": names,
                             "sessions": [r for n in names for r in flow.store.sessions_overview(n)]})

    @router.get("/api/admin/export.csv")
    def admin_csv(request: Request) -> Response:
        require_admin(request)
        return Response(export_answers(flow.store, "csv", flow.design.name), media_type="text/csv",
                        headers={"Content-Disposition": f'attachment; filename="{flow.design.name}-answers.csv"'})

    @router.get("/api/admin/export.json")
    def admin_json(request: Request) -> Response:
        require_admin(request)
        return Response(export_answers(flow.store, "json", flow.design.name), media_type="application/json")

    @router.get("/api/admin/analysis")
    def admin_analysis(request: Request) -> Response:
        require_admin(request)
        return JSONResponse(jsonable(analyze(flow.store, flow.design.name)))

    return router


def create_experiment_app(protocol, db_url: str | None = None, admin_token: str | None = None,
                          hosts: Any = None) -> FastAPI:
    """A standalone app serving one protocol's flow under ``/experiment``.

    Parameters
    ----------
    protocol : Design or str
        A design, a built-in protocol's name or a protocol TOML path.
    db_url : str, optional
        SQLAlchemy URL or SQLite file path; the default data-directory file if None.
    admin_token : str, optional
        Required by the experimenter routes (and a resume by ID); a random one
        (``app.state.experiment_flow.admin_token``) when not given.
    hosts : iterable of str, optional
        Host names the app answers to (:func:`tactilize.web.guard.accepted_hosts`);
        the loopback names by default.
    """
    if not isinstance(protocol, Design):
        protocol = load_design(protocol)
    flow = Flow(protocol, Store(db_url), admin_token=admin_token or secrets.token_urlsafe(16))

    @asynccontextmanager
    async def lifespan(_app):
        settle_heap()  # as the pen app does once warm: full collections skip what lives as long as the server
        yield

    app = FastAPI(title=f"tactilize experiment: {protocol.name}", docs_url=None, redoc_url=None, lifespan=lifespan)
    app.state.experiment_flow = flow
    install(app, hosts)
    app.include_router(experiment_router(flow))

    @app.get("/", include_in_schema=False)
    def root() -> Response:
        return RedirectResponse(f"{PREFIX}/")

    return app


def serve_flow(protocol, db_url: str | None, host: str = "127.0.0.1", port: int = 8765,
               admin_token: str | None = None, output: str = "simulated", profile: str | None = None,
               echo=print, warn=None, open_browser: bool | None = False) -> None:
    """Run the flow inside ``tactilize serve``'s app (the CLI's ``experiment run``).

    ``protocol`` may be a list: one visit runs them in sequence (:mod:`.visit`).

    The participant pages live at ``/experiment/``, beside the pen page, and the
    condition's drives go to the same actuator output (``--output``).  An
    experimenter token is mandatory, on loopback too: one is generated and
    printed when none is given, so the data are never open to another page.
    ``open_browser`` opens the experimenter's page (None: when a display exists).
    """
    protocols = [p if isinstance(p, Design) else load_design(p)
                 for p in (protocol if isinstance(protocol, (list, tuple)) else [protocol])]
    protocol = protocols[0]
    if not admin_token:
        admin_token = secrets.token_urlsafe(16)
    store = Store(db_url)
    first = Flow(protocol, store, admin_token=admin_token)
    flow: Flow | Visit = first
    if len(protocols) > 1:
        flow = Visit([first] + [Flow(p, store, admin_token=admin_token) for p in protocols[1:]])
        echo("one visit: " + " -> ".join(p.name for p in protocols))
    # The URL may hold a database password: a terminal (and its scrollback) must not.
    echo(f"tactilize experiment: {protocol.name} v{protocol.version} ({protocol.sha256[:12]}), "
         f"database {redact_url(flow.store.url)}")

    def relay(line: str) -> None:
        echo(line)
        m = re.search(r"(https?://\S+?:\d+)/", line)
        if m:  # the pen app printed its real address (port 0 picks one)
            echo(f"  participant  {m.group(1)}{PREFIX}/")
            echo(f"  experimenter {m.group(1)}{PREFIX}/admin" + (f"?token={admin_token}" if admin_token else ""))

    try:
        from ..web.serve import serve as web_serve
    except ImportError:  # a build without the pen app: serve the flow alone
        import uvicorn  # only here: the pen app brings its own server

        app = create_experiment_app(protocol, db_url, admin_token, hosts=accepted_hosts(host))
        relay(f"serving at http://{host}:{port}/")
        uvicorn.run(app, host=host, port=port, log_level="warning")
        return
    web_serve(host, port, output, profile, open_browser, extra_routers=[experiment_router(flow)], echo=relay,
              warn=warn or (lambda s: print(s, file=sys.stderr)), open_path=f"{PREFIX}/admin?token={admin_token}")
