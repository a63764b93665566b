"""The experiment's pen socket: one task per page's WebSocket, its messages off the event loop.

Messages and answers are described in :mod:`.strokes` (:class:`~.strokes.StrokeHandler`
handles them); this module carries them: a pen message runs in a small
executor of its own, a request that waits on the store in a bounded number of
threads, and each batch's ``ack`` follows its commit.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from functools import partial
from typing import Any

import anyio
from anyio.lowlevel import RunVar
from sqlalchemy.exc import OperationalError
from starlette.concurrency import run_in_threadpool
from starlette.websockets import WebSocketDisconnect

from ..web.limits import MessageRate
from .errors import FlowError
from .strokes import StrokeHandler

__all__ = ["pump", "pen_executor", "PEN_THREADS", "in_store_thread", "STORE_THREADS"]

log = logging.getLogger(__name__)

#: Threads of the pen messages' own executor (:func:`pen_executor`).
PEN_THREADS = 2

_PEN_LOCK = threading.Lock()
_PEN_EXECUTOR: ThreadPoolExecutor | None = None


#: How many requests of one event loop run their store work at once (:func:`in_store_thread`).
STORE_THREADS = 4

_STORE_LIMITER: Any = None  # an anyio RunVar: one limiter per event loop, made on first use


async def in_store_thread(func, *args):
    """Run ``func(*args)`` in a worker thread, at most :data:`STORE_THREADS` at a time.

    Starting, calibrating and answering run a dozen ORM queries each, all
    Python, and an answer also waits for the writer's commit; when twenty
    participants answer at once, twenty such threads took turns on the
    interpreter with the event loop and the pen's threads (each turn up to the
    5 ms switch interval), so the drives waited tens of milliseconds.  A few at
    a time do the same work in the same total time, and the drive's threads
    find the interpreter free sooner.
    """
    global _STORE_LIMITER
    if _STORE_LIMITER is None:
        _STORE_LIMITER = RunVar("tactilize_store_limiter")
    limiter = _STORE_LIMITER.get(None)
    if limiter is None:
        limiter = anyio.CapacityLimiter(STORE_THREADS)
        _STORE_LIMITER.set(limiter)
    try:
        return await anyio.to_thread.run_sync(partial(func, *args), limiter=limiter)
    except OperationalError as exc:
        # A full disk, a database restarting: nothing of the request was stored
        # (its transaction rolled back), and the same request will be once the
        # store can write again.  A 503 with one line, not a 500 and a traceback.
        reason = str(exc.orig).strip().splitlines()[0][:200] if exc.orig is not None else exc.__class__.__name__
        log.warning("request not stored (%s); the page keeps it and sends it again", reason)
        raise FlowError("store", f"the database cannot store this now ({reason}); the page keeps it and "
                        "sends it again", 503, retry=True) from None


def pen_executor() -> ThreadPoolExecutor:
    """The executor that turns pen messages into drives, apart from every request that waits on the store.

    Answers, starts and calibrations run in Starlette's thread pool and block on
    the database (an answer waits for the writer's commit); a pen message queued
    behind them would wait for their queries.  Its few threads only run
    :meth:`StrokeHandler.take` for messages that need no query
    (:meth:`StrokeHandler.needs_store`): a fraction of a millisecond each.
    """
    global _PEN_EXECUTOR
    with _PEN_LOCK:
        if _PEN_EXECUTOR is None:
            _PEN_EXECUTOR = ThreadPoolExecutor(PEN_THREADS, thread_name_prefix="tactilize-pen")
        return _PEN_EXECUTOR


def _ack(future: Future, batch: str, trial: Any) -> dict[str, Any]:
    exc = future.exception()
    if exc is None:
        return {"type": "ack", "batch": batch, "trial": trial, "stored": future.result()}
    return {"type": "error", "source": "samples", "status": 503, "batch": batch, "retry": True,
            "error": "the samples could not be stored yet; the page keeps them and sends them again"}


async def pump(ws, handler: StrokeHandler) -> None:
    """Serve one accepted WebSocket until it closes.

    A message that needs no query runs in :func:`pen_executor`'s threads, not
    queued behind the requests blocked on the database in the thread pool;
    one that does (:meth:`StrokeHandler.needs_store`) runs in the thread pool.
    Neither waits for the samples' commit: the drive goes back as soon as it is
    computed, and each batch's ``ack`` follows from the writer's thread once its
    group committed.  One task sends, so answers and acknowledgements never
    interleave on the socket.
    """
    loop = asyncio.get_running_loop()
    out: asyncio.Queue = asyncio.Queue()

    def post(doc: dict[str, Any]) -> None:  # from the writer's thread
        try:
            loop.call_soon_threadsafe(out.put_nowait, doc)
        except RuntimeError:  # the loop is gone: the page resends what it did not see acknowledged
            pass

    async def sender() -> None:
        while (doc := await out.get()) is not None:
            await ws.send_json(doc)

    async def tell(text: str) -> None:
        out.put_nowait({"type": "error", "error": text, "source": "stroke", "status": 429})

    sending = asyncio.create_task(sender())
    refreshing: asyncio.Future | None = None
    budget = MessageRate()
    try:
        while not sending.done():
            message = await ws.receive()
            if message["type"] == "websocket.disconnect":
                return
            # Dropped unread: the other participants' drives do not wait for a
            # flood, and a dropped batch, never acknowledged, is sent again.
            if not budget.take():
                if await budget.refuse(ws, tell):
                    return
                continue
            text = message.get("text")
            if text is None and message.get("bytes") is not None:
                text = message["bytes"].decode("utf-8", "replace")
            future = None
            msg: Any = None  # the parsed JSON: anything until take() checks it
            try:
                msg = json.loads(text or "")
                if handler.needs_store(msg):
                    reply, future = await in_store_thread(handler.take, msg)
                else:
                    reply, future = await loop.run_in_executor(pen_executor(), handler.take, msg)
            except json.JSONDecodeError:
                reply = {"type": "error", "error": "messages must be JSON", "source": "stroke", "status": 400}
            except FlowError as exc:
                reply = {"type": "error", **exc.to_dict(), "status": exc.status}
                if isinstance(msg, dict) and isinstance(msg.get("batch"), str):
                    reply["batch"] = msg["batch"]  # refused for good: the page drops it
            if reply is not None:
                out.put_nowait(reply)
            if future is not None:
                batch, trial = (reply or {}).get("batch") or msg.get("batch"), msg.get("trial")
                future.add_done_callback(lambda f, b=batch, t=trial: post(_ack(f, b, t)))
                if (handler.flow.open_trial_due(handler.session)  # the reply is on its way: query now,
                        and (refreshing is None or refreshing.done())):  # without holding up the next message
                    refreshing = asyncio.ensure_future(in_store_thread(handler.refresh_open_trial))
                    # A failed read is retried at the next message; the drive goes on meanwhile.
                    refreshing.add_done_callback(lambda f: f.cancelled() or f.exception())
    except WebSocketDisconnect:
        return
    finally:
        out.put_nowait(None)
        for task in (sending, refreshing):
            try:
                if task is not None:
                    await task
            except Exception:  # the socket closed under the sender / the store failed: nothing more to tell
                pass
        await run_in_threadpool(handler.stop)
