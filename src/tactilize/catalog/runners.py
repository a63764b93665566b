"""Where the work runs: this process, a local process pool, or a Dask cluster.

Each runner takes a :class:`Feeder` of items and yields lists of rows as tasks
finish, in any order.  All three send the same function,
:func:`~tactilize.catalog.analyse_chunk`, so the rows do not depend
on where they were computed.  A worker that dies costs error rows for its
task, never the batch.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterator, Sequence
from typing import Any

from ..errors import CatalogError
from ..features import warm_up
from .analysis import AnalysisSettings, analyse_chunk, base_row
from .sources import CatalogItem

__all__ = ["Feeder", "default_workers", "run_dask", "run_processes", "run_serial"]

_WORKER_DIED = (
    "the worker process died during this task (out of memory, or a crash in a decoder); "
    "innocent images of the same task are marked too: rerun with --retry-failed"
)


def default_workers() -> int:
    """Cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


class Feeder:
    """Hands out tasks of a size that adapts to how long an image takes.

    A task should last about ``target_s``: long enough that sending it and its
    rows costs little beside the analysis (tiny thumbnails need hundreds per
    task), short enough that progress moves and, near the end, no worker waits
    for another's long task (no task takes more than a share of what is left).

    Parameters
    ----------
    items : sequence of CatalogItem
        What is left to analyse.
    slots : int
        Tasks that run at once (workers, or a cluster's threads).
    fixed : int, optional
        Items per task, instead of the adaptive size.
    target_s : float
        How long a task should last [s].
    """

    def __init__(self, items: Sequence[CatalogItem], slots: int, fixed: int | None = None, target_s: float = 0.15):
        self.items = items
        self.slots = max(1, slots)
        self.fixed = fixed
        self.target_s = target_s
        self.pos = 0
        self.size = fixed or 2  # small first tasks give a first estimate quickly
        self.per_image_s: float | None = None

    def __bool__(self) -> bool:
        return self.pos < len(self.items)

    def next(self) -> list[CatalogItem] | None:
        """The next task's items, or None when every item has been handed out."""
        remaining = len(self.items) - self.pos
        if remaining <= 0:
            return None
        size = self.fixed or max(1, min(self.size, remaining // (2 * self.slots) or 1))
        chunk = list(self.items[self.pos : self.pos + size])
        self.pos += len(chunk)
        return chunk

    def observe(self, rows: list[dict[str, Any]]) -> None:
        """Learn the time per image [s] from a finished task's rows."""
        if self.fixed:
            return
        secs = [r["seconds"] for r in rows if r.get("seconds")]
        if not secs:
            return
        t = sum(secs) / len(secs)
        # A moving average: one slow image must not swing the task size.
        self.per_image_s = t if self.per_image_s is None else 0.7 * self.per_image_s + 0.3 * t
        self.size = int(min(512, max(1, self.target_s / max(self.per_image_s, 1e-6))))


def _error_rows(chunk: Sequence[CatalogItem], settings: AnalysisSettings, reason: str) -> list[dict[str, Any]]:
    """Error rows for a task whose worker died: the batch goes on, --retry-failed redoes them."""
    return [{**base_row(it, settings), "status": "error", "error": reason, "seconds": None} for it in chunk]


def run_serial(feed: Feeder, settings: AnalysisSettings) -> Iterator[list[dict[str, Any]]]:
    """Every task in this process, one after the other."""
    while (chunk := feed.next()) is not None:
        rows = analyse_chunk(chunk, settings)
        feed.observe(rows)
        yield rows


def _die_with_parent(parent_pid: int) -> None:
    """End this worker when the batch's process ends, however it ends.

    A pool's workers wait for tasks on a pipe; a parent killed (SIGKILL, the OOM
    killer) closed nothing they notice, so they lived on, each holding a core's
    worth of memory.  Linux sends them SIGTERM when the parent goes
    (``PR_SET_PDEATHSIG``); elsewhere a thread watches the parent's id.
    """
    import signal
    import threading

    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(1, signal.SIGTERM, 0, 0, 0) != 0:  # 1: PR_SET_PDEATHSIG
            raise OSError(ctypes.get_errno(), "prctl")
        if os.getppid() != parent_pid:  # gone before the request took effect
            os._exit(1)
        return
    except (OSError, AttributeError):
        pass

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="tactilize-parent-watch", daemon=True).start()


def _init_worker(parent_pid: int | None = None) -> None:
    """Process-pool initialiser: one core per process, Ctrl-C is the parent's business,
    and the worker ends with its parent."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent_pid is not None:
        _die_with_parent(parent_pid)
    try:
        # Several processes each starting a BLAS thread per core would fight over the cores.
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except Exception:
        pass
    # Nothing to do in a worker forked from a parent that warmed up (see run_processes);
    # a worker started afresh loads the compiled passes now, not inside its first task.
    warm_up()


def run_processes(feed: Feeder, settings: AnalysisSettings, workers: int) -> Iterator[list[dict[str, Any]]]:
    """Tasks on a pool of ``workers`` local processes; a pool that loses a worker is replaced."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # Ready in the parent, the compiled analysis is inherited by every forked worker:
    # loading it costs each fresh process a few tenths of a second, as much as 40 images.
    warm_up()

    def new_pool() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=workers, initializer=_init_worker, initargs=(os.getpid(),))

    pool = new_pool()
    chunk_of: dict[Any, list[CatalogItem]] = {}

    def submit(chunk: list[CatalogItem]) -> None:
        nonlocal pool
        try:
            fut = pool.submit(analyse_chunk, chunk, settings)
        except BrokenProcessPool:
            # A worker was killed (say by the OOM killer): the pool is unusable, start another.
            pool.shutdown(wait=False, cancel_futures=True)
            pool = new_pool()
            fut = pool.submit(analyse_chunk, chunk, settings)
        chunk_of[fut] = chunk

    try:
        # A bounded number in flight keeps memory flat for a catalog of any size.
        while len(chunk_of) < 2 * workers and (chunk := feed.next()) is not None:
            submit(chunk)
        while chunk_of:
            done, _ = wait(list(chunk_of), return_when=FIRST_COMPLETED)
            for fut in done:
                chunk = chunk_of.pop(fut)
                try:
                    rows = fut.result()
                except BrokenProcessPool:
                    rows = _error_rows(chunk, settings, _WORKER_DIED)
                feed.observe(rows)
                nxt = feed.next()
                if nxt is not None:
                    submit(nxt)
                yield rows
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def run_dask(feed: Feeder, settings: AnalysisSettings, scheduler: Any, timeout_s: float) -> Iterator[list[dict[str, Any]]]:
    """Tasks on a Dask cluster: a scheduler address, or a connected ``distributed.Client``."""
    from ..extras import require

    distributed = require("distributed", "--scheduler", "batch", error=CatalogError)
    Client, as_completed = distributed.Client, distributed.as_completed
    KilledWorker = require("distributed.scheduler", "--scheduler", "batch", error=CatalogError).KilledWorker

    own = not isinstance(scheduler, Client)
    with _dask_quiet(own):
        yield from _run_dask(feed, settings, scheduler, timeout_s, own)


