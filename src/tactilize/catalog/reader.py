"""Reading a catalog: the whole table as pandas, or one product at a time.

:class:`Catalog` is what the web API (:mod:`tactilize.catalog.api`) and scripts
use: counts, pages of ids, a product's row, its stored drives and its drive at
any speed from the stored features, without the image, or from its picture rendered
as the row's material (:meth:`Catalog.choice_of`) for a surface profile.  A catalog
written by an earlier version reads as it is; only a batch refuses to add to it.
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from typing import Any

from ..errors import CatalogError
from ..extras import require
from ..drive import Drive
from ..mapping import DriveFeatures, Profile
from ..materials import MaterialChoice
from .analysis import DEFAULT_SPEEDS_M_S, speed_label
from .stores import META_FILE, PART_PREFIX, is_sql_url, safe_url

__all__ = ["Catalog", "StoredFeatures", "read_catalog"]


def read_catalog(location: str | os.PathLike, *, table: str = "catalog"):
    """A catalog as a pandas DataFrame, one row per id (the latest when an id was retried).

    Parameters
    ----------
    location : str or path
        The Parquet folder or SQLAlchemy URL given to :func:`run_batch`.
    table : str
        Table name for an SQL catalog.

    Returns
    -------
    pandas.DataFrame
        Sorted by id; integer and boolean columns are nullable (an error row
        has no ``width_px``).  Units as in the column names (see ``docs/batch.md``).

    Raises
    ------
    CatalogError
        Not a catalog, or a table that cannot be read.
    """
    import pandas as pd

    if is_sql_url(location):
        import sqlalchemy as sa

        engine = sa.create_engine(os.fspath(location))
        try:
            with engine.connect() as conn:
                return pd.read_sql_table(table, conn)
        except (sa.exc.SQLAlchemyError, ValueError) as exc:
            raise CatalogError(safe_url(os.fspath(location)), f"cannot read table {table!r} ({exc.__class__.__name__})") from None
        finally:
            engine.dispose()
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(location)
    if not (path / META_FILE).exists():
        raise CatalogError(str(path), "not a catalog (no _catalog.json): make one with `tactilize batch`")
    parts = sorted(path.glob(f"{PART_PREFIX}*.parquet"))
    if not parts:
        return pd.DataFrame({"id": pd.Series([], dtype=object), "status": pd.Series([], dtype=object)})
    # Nullable integer and boolean columns: an error row has no width_px, and that
    # must not turn every width into a float.
    nullable = {pa.int64(): pd.Int64Dtype(), pa.bool_(): pd.BooleanDtype()}
    df = pa.concat_tables([pq.read_table(p) for p in parts]).to_pandas(types_mapper=nullable.get)
    # Parts are in write order, so the last row of an id is its latest analysis.
    df = df.drop_duplicates("id", keep="last")
    return df.sort_values("id", kind="stable").reset_index(drop=True)


#: The features a stored row keeps that :meth:`Profile.drive` reads: the one
#: value type for that, shared with the experiments.
StoredFeatures = DriveFeatures


class Catalog:
    """Read access to a catalog made by :func:`run_batch` (for the web API and scripts).

    Parameters
    ----------
    location : str or path
        The Parquet folder or SQLAlchemy URL.
    table : str
        Table name for an SQL catalog.

    Notes
    -----
    A Parquet catalog is read into memory (a few hundred bytes per product) and
    read again when its parts change, so a batch still running is seen as it
    grows.  An SQL catalog is queried per request.
    """

    def __init__(self, location: str | os.PathLike, *, table: str = "catalog"):
        self.location = os.fspath(location)
        self.table = table
        self.is_sql = is_sql_url(self.location)
        self._df = None
        self._parts_seen: tuple = ()
        self._checked = 0.0
        if self.is_sql:
            import sqlalchemy as sa

            self._engine = sa.create_engine(self.location)
            try:
                md = sa.MetaData()
                self._table = sa.Table(table, md, autoload_with=self._engine)
                meta = sa.Table(f"{table}_meta", md, autoload_with=self._engine)
                with self._engine.connect() as conn:
                    raw = conn.execute(sa.select(meta.c.value).where(meta.c.key == "settings")).scalar()
            except sa.exc.SQLAlchemyError as exc:
                raise CatalogError(safe_url(self.location), f"not a catalog ({exc.__class__.__name__})") from None
            self.settings = json.loads(raw) if raw else {}
        else:
            meta_path = Path(self.location) / META_FILE
            if not meta_path.exists():
                raise CatalogError(self.location, "not a catalog (no _catalog.json): make one with `tactilize batch`")
            self.settings = json.loads(meta_path.read_text("utf-8")).get("settings", {})
            # The parts are read at the first request: a missing extra is said now,
            # in one line, rather than as a 500 on every request.
            for module in ("pandas", "pyarrow.parquet"):
                require(module, self.location, prefer="batch")
        try:
            self.profile = Profile.from_dict(self.settings["profile"], source=f"{self.location} profile")
        except KeyError:
            self.profile = Profile.preset("paper")
        self.speeds_m_s: tuple[float, ...] = tuple(self.settings.get("speeds_m_s", DEFAULT_SPEEDS_M_S))

    # -- Parquet: an in-memory index, refreshed when the parts change

    def _frame(self):
        now = time.monotonic()
        if self._df is None or now - self._checked > 2.0:
            self._checked = now
            parts = tuple(sorted((p.name, p.stat().st_mtime_ns) for p in Path(self.location).glob(f"{PART_PREFIX}*.parquet")))
            if self._df is None or parts != self._parts_seen:
                df = read_catalog(self.location)
                self._df = df.set_index("id", drop=False)
                self._parts_seen = parts
        return self._df

    def counts(self) -> dict[str, int]:
        """``total``, ``ok`` and ``failed`` rows."""
        if self.is_sql:
            import sqlalchemy as sa

            with self._engine.connect() as conn:
                rows = conn.execute(sa.select(self._table.c.status, sa.func.count()).group_by(self._table.c.status)).all()
            by = {s: int(n) for s, n in rows}
        else:
            by = self._frame()["status"].value_counts().to_dict() if len(self._frame()) else {}
        ok = int(by.get("ok", 0))
        total = int(sum(by.values()))
        return {"total": total, "ok": ok, "failed": total - ok}

    def ids(self, *, offset: int = 0, limit: int = 100, status: str | None = None) -> list[str]:
        """Product ids in order, a page at a time."""
        if self.is_sql:
            import sqlalchemy as sa

            q = sa.select(self._table.c.id).order_by(self._table.c.id).offset(offset).limit(limit)
            if status:
                q = q.where(self._table.c.status == status)
            with self._engine.connect() as conn:
                return [r[0] for r in conn.execute(q)]
        df = self._frame()
        if status:
            df = df[df["status"] == status]
        return df["id"].iloc[offset : offset + limit].tolist()  # read_catalog sorts by id

    def get(self, product_id: str) -> dict[str, Any] | None:
        """The stored row of a product (missing values as None), or None if unknown."""
        if self.is_sql:
            import sqlalchemy as sa

            with self._engine.connect() as conn:
                r = conn.execute(sa.select(self._table).where(self._table.c.id == product_id)).mappings().first()
            row = dict(r) if r is not None else None
        else:
            df = self._frame()
            if product_id not in df.index:
                return None
            row = df.loc[product_id].to_dict()
        if row is None:
            return None
        return {k: _plain(v) for k, v in row.items()}

    @staticmethod
    def features_of(row: dict[str, Any]) -> StoredFeatures:
        """What :meth:`Profile.drive` needs, from a row with ``status == "ok"``."""
        return StoredFeatures(
            float(row.get("spatial_frequency_per_m") or 0.0),
            float(row.get("spectral_intensity") or 0.0),
            float(row.get("orientation_deg") or 0.0),
            # Unknown counts as directional, as Profile.drive assumes (every ok row has it).
            float(row["anisotropy"]) if row.get("anisotropy") is not None else 1.0,
            float(row["periodicity"]) if row.get("periodicity") is not None else 1.0,
        )

    @staticmethod
    def choice_of(row: dict[str, Any]) -> MaterialChoice:
        """What a row's picture is rendered as: its ``material`` (empty or absent: the picture
        alone) and its ``relief_rms_m`` [m] when the row carries one, as ``--material`` and
        ``--relief-mm`` name them.

        Raises
        ------
        MaterialError
            A material the library does not hold (such a row is an error row of the batch).
        """
        rms = row.get("relief_rms_m")
        return MaterialChoice.of(row.get("material") or None, None if rms is None else float(rms))

    def stored_drives(self, row: dict[str, Any]) -> list[tuple[float, Drive]]:
        """(speed [m/s], drive) at the catalog's reference speeds, as the batch stored them."""
        out: list[tuple[float, Drive]] = []
        if row.get("status") != "ok":
            return out
        for speed in self.speeds_m_s:
            p = f"drive_{speed_label(speed)}_"
            clamped = row.get(p + "clamped") or ""
            # Absent in catalogs from before they were stored; NaN in a float column means None.
            strength, regularity = row.get(p + "strength"), row.get(p + "regularity")
            out.append(
                (
                    speed,
                    Drive(
                        float(row[p + "pulse_frequency_hz"]),
                        float(row[p + "pulse_width_s"]),
                        float(row[p + "amplitude"]),
                        tuple(c for c in clamped.split(",") if c),
                        None if strength is None or strength != strength else float(strength),
                        None if regularity is None or regularity != regularity else float(regularity),
                    ),
                )
            )
        return out

    def drive(self, row: dict[str, Any], speed_m_s: float, profile: Profile | None = None) -> Drive:
        """The drive of a stored product at any speed [m/s] (the catalog's profile by default): what
        the profile renders for the picture stroked steadily, as the batch stores it.  A surface
        rendering reads the picture again (its bumps are not in the row) and renders it as the
        row's material (:meth:`choice_of`)."""
        prof = profile or self.profile
        from ..image import METRES_PER_INCH, load_image
        from ..surface.rendering import rendering_for

        pitch = row.get("pitch_m")
        # Read only by a rendering that needs the picture itself (its bumps are not in the row).
        picture = lambda: load_image(row["path"], dpi=METRES_PER_INCH / float(pitch) if pitch else None)  # noqa: E731
        rendering = rendering_for(prof, image=picture, **self.choice_of(row).surface_kwargs())
        return rendering.steady_drive(self.features_of(row), speed_m_s)

    def close(self) -> None:
        """Release the database connections (nothing to do for Parquet)."""
        if self.is_sql:
            self._engine.dispose()


def _pd_na() -> Any:
    try:
        import pandas as pd

        return pd.NA
    except ImportError:  # pragma: no cover
        return None


def _plain(v: Any) -> Any:
    """numpy scalars -> Python, NaN -> None (a missing value in an error row)."""
    if v is None or v is _pd_na():
        return None
    if hasattr(v, "item") and callable(v.item):
        v = v.item()
    if isinstance(v, float) and math.isnan(v):
        return None
    return v

