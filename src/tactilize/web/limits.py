"""Bounded work for strangers: how much of the machine one request may take.

A picture upload or a stroke export costs hundreds of megabytes and seconds of
a core; the server is on a laptop.  Each kind of heavy request passes a
:class:`WorkGate`: at most ``admitted`` requests of that kind are inside the
server at once (their bodies read, waiting or working) and one more is refused
with 503 before its body is read; of those admitted, ``running`` work at once.
Bodies are read with :func:`read_body`, which refuses one longer than its cap
with 413 before it is all in memory, and one that trickles in with 408, so a
slow client leaves the gate soon.  docs/serve.md ("Bounds") lists the
figures; docs/safety.md says which test pins each.
"""

from __future__ import annotations

import asyncio
import collections
import logging
import time
from contextlib import asynccontextmanager
from typing import Any, AsyncIterator, Awaitable, Callable, MutableMapping

from ..errors import RequestError

__all__ = ["WorkGate", "read_body", "MessageRate", "HEADER_TIMEOUT_S", "BODY_GRACE_S", "BODY_MIN_BYTES_S",
           "MAX_REQUESTS", "MESSAGES_PER_S", "MESSAGE_BURST", "FLOOD_CLOSE_CODE", "UPLOADS_ADMITTED", "UPLOADS_RUNNING", "EXPORTS_ADMITTED", "EXPORTS_RUNNING",
           "MAX_EXPORT_BODY_BYTES", "MAX_UPLOAD_BYTES", "MAX_UPLOAD_PIXELS"]

log = logging.getLogger("tactilize.web")

#: Time a request's head (its request line and headers) may take to arrive [s],
#: from the connection's opening or the end of its previous response; beyond
#: it the connection gets 408 and is closed (web/serve.py).  A browser sends
#: the head in one write.
HEADER_TIMEOUT_S = 10.0
#: Time a request body may take before it must keep up :data:`BODY_MIN_BYTES_S` [s].
BODY_GRACE_S = 5.0
#: Average rate a request body must keep after :data:`BODY_GRACE_S` [bytes/s]:
#: a 12 MB upload may take three minutes; a client trickling a byte now and
#: then gets 408 and frees its place (:func:`read_body`).
BODY_MIN_BYTES_S = 64 * 1024
#: HTTP requests answered at once (their heads in), besides the WebSockets; one
#: more gets 503 (web/guard.py).  A connection still sending its head is not
#: one of them: it waits for no place another client needs.
MAX_REQUESTS = 64

#: Largest upload accepted [bytes]: a high-quality phone photo fits.
MAX_UPLOAD_BYTES = 12 * 1024 * 1024
#: Largest upload accepted [pixels]: 16 Mpx; analysing it takes about a second.
MAX_UPLOAD_PIXELS = 16 * 1024 * 1024

#: Uploads inside the server at once (their bodies arriving, waiting or
#: analysing); one more gets 503.  Two slow clients leave room for two others.
UPLOADS_ADMITTED = 4
#: Uploads analysed at once: a 16 Mpx picture needs about 260 MB while it is analysed.
UPLOADS_RUNNING = 1
#: Stroke exports inside the server at once (as uploads); one more gets 503.
EXPORTS_ADMITTED = 4
#: Stroke exports rendered at once (a minute of wire simulation takes seconds of a core).
EXPORTS_RUNNING = 1
#: Longest stroke-export body [bytes]: 60 000 samples as JSON rows fit in about 6 MB.
MAX_EXPORT_BODY_BYTES = 8 * 1024 * 1024

#: Messages one WebSocket may send a second, on average [1/s]: the pen page sends
#: one per pointer event, raw updates included (a 1 kHz mouse: 1000 a second;
#: docs/references.md, section 5), the experiments' page one per 30 ms.
MESSAGES_PER_S = 2000.0
#: Messages one WebSocket may send at once beyond that rate; also how many
#: refused messages end the connection (:class:`MessageRate`).
MESSAGE_BURST = 2000
#: WebSocket close code for a page that goes on flooding: policy violation (RFC 6455, 7.4.1).
FLOOD_CLOSE_CODE = 1008


