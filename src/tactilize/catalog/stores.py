"""Where rows go: a Parquet dataset (a folder of parts) or an SQL table.

Both stores have the same four steps: ``open(fingerprint)`` (create, or check
that a catalog being resumed was made with the same settings and versions),
``done_ids``, ``write(rows)`` and ``close``.  A write is whole or absent, so a
crash loses at most the rows not yet written.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from pathlib import Path
from typing import Any

from ..errors import CatalogError, CatalogVersionError, check_output_path
from ..redact import ambiguous_user, redact_text

__all__ = ["META_FILE", "PART_PREFIX", "ParquetStore", "SqlStore", "check_fingerprint", "is_sql_url", "open_store", "safe_url"]

#: The settings file of a Parquet catalog, beside its parts.
META_FILE = "_catalog.json"
#: Parts are ``part-00000.parquet``, ``part-00001.parquet``...
PART_PREFIX = "part-"

# Fingerprint keys that say which code wrote a catalog (the others are user settings).
_VERSION_KEYS = ("format", "tactilize", "analysis")


def is_sql_url(out: str | os.PathLike) -> bool:
    """True when ``out`` names a database (``sqlite:///x.db``, ``postgresql://...``)."""
    text = os.fspath(out)
    head = text.split("://", 1)[0] if "://" in text else ""
    return bool(head) and all(c.isalnum() or c in "+_" for c in head)


def safe_url(url: str) -> str:
    """The URL without its secrets, for messages (:func:`tactilize.redact.redact_url`)."""
    from ..redact import redact_url

    return redact_url(url)


def check_fingerprint(where: str, old: Any, new: dict[str, Any]) -> None:
    """Refuse to resume a catalog whose rows were computed another way.

    Parameters
    ----------
    where : str
        The catalog, for the message.
    old : dict or None
        The fingerprint stored with the catalog (None: a new catalog).
    new : dict
        This run's :meth:`AnalysisSettings.fingerprint`.

    Raises
    ------
    CatalogVersionError
        Another tactilize version, analysis version or layout wrote the catalog.
    CatalogError
        The same code with other settings (profile, speeds, dpi...).
    """
    if old is None or old == new:
        return
    if any(old.get(k) != new.get(k) for k in _VERSION_KEYS):
        raise CatalogVersionError(
            where,
            f"was written by {_versions(old)} and this is {_versions(new)}: resuming would mix rows computed "
            "two ways; give another --out (or delete this catalog to rebuild it)",
        )
    differ = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    raise CatalogError(
        where,
        f"was built with other settings ({', '.join(differ)} differ); resume with the same ones or give another --out",
    )


def _versions(fingerprint: dict[str, Any]) -> str:
    # Catalogs of format 2 and earlier recorded neither version.
    who = f"tactilize {fingerprint['tactilize']}" if fingerprint.get("tactilize") else "a tactilize that did not record its version"
    return f"{who} (catalog format {fingerprint.get('format', '?')}, analysis {fingerprint.get('analysis', 'unrecorded')})"


class ParquetStore:
    """A directory of Parquet parts plus ``_catalog.json``; each part is written atomically.

    Parameters
    ----------
    path : Path
        The catalog folder (created on :meth:`open`).
    columns : list of (str, str)
        Column names and kinds (``"str"``, ``"float"``, ``"int"``, ``"bool"``).
    """

    def __init__(self, path: Path, columns: list[tuple[str, str]]):
        from ..extras import require

        pa = require("pyarrow", f"--out {path}", "batch", error=CatalogError)

        self.path = path
        types = {"str": pa.string(), "float": pa.float64(), "int": pa.int64(), "bool": pa.bool_()}
        self.schema = pa.schema([(name, types[kind]) for name, kind in columns])

    def open(self, fingerprint: dict[str, Any]) -> None:
        if self.path.exists() and not self.path.is_dir():
            raise CatalogError(str(self.path), "exists and is not a directory (a Parquet catalog is a folder of parts)")
        try:
            self._open(fingerprint)
        except OSError as exc:
            raise CatalogError(str(self.path), f"cannot write the catalog here ({_os_fault(exc)})") from None

    def _open(self, fingerprint: dict[str, Any]) -> None:
        self.path.mkdir(parents=True, exist_ok=True)
        meta = self.path / META_FILE
        if meta.exists():
            old = json.loads(meta.read_text("utf-8"))
            check_fingerprint(str(self.path), old.get("settings"), fingerprint)
        else:
            _atomic_write(meta, json.dumps({"settings": fingerprint}, indent=2).encode("utf-8"))
        self._next = max((_part_number(p) for p in self._parts()), default=-1) + 1

    def _parts(self) -> list[Path]:
        return sorted(self.path.glob(f"{PART_PREFIX}*.parquet"))

    def done_ids(self, retry_failed: bool) -> set[str]:
        import pyarrow.parquet as pq

        status: dict[str, str] = {}
        for part in self._parts():
            t = pq.read_table(part, columns=["id", "status"])
            status.update(zip(t.column("id").to_pylist(), t.column("status").to_pylist()))
        return {i for i, s in status.items() if s == "ok" or not retry_failed}

    def write(self, rows: list[dict[str, Any]]) -> None:
        import pyarrow as pa

        # Column lists, not from_pylist: the latter costs ~1 ms a row in this process,
        # which the workers need.
        table = pa.Table.from_pydict({n: [r.get(n) for r in rows] for n in self.schema.names}, schema=self.schema)
        # Dot-prefixed temporaries are ignored by Parquet readers.
        tmp = self.path / f".{PART_PREFIX}{os.getpid()}-{self._next:05d}.parquet.tmp"
        try:
            self._write_part(table, tmp)
        except OSError as exc:  # a full or read-only disk: what is written stays, the run stops
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)
            raise CatalogError(str(self.path), f"cannot write a part of the catalog ({_os_fault(exc)}); the parts "
                               "written so far are kept, free space or fix the folder and rerun to resume") from None

    def _write_part(self, table: Any, tmp: Path) -> None:
        import pyarrow.parquet as pq

        pq.write_table(table, tmp)
        try:
            while True:
                final = self.path / f"{PART_PREFIX}{self._next:05d}.parquet"
                self._next += 1
                try:
                    # link, unlike rename, refuses to replace: a second batch writing
                    # into the same folder takes the next number instead of a part.
                    os.link(tmp, final)
                    break
                except FileExistsError:
                    continue
                except OSError:  # a file system without hard links
                    if final.exists():
                        continue
                    os.replace(tmp, final)
                    break
        finally:
            tmp.unlink(missing_ok=True)

    def close(self) -> None:
        pass


