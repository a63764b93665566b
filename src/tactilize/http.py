"""What every HTTP app shares (the pen app, the catalog's API, the experiments' routes): the error
answer and the loopback rule.  Below :mod:`tactilize.web`, so the others need not import the pen app."""

from __future__ import annotations

import gc
import ipaddress
from typing import Any, Callable, Coroutine

from fastapi import Request, Response
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute

from .errors import RequestError, TactilizeError

__all__ = ["is_loopback", "error_response", "ErrorAnsweringRoute", "settle_heap"]


def is_loopback(host: str) -> bool:
    """True when a server bound to ``host`` only accepts connections from this machine.

    Parameters
    ----------
    host : str
        An address or name as given to ``--host`` (IPv6 with or without brackets).

    Notes
    -----
    The empty string binds *every* interface, so it is not loopback.  Of the
    names, only ``localhost`` is: it is reserved for loopback (RFC 6761); any
    other name may resolve anywhere.
    """
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def settle_heap() -> None:
    """Keep the garbage collector's full passes off the pen's path.

    What exists once the server has warmed up (imported libraries, compiled
    kernels, the built-in maps: about 150 000 objects) lives as long as the
    server, yet every full collection walked it: 80 .. 130 ms with the event
    loop stopped, measured as pen batches answered 130 ms late.  Collect once
    now, then move the survivors out of the collector's sight (``gc.freeze``),
    so later collections see only what the sessions make.  Both apps call it
    once started: the pen app (:func:`tactilize.web.app.create_app`) and the
    experiment's own (:func:`tactilize.experiments.web.create_experiment_app`).
    """
    gc.collect()
    gc.freeze()


def error_response(exc: TactilizeError) -> JSONResponse:
    """The JSON answer to a refused request.

    A :class:`~tactilize.errors.RequestError` gives its status and body; any
    other :class:`~tactilize.errors.TactilizeError` is bad input: 422 and
    ``{"error": "source: fault", "source": source}``.
    """
    if isinstance(exc, RequestError):
        return JSONResponse(exc.to_dict(), status_code=exc.status)
    return JSONResponse({"error": str(exc), "source": exc.source}, status_code=422)


class ErrorAnsweringRoute(APIRoute):
    """A route that answers every :class:`~tactilize.errors.TactilizeError` it
    raises with :func:`error_response` instead of a 500.

    Give it to a router (``APIRouter(route_class=ErrorAnsweringRoute)``): the
    routes keep it in whatever app includes the router, so its handlers just
    raise.
    """

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handle = super().get_route_handler()

        async def handle_and_answer_errors(request: Request) -> Response:
            try:
                return await handle(request)
            except TactilizeError as exc:
                return error_response(exc)

        return handle_and_answer_errors
