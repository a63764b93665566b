"""The WebSocket protocol of the pen page: pen samples in, drives out.

Every message is one JSON object with a ``type``.

Page to server
--------------
``{"type": "hello", "texture": ID, "mm_per_px": F, "profile": NAME}``
    Any subset of the three settings below in one message.
``{"type": "texture", "id": ID, "repeat": [COLS, ROWS]}``
    Show another picture (the stroke restarts, the output stops).  With
    ``repeat`` (optional; at most :data:`MAX_REPEAT` copies) the picture is
    tiled COLS x ROWS times from the first copy's top-left corner, to fill a
    large screen; the state message echoes ``"repeat"``.
``{"type": "composite", "ids": [ID, ...], "cols": N}``
    Several pictures side by side as one surface (the paper's Fig. 16): up to
    :data:`MAX_COMPOSITE` ids, ``cols`` a row, each at its physical size in
    the top-left corner of an equal cell (the largest picture's size); sample
    positions are then from the surface's top-left corner.  The state message
    says ``"composite": {"ids", "cols", "cell_mm"}`` and ``"texture": null``.
``{"type": "calibrate", "mm_per_px": F}``
    The page's calibrated size of a CSS pixel [mm], 0.01 .. 5: the page
    converts its samples with it; the stroke restarts.
``{"type": "profile", "name": NAME}``
    Another profile: a preset or the server's default.
``{"type": "samples", "batch": ID, "samples": [[t_ms, x_mm, y_mm, pressure, tilt_x_deg, tilt_y_deg], ...]}``
    The pen socket's one sample message, the experiment's too (:mod:`.rows`,
    parsed by :func:`.rows.pen_batch`): millimetres on the picture as shown,
    from its top-left corner (y down), each sample with its own event
    timestamp [ms].  At most :data:`MAX_BATCH` samples.  Nothing is acknowledged:
    nothing is stored.
``{"type": "lift", "batch": ID}``
    The pen left the surface (pointerup, pointercancel): stop at once.
``{"type": "hover"}``
    The pen (or mouse) is over the picture but not touching: the output holds
    its actuators ready (an SMA wire in standby), so a touch is felt at once.
    The page sends it at most a few times a second.
``{"type": "ping", "id": X}``
    Answered with ``{"type": "pong", "id": X}`` (round-trip measurements).
``{"type": "take_over"}``
    Drive the physical output although another page holds it (:mod:`.ownership`);
    answered with an ``output`` message.

Server to page
--------------
``{"type": "ready", ...}`` and ``{"type": "state", ...}``
    The session's settings after a change (texture, profile, mm_per_px, limits).
``{"type": "drive", "batch": ID, ...}``
    After each batch (or lift): ``rendering`` (``steady`` or ``surface``) and,
    for the surface rendering, ``events``, the pulses this batch scheduled
    ahead, and ``pulses``, those that became due since the previous batch
    (docs/surfaces.md); per channel the applied drive (frequency [Hz],
    width [s] and [ms], duty ratio, amplitude, the limits that clamped), the
    speed [m/s] and [mm/s], direction [deg, y up], whether the pen is down and
    over the picture; ``output_fault``: one line when the output cannot be
    trusted now (a faulty sense path, a stopped simulation), else null.
    ``batch`` echoes the newest batch it covers; ``resting`` is true for the
    drive the server sends by itself when the pen is down but no samples came
    for :data:`IDLE_S` (a resting pen: speed 0).
``{"type": "wire", "t_s": [...], "displacement_um": [[...], [...]], "state": [...]}``
    The simulated wires' displacement per channel since the previous message
    (simulated time [s], displacement [um]) and each wire's controller state now
    (off, standby, warming, vibrating), when the output keeps a trace;
    :data:`WIRE_PERIOD_S` apart, or up to half as much again (each waits for
    the gap after a drive, when the pen is busy).
``{"type": "error", "message": TEXT}``
    A malformed message was ignored; the connection stays open.
``{"type": "output", "state": "yours"|"in_use"|"free", "by": WHO, "take_over": BOOL}``
    This page's standing on a physical output shared by several pages
    (:mod:`.ownership`): sent when it changes, and when a stroke could not be
    played because another page holds the output.

Floods
------
The reader renders each batch and sends its drive itself, as soon as the
batch is read.  While a drive is held up on the way out (a page that does not
read its socket), it only parses what comes and keeps at most
:data:`MAX_PENDING` samples waiting, and a render task renders whatever is
waiting in one go once the drive is out.  When the page sends faster than the
server renders, old samples fall off the front of the queue (counted, never
queued without bound) and the newest always wins.  A lift discards whatever samples were waiting before it.
Messages beyond a socket's budget (:class:`.limits.MessageRate`) are dropped unread; a flood closes it (1008).
"""

