"""The tactile pen system in the browser (``tactilize serve``).

:func:`create_app` builds the ASGI application: the page (plain ES modules in
``static/``), the texture gallery and uploads, the profiles, and the WebSocket
``/ws`` that turns pen samples into drives.  Other parts of tactilize mount
their own routes with ``create_app(extra_routers=[router])`` or
``app.include_router(router)``.

Modules
-------
:mod:`.app`      the application and its routes
:mod:`.state`    the shared state: the output, the profile, the gallery
:mod:`.session`  the WebSocket protocol of the pen page
:mod:`.serve`    binding the socket and running the server
:mod:`.rows`     the pages' pen sample rows: validation, conversion to SI
:mod:`.guard`    Host and Origin checks, the socket cap
:mod:`.ownership` one physical output, many pages
:mod:`.limits`   bounded uploads and stroke exports

``create_app`` and ``ServerState`` load the web framework on first use, so
:mod:`.rows` stays cheap to import.  What the pen app shares with the catalog's
API, the experiments and the CLI lives below it: :mod:`tactilize.http` (the
error answer, the loopback rule) and :mod:`tactilize.encode` (the one JSON
encoder).
"""

from __future__ import annotations

from typing import Any

__all__ = ["create_app", "ServerState"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from . import app

        return getattr(app, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