def _os_fault(exc: OSError) -> str:
    """An OSError in words, without a traceback's worth of path (the message names the folder)."""
    return exc.strerror or str(exc) or exc.__class__.__name__


def _part_number(p: Path) -> int:
    try:
        return int(p.stem[len(PART_PREFIX) :])
    except ValueError:
        return -1


def _atomic_write(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


class SqlStore:
    """One table (``id`` primary key) plus ``<table>_meta``; one transaction per write.

    Parameters
    ----------
    url : str
        An SQLAlchemy URL.
    columns : list of (str, str)
        Column names and kinds (``"str"``, ``"float"``, ``"int"``, ``"bool"``).
    table : str
        The rows' table; the settings go to ``<table>_meta``.
    """

    def __init__(self, url: str, columns: list[tuple[str, str]], table: str):
        import sqlalchemy as sa

        self.url = url
        if ambiguous_user(url):
            raise CatalogError(safe_url(url), "more than one '@' before the host: write an '@' inside the password as %40")
        try:
            self.engine = sa.create_engine(url)
        except Exception as exc:  # unknown dialect, missing driver, malformed URL
            raise CatalogError(safe_url(url), f"cannot use this database URL ({exc.__class__.__name__}: "
                               f"{redact_text(str(exc), url)})") from None
        types = {"str": sa.Text, "float": sa.Float, "int": sa.BigInteger, "bool": sa.Boolean}
        md = sa.MetaData()
        self.table = sa.Table(
            table,
            md,
            *[sa.Column(name, sa.String(512) if name == "id" else types[kind](), primary_key=(name == "id")) for name, kind in columns],
        )
        self.meta = sa.Table(f"{table}_meta", md, sa.Column("key", sa.String(64), primary_key=True), sa.Column("value", sa.Text))
        self.md = md

    def open(self, fingerprint: dict[str, Any]) -> None:
        import sqlalchemy as sa

        try:
            self.md.create_all(self.engine)
            with self.engine.begin() as conn:
                old = conn.execute(sa.select(self.meta.c.value).where(self.meta.c.key == "settings")).scalar()
                if old is None:
                    conn.execute(self.meta.insert(), [{"key": "settings", "value": json.dumps(fingerprint)}])
                else:
                    check_fingerprint(safe_url(self.url), json.loads(old), fingerprint)
        except sa.exc.SQLAlchemyError as exc:
            detail = redact_text(str(exc.orig if hasattr(exc, "orig") else exc), self.url)
            raise CatalogError(safe_url(self.url), f"database error ({exc.__class__.__name__}: {detail})") from None

    def done_ids(self, retry_failed: bool) -> set[str]:
        import sqlalchemy as sa

        q = sa.select(self.table.c.id)
        if retry_failed:
            q = q.where(self.table.c.status == "ok")
        with self.engine.connect() as conn:
            return {r[0] for r in conn.execute(q)}

    def write(self, rows: list[dict[str, Any]]) -> None:
        names = [c.name for c in self.table.columns]
        clean = [{n: _sql_value(r.get(n)) for n in names} for r in rows]
        with self.engine.begin() as conn:
            # A retried id replaces its earlier (failed) row in the same transaction.
            conn.execute(self.table.delete().where(self.table.c.id.in_([r["id"] for r in clean])))
            conn.execute(self.table.insert(), clean)

    def close(self) -> None:
        self.engine.dispose()


def _sql_value(v: Any) -> Any:
    # Not every database stores NaN/inf; NULL means "no value" in every one of them.
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def open_store(out: str | os.PathLike, columns: list[tuple[str, str]], table: str) -> ParquetStore | SqlStore:
    """The store for an output: an SQL table for a database URL, else a Parquet folder."""
    if is_sql_url(out):
        return SqlStore(os.fspath(out), columns, table)
    path = check_output_path(out, CatalogError, folder=True)
    if path.suffix.lower() in _FILE_SUFFIXES:
        # A folder named like a file would be read as that file by every other tool.
        raise CatalogError(str(out), f"a catalog is a Parquet folder or an SQLAlchemy URL, not a {path.suffix} file: "
                                     "give a folder name (pandas.read_parquet reads it back, .to_csv writes CSV)")
    return ParquetStore(path, columns)


#: Names that say "one file", which a Parquet catalog (a folder of parts) is not.
_FILE_SUFFIXES = (".csv", ".tsv", ".txt", ".json", ".jsonl", ".xlsx", ".xls")
