"""The tactile pen system in the browser (``tactilize serve``).

:func:`create_app` builds the ASGI application: the page (plain ES modules in
``static/``), the texture gallery and uploads, the profiles, and the WebSocket
``/ws`` that turns pen samples into drives.  Other parts of tactilize mount
their own routes with ``create_app(extra_routers=[router])`` or
``app.include_router(router)``.
"""

from .app import ServerState, create_app

__all__ = ["create_app", "ServerState"]
