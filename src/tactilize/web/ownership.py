"""One output, many pages: who drives a physical output, and a simulated one per page.

A physical output (the serial controller, a sound card) is one device.  When
every page drove it, a second page (another tab, a phone, a page on another
site) that connected and closed put the first page's wire in standby, and its
strokes replaced the first page's drive, a participant's included.  Now
(docs/safety.md, "Who may touch what"):

- the device is held by one page at a time, through an :class:`OutputLease`:
  the first page to stroke holds it until it closes or is silent for
  :data:`IDLE_RELEASE_S`; a page that does not hold it is told it is in use
  and may take it over (a button on the page); an experiment trial
  (:data:`TRIAL`) outranks the pen page (:data:`PEN`), which cannot take it
  from a trial;
- a page that does not hold the device drives nothing: its ``apply`` plays
  nothing and answers off drives, and its ``stop`` and ``standby`` touch the
  device only while nobody strokes it (a hovering pen readies a free wire);
- a simulated output is no device: every page gets its own (its own wire
  model, traces and log), so concurrent participants each feel their own; a
  page that goes leaves its wire for the next page to connect (a reload finds it
  as warm as it was), never to two pages at once.

:func:`page_output` gives a page the output it uses; close it when the page goes.
"""

from __future__ import annotations

import itertools
import threading
import time
from typing import TYPE_CHECKING, Any, Callable, Sequence

from ..actuators.base import Output
from ..drive import Drive
from .state import ServerState

if TYPE_CHECKING:
    from ..surface.rendering import Frame

__all__ = ["PEN", "TRIAL", "IDLE_RELEASE_S", "OutputLease", "LeasedOutput", "page_output", "lease_of", "close_outputs"]

#: Ranks of the pages that may hold an output: a trial outranks the pen page.
PEN, TRIAL = 0, 1
_RANK_NAMES = {PEN: "pen page", TRIAL: "experiment trial"}
#: A holder silent this long [s] (no stroke) no longer keeps others out.
IDLE_RELEASE_S = 10.0


class OutputLease:
    """Who holds one physical output.

    Parameters
    ----------
    idle_s : float
        Silence [s] after which the holder may be replaced by any page that strokes.
    clock : callable
        Monotonic time [s] (injected by tests).

    Thread-safe: the pen pages call it on the event loop, the experiment's
    strokes from worker threads.
    """

    def __init__(self, idle_s: float = IDLE_RELEASE_S, clock: Callable[[], float] = time.monotonic) -> None:
        self.idle_s = float(idle_s)
        self.clock = clock
        self._lock = threading.Lock()
        self._holder: "LeasedOutput | None" = None
        self._last_s = 0.0
        self._pages: list["LeasedOutput"] = []

    def _free_for(self, page: "LeasedOutput", now: float, taking: bool) -> bool:
        h = self._holder
        if h is None or h is page:
            return True
        if now - self._last_s >= self.idle_s:
            return True
        return h.rank < page.rank or (taking and h.rank <= page.rank)

    def _switch(self, page: "LeasedOutput | None") -> list[tuple["LeasedOutput", dict[str, Any]]]:
        self._holder = page
        return [(p, self._status_for(p)) for p in self._pages]

    def _status_for(self, page: "LeasedOutput") -> dict[str, Any]:
        h = self._holder
        if h is None:
            return {"type": "output", "state": "free", "take_over": False}
        if h is page:
            return {"type": "output", "state": "yours", "take_over": False}
        return {"type": "output", "state": "in_use", "by": _RANK_NAMES[h.rank], "take_over": h.rank <= page.rank}

    def claim(self, page: "LeasedOutput") -> bool:
        """A stroke: True when ``page`` holds (or now takes) the output."""
        now = self.clock()
        with self._lock:
            if not self._free_for(page, now, taking=False):
                return False
            told = self._switch(page) if self._holder is not page else []
            self._last_s = now
        _tell(told)
        return True

    def take_over(self, page: "LeasedOutput") -> bool:
        """The page's user asked for the output: True when it now holds it
        (refused when a higher rank holds it and is not silent)."""
        now = self.clock()
        with self._lock:
            if not self._free_for(page, now, taking=True):
                return False
            told = self._switch(page) if self._holder is not page else []
            self._last_s = now
        _tell(told)
        return True

    def holds(self, page: "LeasedOutput") -> bool:
        return self._holder is page

    def may_rest(self, page: "LeasedOutput") -> bool:
        """May ``page`` stop the output or hold it ready?  When it holds it, or
        nobody does (a hovering pen readies a free wire), never under another
        page's stroke."""
        h = self._holder
        return h is None or h is page or self.clock() - self._last_s >= self.idle_s

    def status(self, page: "LeasedOutput") -> dict[str, Any]:
        """The ``{"type": "output", ...}`` message for ``page`` now."""
        with self._lock:
            return self._status_for(page)

    def join(self, page: "LeasedOutput") -> None:
        with self._lock:
            self._pages.append(page)

    def leave(self, page: "LeasedOutput") -> None:
        """The page closed: it no longer holds anything, and the others are told."""
        with self._lock:
            if page in self._pages:
                self._pages.remove(page)
            told = self._switch(None) if self._holder is page else []
        _tell(told)


def _tell(told: list[tuple["LeasedOutput", dict[str, Any]]]) -> None:
    for page, status in told:
        page.notify(status)