from __future__ import annotations

import asyncio
import json
import logging
import math
import time
from collections import deque
from typing import TYPE_CHECKING, Any

from fastapi import WebSocket
from starlette.websockets import WebSocketDisconnect, WebSocketState

from ..actuators.base import Output
from ..errors import TactilizeError
from ..pen import PenRenderer, PenSample
from ..encode import dumps
from ..pen.display import MM_PER_PX_RANGE  # the one display-scale rule, shared with the experiments
from ..surface.rendering import rendering_kind
from .limits import MessageRate
from .rows import MAX_BATCH, PenMessageError, batch_id, pen_batch
from .state import ServerState
from .wire_trace import WIRE_PERIOD_S, trace_text as _trace_text, wire_source as _wire_source

if TYPE_CHECKING:  # the maps and the surfaces load the FFT stack: not at import
    from ..maps.composite import CompositeMap
    from ..surface.composite import CompositeSurface
    from ..surface.model import SurfaceModel

__all__ = ["websocket_endpoint", "PenSession", "MAX_BATCH", "MAX_PENDING", "MAX_MESSAGE_CHARS", "IDLE_S", "MAX_COMPOSITE"]

log = logging.getLogger("tactilize.web")

#: Samples waiting to be rendered, at most; older ones are dropped first.
MAX_PENDING = 512
#: Longest message accepted [characters].
MAX_MESSAGE_CHARS = 64 * 1024
#: Silence [s] after which a pen that is down counts as resting (speed 0):
#: browsers send no pointer events while the pen does not move.
IDLE_S = 0.08
#: Pictures on one composite surface, at most.
MAX_COMPOSITE = 12
#: Copies of a repeated picture, at most.
MAX_REPEAT = 64


#: A malformed message: reported to the page, connection kept.
_Bad = PenMessageError


