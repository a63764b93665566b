"""The stroke log's writer: pen samples stored once each, in group commits, off the event loop.

Rules, and why:

- every batch of samples the page sends carries an id chosen by the page; the
  table :class:`StrokeBatch` holds one row per stored batch with
  ``UNIQUE(session_id, batch_id)``, and the batch's samples are inserted in the
  same transaction, so a batch resent after a reconnect (or twice by a confused
  client) is stored once whatever happens, across processes too;
- one thread per store gathers the batches waiting and commits them together
  (a group commit): a commit costs milliseconds (SQLite with ``synchronous=FULL``
  syncs to disk), so committing per message caps everyone at a few hundred
  messages a second, while a group costs one commit for all of them;
- a batch's :class:`~concurrent.futures.Future` resolves only after its
  transaction committed; the page is acknowledged from there, and keeps every
  unacknowledged batch to resend it, so what the page was told is stored
  survives SIGKILL and what it was not told is sent again;
- a batch's rows may be given as a function that makes them, called in the
  writer's thread: the socket's thread then only computes what the page is
  answered with (:mod:`.strokes` logs a drive per sample and answers one per
  message).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, Union, cast

from sqlalchemy import Table, insert, select, update
from sqlalchemy.exc import IntegrityError

from .tables import StrokeBatch, StrokeSample, Trial, utcnow

__all__ = ["StrokeBatch", "SampleWriter", "writer_for", "MAX_GROUP_ITEMS"]

log = logging.getLogger(__name__)

#: At most this many batches go into one transaction (bounds its statements' size).
MAX_GROUP_ITEMS = 500


Rows = Union[list[dict[str, Any]], Callable[[], list[dict[str, Any]]]]


@dataclass
class _Item:
    session_id: int
    trial_id: int
    batch_id: str
    rows: Rows
    future: Future = field(default_factory=Future)


def _materialized(item: _Item) -> list[dict[str, Any]]:
    """The rows of an item :meth:`SampleWriter._materialize` has made."""
    if callable(item.rows):
        raise TypeError(f"batch {item.batch_id!r}: rows not made yet")
    return item.rows


class SampleWriter:
    """Writes batches of stroke samples in group commits from one thread.

    Parameters
    ----------
    store : Store
        The experiment store (its engine is shared; the writer opens its own
        connections from the pool).
    """

    THREAD_NAME = "tactilize-samples"

    def __init__(self, store):
        self.store = store
        self._cond = threading.Condition()
        self._items: list[_Item] = []
        self._submitted = 0
        self._finished = 0
        self._thread: threading.Thread | None = None

    def submit(self, session_id: int, trial_id: int, batch_id: str, rows: Rows) -> Future:
        """Queue one batch; the future gives ``"stored"`` or ``"duplicate"`` after the commit.

        ``rows`` is the list of the batch's :class:`~.store.StrokeSample` rows, or
        a function of no argument returning it, called once in the writer's thread.
        The future fails with the database's exception when the transaction does
        not commit (nothing of the batch is stored then; the page resends it), or
        with the function's when it raises (nothing of that batch is stored).
        """
        item = _Item(session_id, trial_id, str(batch_id), rows if callable(rows) else list(rows))
        with self._cond:
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._run, name=self.THREAD_NAME, daemon=True)
                self._thread.start()
            self._items.append(item)
            self._submitted += 1
            self._cond.notify_all()
        return item.future

    def barrier(self, timeout_s: float | None = 30.0) -> bool:
        """Wait until every batch submitted before this call is committed (or failed).

        Returns False when ``timeout_s`` (seconds) passed first."""
        with self._cond:
            target = self._submitted
            return self._cond.wait_for(lambda: self._finished >= target, timeout_s)

    # ------------------------------------------------------------ the thread

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: bool(self._items))
                group, self._items = self._items[:MAX_GROUP_ITEMS], self._items[MAX_GROUP_ITEMS:]
            group = self._materialize(group)
            try:
                statuses = self._write(group) if group else []
            except Exception as exc:  # the database is unreachable, full...: nothing of the group is stored
                log.warning("stroke samples not stored (%s); the pages keep them and resend", exc.__class__.__name__)
                for it in group:
                    it.future.set_exception(exc)
            else:
                for it, status in zip(group, statuses):
                    it.future.set_result(status)
            with self._cond:
                self._finished += len(group)
                self._cond.notify_all()

    def _materialize(self, group: list[_Item]) -> list[_Item]:
        """Make the rows given as functions; a batch whose function raises fails alone."""
        ready = []
        for it in group:
            if callable(it.rows):
                try:
                    it.rows = it.rows()
                except Exception as exc:
                    log.warning("stroke samples of batch %r not stored: %s", it.batch_id, exc)
                    it.future.set_exception(exc)
                    with self._cond:
                        self._finished += 1
                        self._cond.notify_all()
                    continue
            ready.append(it)
        return ready

    def _write(self, group: list[_Item]) -> list[str]:
        for _attempt in range(3):
            try:
                return self._write_once(group)
            except IntegrityError:
                # Another process stored one of these batches between our check and
                # our insert: the unique key refused it; the next check sees it.
                continue
        return self._write_once(group)

    def _write_once(self, group: list[_Item]) -> list[str]:
        # Declarative classes map Tables (their stubs say FromClause).
        batches = cast(Table, StrokeBatch.__table__)
        samples, trials = cast(Table, StrokeSample.__table__), cast(Table, Trial.__table__)
        now = utcnow()
        with self.store.engine.begin() as conn:
            ids = sorted({it.batch_id for it in group})
            seen = set(conn.execute(select(batches.c.session_id, batches.c.batch_id)
                                    .where(batches.c.batch_id.in_(ids))))
            fresh, statuses = [], []
            for it in group:
                key = (it.session_id, it.batch_id)
                if key in seen:
                    statuses.append("duplicate")
                    continue
                seen.add(key)
                fresh.append(it)
                statuses.append("stored")
            if fresh:
                conn.execute(insert(batches), [{"session_id": it.session_id, "trial_id": it.trial_id,
                                                "batch_id": it.batch_id, "n_samples": len(_materialized(it)),
                                                "received_at": now} for it in fresh])
                conn.execute(insert(samples),
                             [{"trial_id": it.trial_id, "received_at": now, **r} for it in fresh for r in _materialized(it)])
                conn.execute(update(trials)
                             .where(trials.c.id.in_(sorted({it.trial_id for it in fresh})),
                                    trials.c.started_at.is_(None))
                             .values(started_at=now))
        return statuses


_LOCK = threading.Lock()


def writer_for(store) -> SampleWriter:
    """The one writer of ``store`` (created on first use): one thread per database."""
    with _LOCK:
        w = store.__dict__.get("_sample_writer")
        if w is None:
            w = store.__dict__["_sample_writer"] = SampleWriter(store)
        return w