class LeasedOutput:
    """One page's view of a shared physical output: drives only while it holds the lease.

    Parameters
    ----------
    output : Output
        The device.
    lease : OutputLease
        Its lease.
    rank : int
        :data:`PEN` or :data:`TRIAL`.
    notify : callable, optional
        Called with the ``{"type": "output", ...}`` message whenever this page's
        standing changes (from any thread).
    """

    _ids = itertools.count(1)

    def __init__(self, output: Output, lease: OutputLease, rank: int = PEN,
                 notify: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.output, self.lease, self.rank = output, lease, int(rank)
        self.id = next(self._ids)
        self._notify = notify
        self._told_refused = False
        self.refused = 0  #: batches this page could not play
        lease.join(self)

    def __getattr__(self, name: str) -> Any:  # channels, traces, events, connected...
        return getattr(self.output, name)

    def notify(self, status: dict[str, Any]) -> None:
        self._told_refused = status["state"] == "in_use"
        if self._notify is not None:
            self._notify(status)

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        if self.lease.claim(self):
            return self.output.apply(channels)
        self.refused += 1
        if not self._told_refused:
            self.notify(self.lease.status(self))
        return [Drive.off()] * int(self.output.channels)

    def play(self, frame: Frame, now_s: float, channels: Sequence[Drive]) -> list[Drive]:
        # A frame is a stroke: it claims the lease as apply() does (else a page could replace
        # the holder's events, and its after_batch() would never reach the output).
        if self.lease.claim(self):
            return self.output.play(frame, now_s, channels)
        self.refused += 1
        if not self._told_refused:
            self.notify(self.lease.status(self))
        return [Drive.off()] * int(self.output.channels)

    def stop(self) -> None:
        if self.lease.may_rest(self):
            self.output.stop()

    def standby(self) -> None:
        if self.lease.may_rest(self):
            self.output.standby()

    def after_batch(self) -> None:
        if self.lease.holds(self):
            self.output.after_batch()

    def take_over(self) -> dict[str, Any]:
        """The page asks for the output; returns its standing after."""
        self.lease.take_over(self)
        return self.lease.status(self)

    def close(self) -> None:
        """The page went: rest the device if this page drove it, and let it go
        (the device itself stays open: the server owns it)."""
        if self.lease.holds(self):
            self.output.standby()
        self.lease.leave(self)

    def __enter__(self) -> "LeasedOutput":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _OwnOutput:
    """A page's own simulated output, handed back to its pool when the page goes."""

    def __init__(self, output: Output, pool: "_Pool") -> None:
        self.output: Output | None = output
        self._pool = pool

    def __getattr__(self, name: str) -> Any:
        return getattr(self.output, name)

    def take_over(self) -> dict[str, Any]:
        return {"type": "output", "state": "yours", "take_over": False}

    def close(self) -> None:
        out, self.output = self.output, None
        if out is not None:
            self._pool.put(out)


class _Pool:
    """Simulated outputs no page uses now, kept for the next page (a reload finds
    its wire as warm as it left it, as with one shared wire); never two pages at once."""

    def __init__(self, factory: Callable[[], Output], keep: int = 4) -> None:
        self.factory, self.keep = factory, keep
        self._idle: list[Output] = []
        self._lock = threading.Lock()

    def get(self) -> Output:
        with self._lock:
            if self._idle:
                return self._idle.pop()
        return self.factory()

    def put(self, out: Output) -> None:
        with self._lock:
            if len(self._idle) < self.keep:
                self._idle.append(out)
                return
        _close_soon(out)

    def close(self) -> None:
        with self._lock:
            idle, self._idle = self._idle, []
        for out in idle:
            out.close()


def _close_soon(out: Output) -> None:
    # Off the caller's thread: ending a simulated wire's thread waits up to a tick.
    threading.Thread(target=out.close, name="tactilize-close-output", daemon=True).start()


def close_outputs(state: ServerState) -> None:
    """Close the outputs kept for later pages (at the server's shutdown)."""
    pool = getattr(state, "page_output_pool", None)
    if pool is not None:
        pool.close()


def lease_of(state: ServerState) -> OutputLease:
    """The lease of the server's shared output (made on first use)."""
    lease = getattr(state, "output_lease", None)
    if lease is None:
        lease = state.output_lease = OutputLease()
    return lease


def page_output(
    state: ServerState, rank: int = PEN, notify: Callable[[dict[str, Any]], None] | None = None
) -> LeasedOutput | _OwnOutput:
    """The output a new page drives.

    Parameters
    ----------
    state : ServerState
        The server's; ``state.page_output_factory`` (set by :func:`tactilize.web.create_app`
        for a simulated output) makes one output per page, else ``state.output``
        is shared under its lease.
    rank : int
        :data:`PEN` or :data:`TRIAL`.
    notify : callable, optional
        See :class:`LeasedOutput`.

    Returns
    -------
    Output
        With ``take_over()`` and ``close()``; close it when the page goes.
    """
    factory = getattr(state, "page_output_factory", None)
    if factory is not None:
        pool = getattr(state, "page_output_pool", None)
        if pool is None:
            pool = state.page_output_pool = _Pool(factory)
        return _OwnOutput(pool.get(), pool)
    return LeasedOutput(state.output, lease_of(state), rank, notify)