class PenSession:
    """One page's connection: its settings, renderer and queues.

    Parameters
    ----------
    state : ServerState
        Shared server state (output, profiles, textures, statistics).
    output : Output, optional
        What this page drives (:func:`.ownership.page_output`); the server's output by default.
    """

    def __init__(self, state: ServerState, output: Output | None = None) -> None:
        self.state = state
        self.output = state.output if output is None else output
        self.m_per_px = state.m_per_px
        self.texture_id: str | None = None
        #: (ids, cols, CompositeMap) while a composite surface is shown
        self.composite: tuple[list[str], int, Any] | None = None
        #: (cols, rows) of a repeated picture, or None
        self.repeat: tuple[int, int] | None = None
        self.renderer = PenRenderer(_NoPicture(), state.profile, self.output)
        self.pending: deque[PenSample] = deque()
        self.pending_lift = False
        self.batch: str | None = None
        #: perf_counter_ns when the message being handled arrived (set by the reader)
        self.msg_ns = 0
        #: arrival of the newest message the waiting samples came in (for the latency record)
        self.arrival_ns = 0
        #: samples or a lift wait for a render; ``wake`` calls the render task
        self.due = False
        self.wake = asyncio.Event()
        self._idle: asyncio.TimerHandle | None = None
        self._idle_due = False

    # ------------------------------------------------------------- messages

    def handle(self, text: Any) -> dict[str, Any] | None:
        """Parse and apply one message; returns an immediate reply or None.

        Raises
        ------
        _Bad
            The message is malformed (its text is the reason).
        """
        if not isinstance(text, str):
            raise _Bad("messages must be JSON text, not binary")
        if len(text) > MAX_MESSAGE_CHARS:
            raise _Bad(f"message too long ({len(text)} characters, limit {MAX_MESSAGE_CHARS})")
        try:
            msg = json.loads(text)
        except (ValueError, RecursionError) as exc:
            raise _Bad(f"not JSON ({exc.__class__.__name__}: {str(exc)[:80]})") from None
        if not isinstance(msg, dict):
            raise _Bad("a message must be a JSON object with a 'type'")
        kind = msg.get("type")
        if kind == "samples":
            self._samples(msg)
            return None
        if kind == "lift":
            self.pending.clear()
            self.pending_lift = True
            self.batch = batch_id(msg.get("batch")) or self.batch
            self._wake()
            return None
        if kind == "hover":
            self.renderer.hover()
            return None
        if kind == "ping":
            return {"type": "pong", "id": msg.get("id"), "server_time_s": time.time()}
        if kind == "take_over":
            take = getattr(self.output, "take_over", None)
            return take() if take is not None else {"type": "output", "state": "yours", "take_over": False}
        if kind in ("hello", "texture", "calibrate", "profile"):
            return self._settings(kind, msg)
        if kind == "composite":
            return self._composite(msg)
        raise _Bad(f"unknown message type {kind!r} (known: samples, lift, hello, texture, composite, calibrate, profile, ping, "
                   "take_over)")

    def _composite(self, msg: dict[str, Any]) -> dict[str, Any]:
        from ..maps.composite import CompositeMap

        ids, cols = msg.get("ids"), msg.get("cols", 3)
        if not isinstance(ids, list) or not 1 <= len(ids) <= MAX_COMPOSITE or not all(isinstance(i, str) for i in ids):
            raise _Bad(f"'composite' needs 'ids': 1 to {MAX_COMPOSITE} texture ids")
        if isinstance(cols, bool) or not isinstance(cols, int) or not 1 <= cols <= MAX_COMPOSITE:
            raise _Bad(f"'cols' must be an integer in [1, {MAX_COMPOSITE}]")
        try:
            entries = [self.state.texture(i) for i in ids]
        except KeyError as exc:
            raise _Bad(f"no texture {exc.args[0]!r}") from None
        cmap = CompositeMap.of([e.map for e in entries], cols)
        self.pending.clear()
        self.texture_id = None
        self.repeat = None
        self.composite = (list(ids), cols, cmap)
        self.renderer.set_texture(cmap, _composite_surface([e.surface for e in entries], cols, cmap))
        return self.describe("state")

    def _samples(self, msg: dict[str, Any]) -> None:
        batch, rows = pen_batch(msg)
        if self.texture_id is None and self.composite is None:
            raise _Bad("no texture selected: send {'type': 'texture', 'id': ...} first")
        if not rows:
            return
        pending = self.pending
        pending.extend(rows)
        over = len(pending) - MAX_PENDING
        if over > 0:
            # Latest wins: the oldest samples only refine a speed estimate that
            # the newest ones will give anyway.
            for _ in range(over):
                pending.popleft()
            self.state.counters["samples_dropped"] += over
        self.state.counters["samples_received"] += len(rows)
        self.batch = batch or self.batch
        self._wake()

    def _settings(self, kind: str, msg: dict[str, Any]) -> dict[str, Any]:
        st = self.state
        tid = msg.get("texture") if kind == "hello" else msg.get("id") if kind == "texture" else None
        mm = msg.get("mm_per_px") if kind in ("hello", "calibrate") else None
        pname = msg.get("profile") if kind == "hello" else msg.get("name") if kind == "profile" else None
        if kind == "texture" and tid is None:
            raise _Bad("'texture' needs an 'id'")
        if kind == "calibrate" and mm is None:
            raise _Bad("'calibrate' needs 'mm_per_px'")
        if kind == "profile" and pname is None:
            raise _Bad("'profile' needs a 'name'")
        repeat = msg.get("repeat") if kind == "texture" else None
        if repeat is not None:
            if (
                not isinstance(repeat, list) or len(repeat) != 2
                or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in repeat)
                or repeat[0] * repeat[1] > MAX_REPEAT
            ):
                raise _Bad(f"'repeat' must be [cols, rows], positive integers, at most {MAX_REPEAT} copies")
        # Validate everything before changing anything.
        entry = None
        if tid is not None:
            if not isinstance(tid, str):
                raise _Bad("texture id must be a string")
            try:
                entry = st.texture(tid)
            except KeyError:
                raise _Bad(f"no texture {tid!r}") from None
        if mm is not None:
            lo, hi = MM_PER_PX_RANGE
            if isinstance(mm, bool) or not isinstance(mm, (int, float)) or not math.isfinite(mm) or not lo <= mm <= hi:
                raise _Bad(f"mm_per_px must be a number in [{lo}, {hi}], got {mm!r}")
        profile = None
        if pname is not None:
            if not isinstance(pname, str):
                raise _Bad("profile name must be a string")
            try:
                profile = st.profile_named(pname)
            except TactilizeError as exc:
                raise _Bad(str(exc)) from None
        # The pen starts a new stroke after any change: a speed estimated in the
        # old millimetres, or a drive for the old picture, must not carry over.
        self.pending.clear()
        if entry is not None:
            self.composite = None
            self.texture_id = entry.id
            self.repeat = (repeat[0], repeat[1]) if repeat is not None and repeat != [1, 1] else None
            if self.repeat is None:
                self.renderer.set_texture(entry.map, entry.surface)
            else:
                from ..maps.composite import CompositeMap

                cols, rows = self.repeat
                cmap = CompositeMap.of([entry.map] * (cols * rows), cols)
                self.renderer.set_texture(cmap, _composite_surface([entry.surface] * (cols * rows), cols, cmap))
        if mm is not None:
            self.m_per_px = float(mm) * 1e-3
            self.renderer.lift()
        if profile is not None:
            self.renderer.set_profile(profile)
            self.renderer.lift()
        return self.describe("ready" if kind == "hello" else "state")

    def describe(self, kind: str = "state") -> dict[str, Any]:
        """The session's settings as a message."""
        p = self.renderer.profile
        d: dict[str, Any] = {
            "type": kind,
            "texture": self.texture_id,
            "mm_per_px": self.m_per_px * 1e3,
            "profile": p.name,
            "rendering": rendering_kind(p).name,
            "limits": p.limits.to_dict(),
            "output": self.state.output_name,
            "channels": self.renderer.channels,
        }
        if self.texture_id is not None:
            e = self.state.texture(self.texture_id)
            d["texture_width_mm"] = e.width_m * 1e3
            d["texture_height_mm"] = e.height_m * 1e3
            if self.repeat is not None:
                d["repeat"] = list(self.repeat)
        if self.composite is not None:
            ids, cols, cmap = self.composite
            d["composite"] = {"ids": ids, "cols": cols, "cell_mm": [cmap.cell_m[0] * 1e3, cmap.cell_m[1] * 1e3]}
        return d

    def _wake(self) -> None:
        self.arrival_ns = self.msg_ns
        self.due = True

    # ------------------------------------------------------------- rendering

    def render_pending(self) -> dict[str, Any] | None:
        """Render whatever is waiting; the drive message, or None if nothing was."""
        if self._idle_due:
            self._idle_due = False
            if not self.pending and not self.pending_lift:
                msg = self._drive_msg(self.renderer.still())
                msg["resting"] = True
                return msg
        if not self.pending and not self.pending_lift:
            return None
        res = None
        if self.pending_lift:
            self.pending_lift = False
            res = self.renderer.lift()
        if self.pending:
            samples = list(self.pending)
            self.pending.clear()
            res = self.renderer.feed(samples)
        return self._drive_msg(res)

    def _drive_msg(self, res: Any) -> dict[str, Any]:
        d = res.to_dict()
        d["type"] = "drive"
        d["rendering"] = rendering_kind(self.renderer.profile).name
        d["batch"] = self.batch
        d["resting"] = False
        # Why the output cannot be trusted now (a faulty sense path, a stopped
        # simulation): the page shows it beside the wire's state.
        d["output_fault"] = getattr(self.renderer.output, "fault", None)
        return d

    def schedule_idle(self, loop: asyncio.AbstractEventLoop) -> None:
        """(Re)arm the resting-pen timer after a render with the pen down."""
        if self._idle is not None:
            self._idle.cancel()
            self._idle = None
        if self.renderer.last.down and self.renderer.tracker.state is not None and self.renderer.tracker.state.speed_m_s > 0:
            self._idle = loop.call_later(IDLE_S, self._on_idle)

    def _on_idle(self) -> None:
        self._idle = None
        self._idle_due = True
        self.wake.set()

    def close(self) -> None:
        if self._idle is not None:
            self._idle.cancel()
        self.renderer.lift()


