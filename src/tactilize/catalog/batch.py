"""The batch: a source in, a catalog out, resuming what an earlier run left.

:func:`run_batch` ties the other modules together, in one direction::

    discover(source) -> [CatalogItem] -> analyse_chunk (in workers) -> rows -> store

It opens the store (refusing a catalog made with other settings or by another
version), skips the ids already done, hands the rest to a runner and writes
the rows as they come, every few hundred rows or seconds, so that a crash, a
Ctrl-C or a lost cluster costs at most the rows not yet written.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import CatalogError
from ..mapping import Profile
from ..materials import MaterialChoice
from .analysis import DEFAULT_SPEEDS_M_S, AnalysisSettings, catalog_columns
from .runners import Feeder, default_workers, run_dask, run_processes, run_serial
from .sources import CatalogItem, discover, with_defaults
from .stores import is_sql_url, open_store, safe_url

__all__ = ["BatchSummary", "ProgressCallback", "TerminalProgress", "run_batch"]


@dataclass(frozen=True)
class BatchSummary:
    """What a batch did.

    Attributes
    ----------
    total : int
        Items in the source.
    ok, failed : int
        Rows written by this run, by status.
    skipped : int
        Items already in the output (not analysed again).
    seconds : float
        Wall-clock time of the run [s].
    out : str
        Where the rows went (a folder or a database URL without password).
    """

    total: int
    ok: int
    failed: int
    skipped: int
    seconds: float
    out: str

    @property
    def images_per_second(self) -> float:
        done = self.ok + self.failed
        return done / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "total": self.total,
            "ok": self.ok,
            "failed": self.failed,
            "skipped": self.skipped,
            "seconds": self.seconds,
            "images_per_second": self.images_per_second,
            "out": self.out,
        }


ProgressCallback = Callable[[int, int, int], None]


def run_batch(
    source: str | os.PathLike | Sequence[CatalogItem],
    out: str | os.PathLike,
    *,
    profile: Profile | str | os.PathLike | None = None,
    speeds_m_s: Sequence[float] = DEFAULT_SPEEDS_M_S,
    dpi: float | None = None,
    analysis_pitch_m: float | None = None,
    full_map: bool = False,
    material: str | None = None,
    relief_rms_m: float | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    scheduler_timeout_s: float = 10.0,
    retry_failed: bool = False,
    chunk_size: int | None = None,
    part_rows: int = 500,
    part_seconds: float = 20.0,
    table: str = "catalog",
    progress: ProgressCallback | None = None,
) -> BatchSummary:
    """Analyse every image of a source into a catalog; resumes a previous run.

    Parameters
    ----------
    source : str, path or sequence of CatalogItem
        A folder, glob or manifest (see :func:`discover`), or items already listed.
    out : str or path
        A Parquet catalog folder (created if needed), or an SQLAlchemy URL
        (``sqlite:///shop.db``, ``postgresql://...``).
    profile : Profile, preset name or TOML path, optional
        Laws for the stored drives; the ``paper`` preset by default.
    speeds_m_s : sequence of float
        Reference stroking speeds [m/s] (default 30, 60 and 120 mm/s).
    dpi : float, optional
        Displayed pixels per inch for images whose manifest row gives neither
        ``dpi`` nor ``width_mm`` (those win); else file metadata, else 96.
    analysis_pitch_m : float, optional
        Coarsest pixel pitch [m] the analysis may use; lets JPEGs be decoded at
        reduced size (see :class:`AnalysisSettings` and ``docs/batch.md``).
    full_map : bool
        Measure every texture-map tile whole rather than on its centred
        half-size square (see :class:`AnalysisSettings`).
    material : str, optional
        Library name of what every picture without a manifest ``material`` of its own
        is of (None: the picture alone).
    relief_rms_m : float, optional
        Relief RMS [m] of every picture without a manifest ``relief_mm`` of its own.
        Rows have a ``relief_rms_m`` column when a picture is given one.
    workers : int, optional
        Local processes (default: the cores this process may use).  1 runs in
        this process.  Ignored with ``scheduler``.
    scheduler : str or distributed.Client, optional
        A Dask scheduler address (``tcp://host:8786``) or a connected client:
        the work runs on that cluster, whose workers must see the image paths.
    scheduler_timeout_s : float
        How long to try to reach the scheduler [s].
    retry_failed : bool
        Also analyse again the ids whose earlier row is an error.
    chunk_size : int, optional
        Images per task.  By default it adapts so that a task lasts about
        0.15 s (many thumbnails, or one large photo per task), smaller near
        the end so that every worker stays busy.
    part_rows, part_seconds : int, float
        Rows are written when this many are waiting or this many seconds [s]
        have passed, whichever comes first: what a crash can lose at most.
    table : str
        Table name for an SQL output.
    progress : callable, optional
        ``progress(done, total, failed)`` after every finished task.

    Returns
    -------
    BatchSummary

    Raises
    ------
    CatalogVersionError
        ``out`` is a catalog written by another tactilize or analysis version
        (resuming it would mix rows computed two ways).
    CatalogError
        Unusable source, output, settings mismatch on resume, or scheduler.
    MaterialError
        ``material`` is not in the library, or ``relief_rms_m`` is not a positive number.
    ProfileError
        Unknown profile.
    """
    t0 = time.perf_counter()
    prof = profile if isinstance(profile, Profile) else Profile.resolve(None if profile is None else os.fspath(profile))
    choice = MaterialChoice.of(material, relief_rms_m)
    if isinstance(source, (str, os.PathLike)):
        items = discover(source, material=choice.name, relief_rms_m=choice.relief_rms_m)
    else:
        items = with_defaults(list(source), choice.name, choice.relief_rms_m)
    settings = AnalysisSettings(prof, tuple(speeds_m_s), dpi, analysis_pitch_m, full_map=full_map,
                                relief_column=any(it.relief_rms_m is not None for it in items))
    ids = [it.id for it in items]
    if len(set(ids)) != len(ids):
        raise CatalogError("<items>", "ids must be unique")

    store = open_store(out, catalog_columns(settings), table)
    store.open(settings.fingerprint())
    try:
        done_before = store.done_ids(retry_failed)
        todo = [it for it in items if it.id not in done_before]
        skipped = len(items) - len(todo)
        n_workers = max(1, int(workers)) if workers else default_workers()
        feed = Feeder(todo, n_workers, chunk_size)
        if scheduler is not None:
            results = run_dask(feed, settings, scheduler, scheduler_timeout_s)
        elif n_workers == 1 or len(todo) <= 1:
            results = run_serial(feed, settings)
        else:
            results = run_processes(feed, settings, n_workers)

        ok = failed = 0
        buffer: list[dict[str, Any]] = []
        last_write = time.monotonic()
        try:
            for rows in results:
                buffer.extend(rows)
                for r in rows:
                    if r["status"] == "ok":
                        ok += 1
                    else:
                        failed += 1
                if len(buffer) >= part_rows or time.monotonic() - last_write >= part_seconds:
                    store.write(buffer)
                    buffer, last_write = [], time.monotonic()
                if progress is not None:
                    progress(ok + failed, len(todo), failed)
        finally:
            # Also on Ctrl-C or a lost cluster: what is finished is kept, so a rerun resumes.
            if buffer:
                store.write(buffer)
            close = getattr(results, "close", None)
            if close is not None:
                close()
    finally:
        store.close()
    where = safe_url(os.fspath(out)) if is_sql_url(out) else os.fspath(out)
    return BatchSummary(len(items), ok, failed, skipped, time.perf_counter() - t0, where)



class TerminalProgress:
    """A one-line progress bar with rate and ETA, on a terminal only.

    Parameters
    ----------
    stream : file, optional
        Where to draw (stderr by default).  Nothing is drawn unless it is a TTY,
        so logs and pipes stay clean.
    """

    def __init__(self, stream: Any = None, *, min_interval_s: float = 0.1):
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.min_interval_s = min_interval_s
        self._t0 = time.monotonic()
        self._last = 0.0
        self._drawn = False

    def __call__(self, done: int, total: int, failed: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if done < total and now - self._last < self.min_interval_s:
            return
        self._last = now
        elapsed = now - self._t0
        rate = done / elapsed if elapsed > 0 else 0.0
        eta = (total - done) / rate if rate > 0 else math.inf
        width = 24
        filled = int(width * done / total) if total else width
        bar = "#" * filled + "." * (width - filled)
        eta_text = "--:--" if not math.isfinite(eta) else f"{int(eta // 60):02d}:{int(eta % 60):02d}"
        fail_text = f"  {failed} failed" if failed else ""
        line = f"\r{done}/{total} [{bar}] {100.0 * done / max(total, 1):5.1f}%  {rate:6.1f} img/s  ETA {eta_text}{fail_text}"
        self.stream.write(line + "\x1b[K")
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        """End the bar's line."""
        if self.enabled and self._drawn:
            self.stream.write("\n")
            self.stream.flush()