@contextlib.contextmanager
def _dask_quiet(own: bool) -> Iterator[None]:
    """While the batch's own client runs, Dask's logs stay out of the terminal:
    a lost scheduler is reported once, as one line, by the CatalogError."""
    import logging

    if not own:  # someone else's client: their logging is theirs
        yield
        return
    # Dask's configuration gives its loggers their own levels: each is silenced.
    names = ["distributed", *(n for n in logging.root.manager.loggerDict if n.startswith("distributed."))]
    saved = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for n, level in saved.items():
            logging.getLogger(n).setLevel(level)


def _one_line(exc: BaseException) -> str:
    return " ".join(f"{exc.__class__.__name__}: {exc}".split())


def _run_dask(feed: Feeder, settings: AnalysisSettings, scheduler: Any, timeout_s: float,
              own: bool) -> Iterator[list[dict[str, Any]]]:
    from distributed import Client, as_completed
    from distributed.scheduler import KilledWorker

    if own:
        try:
            client = Client(str(scheduler), timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise CatalogError(str(scheduler), f"cannot reach the Dask scheduler ({_one_line(exc)})") from None
    else:
        client = scheduler
    try:
        feed.slots = max(1, sum(client.nthreads().values()))
        chunk_of: dict[Any, list[CatalogItem]] = {}
        queue = as_completed([], loop=client.loop)  # this client need not be the default one

        def submit(chunk: list[CatalogItem]) -> None:
            f = client.submit(analyse_chunk, chunk, settings, pure=False)
            chunk_of[f] = chunk
            queue.add(f)

        while len(chunk_of) < 2 * feed.slots and (first := feed.next()) is not None:
            submit(first)
        for fut in queue:
            chunk = chunk_of.pop(fut)
            try:
                rows = fut.result()
            except KilledWorker:
                # Dask already retried the task on other workers; each of them died.
                rows = _error_rows(chunk, settings, _WORKER_DIED)
            except Exception as exc:  # analyse_chunk never raises: this is the cluster
                lost = "scheduler-connection-lost" in str(exc) or exc.__class__.__name__ == "CommClosedError"
                raise CatalogError(
                    str(scheduler) if own else "<dask client>",
                    ("lost the Dask scheduler" if lost else f"the Dask cluster failed ({_one_line(exc)})")
                    + "; the rows finished so far are kept, rerun to resume",
                ) from None
            feed.observe(rows)
            nxt = feed.next()
            if nxt is not None:
                submit(nxt)
            yield rows
            fut.release()
    finally:
        if own:
            with contextlib.suppress(Exception):  # a dead scheduler cannot be told goodbye
                client.close(timeout=timeout_s)