def _composite_surface(surfaces: list[SurfaceModel | None], cols: int, cmap: CompositeMap) -> CompositeSurface | None:
    """The surfaces laid out as the composite map lays the pictures (None if one is missing)."""
    present = [s for s in surfaces if s is not None]
    if len(present) < len(surfaces):
        return None
    from ..surface import CompositeSurface

    return CompositeSurface.of(present, cols, cmap.cell_m)


class _NoPicture:
    """The map before a texture is chosen: the pen is never over a picture."""

    def lookup(self, x_m: float, y_m: float) -> None:
        return None


async def websocket_endpoint(ws: WebSocket, state: ServerState) -> None:
    """Serve one page over its WebSocket until it disconnects."""
    await ws.accept()
    loop = asyncio.get_running_loop()
    # Choosing a texture looks its map up synchronously; make sure the built-in
    # maps exist (normally done at startup) without blocking the event loop.
    await loop.run_in_executor(None, state.warm)
    from .ownership import PEN, page_output

    telling: set[asyncio.Task] = set()  # the loop keeps only weak references to tasks

    def tell(doc: dict[str, Any]) -> None:
        if not closed.is_set():
            task = loop.create_task(send(doc))
            telling.add(task)
            task.add_done_callback(telling.discard)

    def told(doc: dict[str, Any]) -> None:  # from any thread: the lease's standing changed
        loop.call_soon_threadsafe(tell, doc)

    closed = asyncio.Event()
    output = page_output(state, PEN, told)
    session = PenSession(state, output)
    state.sessions += 1
    send_lock = asyncio.Lock()
    # Outputs that do background work in Python (the simulated wire) do it
    # between batches when told that one has just been sent.
    after_batch = output.after_batch
    drive_sent = asyncio.Event()

    async def send(doc: dict[str, Any]) -> None:
        await send_text(dumps(doc, compact=True))

    async def send_text(text: str) -> None:
        # The page may go at any moment, between the check and the send too: a
        # send that fails because it went is the end of the session, not an error
        # (Starlette answers a second send after a failed one with RuntimeError).
        async with send_lock:
            if closed.is_set() or ws.application_state != WebSocketState.CONNECTED:
                return
            try:
                await ws.send_text(text)
            except (WebSocketDisconnect, RuntimeError, OSError):
                closed.set()
                session.wake.set()

    async def deliver() -> None:
        """Render whatever is waiting and send its drive."""
        # Taken now: messages arriving while this batch is sent belong to the next.
        arrival, session.arrival_ns = session.arrival_ns, 0
        try:
            msg = session.render_pending()
        except TactilizeError as exc:  # e.g. a profile law refusing a value
            await send({"type": "error", "message": str(exc)})
            return
        if msg is None:
            return
        await send(msg)
        if arrival:
            state.latency_ns.append(time.perf_counter_ns() - arrival)
        after_batch()
        drive_sent.set()
        state.counters["drives_sent"] += 1
        session.schedule_idle(loop)

    async def renderer_task() -> None:
        while not closed.is_set():
            await session.wake.wait()
            session.wake.clear()
            session.due = False
            await deliver()

    async def wire_task() -> None:
        source = _wire_source(output)
        if source is None:
            return
        while not closed.is_set():
            await asyncio.sleep(WIRE_PERIOD_S)
            # Like the simulation thread, build the trace just after a drive went
            # out (if one does within half a period): a batch arriving while it is
            # built waits for it.
            drive_sent.clear()
            try:
                await asyncio.wait_for(drive_sent.wait(), 0.5 * WIRE_PERIOD_S)
            except asyncio.TimeoutError:
                pass
            try:
                # Built on the event loop, in the gap after a drive: it takes about
                # 0.1 ms, while handing it to a worker thread woke that thread and
                # passed the GIL to and fro 20 times a second, and the pen's
                # batches paid for it in their tail (docs/serve.md, Performance).
                text = _trace_text(source)
            except Exception as exc:  # the page's plot must never kill the pen
                log.debug("wire trace failed: %s", exc)
                return
            if text is not None:
                await send_text(text)

    tasks = [asyncio.create_task(renderer_task()), asyncio.create_task(wire_task())]
    budget = MessageRate()
    try:
        while not closed.is_set():
            message = await ws.receive()
            session.msg_ns = time.perf_counter_ns()
            if message["type"] == "websocket.disconnect":
                break
            if not budget.take():  # dropped unread: the other pages' drives do not wait for a flood
                if await budget.refuse(ws, lambda text: send({"type": "error", "message": text}), state.counters):
                    break
                continue
            text = message.get("text")
            if text is None:
                text = message.get("bytes")
            try:
                reply = session.handle(text)
            except _Bad as exc:
                state.counters["bad_messages"] += 1
                await send({"type": "error", "message": str(exc)})
                continue
            if reply is not None:
                await send(reply)
            # Rendered here, not handed to the render task: a hand-over is one more turn of
            # the event loop on the batch's path, and at each turn the simulated wire's thread
            # may take the interpreter's lock for a switch interval.  Only while a drive is
            # held up on its way out (a page not reading) does the render task take over.
            failed: list[BaseException] = []
            if session.due:
                session.due = False
                if send_lock.locked():
                    session.wake.set()
                    await asyncio.sleep(0)
                else:
                    try:
                        await deliver()
                    except Exception as exc:  # a bug: ended as in a helper task, below
                        failed.append(exc)
            for t in tasks:
                if t.done() and not t.cancelled() and (err := t.exception()) is not None:
                    failed.append(err)
            if failed:
                # A bug or a dead socket in a helper task: end this connection
                # (the output is stopped below); the page reconnects.
                log.error("pen session ended: %r", failed[0])
                try:
                    await ws.close(code=1011)
                except Exception:  # already gone
                    pass
                break
    except WebSocketDisconnect:
        pass
    finally:
        # Stop the actuators first, synchronously: awaiting anything here may be
        # cut short by a cancellation when the connection is torn down.
        session.close()
        output.close()
        state.sessions -= 1
        closed.set()
        session.wake.set()
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