class WorkGate:
    """At most ``admitted`` requests of one kind inside, ``running`` of them working.

    Parameters
    ----------
    what : str
        The kind, as the refusal names it ("upload", "stroke export").
    admitted, running : int
        See the module docstring; ``1 <= running <= admitted``.
    """

    def __init__(self, what: str, admitted: int, running: int) -> None:
        if not 1 <= running <= admitted:
            raise ValueError(f"need 1 <= running <= admitted, got running={running}, admitted={admitted}")
        self.what, self.admitted, self.running = what, int(admitted), int(running)
        self.inside = 0
        self.refused = 0
        self._work: asyncio.Semaphore | None = None  # made on the loop that uses it

    @asynccontextmanager
    async def admit(self) -> AsyncIterator["WorkGate"]:
        """Enter, or raise :class:`~tactilize.errors.RequestError` (503) when full."""
        if self.inside >= self.admitted:
            self.refused += 1
            raise RequestError(self.what, f"the server is busy with {self.inside} other {self.what}s "
                               f"(limit {self.admitted}); try again in a moment", 503)
        self.inside += 1
        try:
            yield self
        finally:
            self.inside -= 1

    async def run(self, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)`` in a worker thread, once one of the ``running`` places is free."""
        if self._work is None:
            self._work = asyncio.Semaphore(self.running)
        async with self._work:
            return await asyncio.get_running_loop().run_in_executor(None, fn, *args)


async def read_body(request: Any, limit_bytes: int, what: str, message: str | None = None) -> bytes:
    """The request body, refused with 413 once longer than ``limit_bytes``
    (by its Content-Length before reading, else as soon as it is exceeded),
    and with 408 once it falls behind :data:`BODY_MIN_BYTES_S` on average after
    :data:`BODY_GRACE_S`.

    Raises
    ------
    RequestError
        413 too long, 408 too slow, 400 a Content-Length that is not a number.
    """
    too_long = message or f"{what} too large (limit {limit_bytes // (1024 * 1024)} MB)"
    try:
        declared = int(request.headers.get("content-length", "0"))
    except ValueError:
        raise RequestError("Content-Length", "bad Content-Length header", 400) from None
    if declared > limit_bytes:
        raise RequestError(what, too_long, 413)
    loop = asyncio.get_running_loop()
    start_s = loop.time()
    chunks = request.stream().__aiter__()
    body = bytearray()
    while True:
        # The deadline moves on with every byte that came: a body arriving at
        # the minimum rate never meets it.
        deadline_s = start_s + BODY_GRACE_S + len(body) / BODY_MIN_BYTES_S
        try:
            chunk = await asyncio.wait_for(chunks.__anext__(), max(0.0, deadline_s - loop.time()))
        except StopAsyncIteration:
            return bytes(body)
        except asyncio.TimeoutError:
            raise RequestError(what, f"{what} too slow: send the body at {BODY_MIN_BYTES_S // 1024} KiB/s or more "
                               f"(after the first {BODY_GRACE_S:g} s)", 408) from None
        body += chunk
        if len(body) > limit_bytes:
            raise RequestError(what, too_long, 413)


class MessageRate:
    """One WebSocket's message budget: a token bucket of :data:`MESSAGE_BURST`
    messages, refilled at :data:`MESSAGES_PER_S`.

    Every message the socket receives asks :meth:`take`; a refused one is
    dropped unread, so one page's flood costs the others no parsing and no
    rendering.  A page whose refused messages reach :data:`MESSAGE_BURST` is
    no pen (a real pen never meets the rate) and :attr:`flooding` says to
    close its socket.

    Parameters
    ----------
    rate_per_s : float, optional
        Refill rate [messages/s]; :data:`MESSAGES_PER_S` by default.
    burst : int, optional
        Bucket size [messages]; :data:`MESSAGE_BURST` by default.
    clock : callable, optional
        Monotonic time [s]; :func:`time.monotonic` by default.
    """

    def __init__(self, rate_per_s: float | None = None, burst: int | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.rate_per_s = float(MESSAGES_PER_S if rate_per_s is None else rate_per_s)
        self.burst = int(MESSAGE_BURST if burst is None else burst)
        self._clock = clock
        self._tokens = float(self.burst)
        self._at_s = clock()
        #: messages refused so far
        self.dropped = 0

    def take(self) -> bool:
        """True when one more message fits the budget; else counts it as dropped."""
        now_s = self._clock()
        self._tokens = min(float(self.burst), self._tokens + (now_s - self._at_s) * self.rate_per_s)
        self._at_s = now_s
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self.dropped += 1
        return False

    @property
    def flooding(self) -> bool:
        """The socket has had :attr:`burst` messages refused: close it."""
        return self.dropped >= self.burst

    async def refuse(self, ws: Any, tell: Callable[[str], Awaitable[None]], counters: MutableMapping[str, int] | None = None) -> bool:
        """After :meth:`take` refused a message: count it, tell the page the
        first time, close a flooding socket (True: it is closed).

        Parameters
        ----------
        ws : WebSocket
            The socket the message came from.
        tell : async callable
            Sends the page one line, in its socket's error message.
        counters : mapping of str to int, optional
            The server's counters (a :class:`collections.Counter`); ``messages_dropped`` counts the message.
        """
        counters = collections.Counter() if counters is None else counters
        counters["messages_dropped"] += 1
        reason = (f"too many messages (more than {self.rate_per_s:g} a second); messages are dropped, and the "
                  f"connection is closed after {self.burst} of them")
        if self.flooding:
            counters["sockets_flooding"] += 1
            log.warning("WebSocket closed: %s", reason)
            await ws.close(code=FLOOD_CLOSE_CODE, reason="too many messages")
            return True
        if self.dropped == 1:
            await tell(reason)
        return False
