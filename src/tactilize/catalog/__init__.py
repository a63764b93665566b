"""Batch analysis of whole image catalogs, resumable, on local cores or a Dask cluster.

A shop has hundreds of thousands of product pictures; their tactile profiles are
computed once, kept, and served (``tactilize serve --catalog``).  This package
turns a *source* (a folder, a glob or a manifest) into a *catalog*: one row per
image with its features, a summary of its texture map, the drive at a few
reference stroking speeds for a profile, a status and, for an image that could
not be analysed, the reason.

The flow is one direction, one module per step::

    discover(source) -> [CatalogItem] -> analyse_chunk (in workers) -> rows -> store
    sources.py          sources.py       analysis.py, runners.py              stores.py

:mod:`~tactilize.catalog.batch` ties them together (:func:`run_batch`),
:mod:`~tactilize.catalog.reader` reads a catalog back (:func:`read_catalog`,
:class:`Catalog`) and :mod:`~tactilize.catalog.api` serves it over HTTP (it
needs FastAPI, so it is imported on its own, not from here).

* A bad image never stops a batch: it becomes a row with ``status == "error"``.
* Output is a Parquet dataset (a directory of ``part-NNNNN.parquet`` files,
  written atomically every few hundred rows) or any SQLAlchemy URL.  A rerun on
  the same output skips every id already there, so a crash loses at most the
  rows not yet written.  A rerun by another version of tactilize or of the
  analysis is refused (:class:`CatalogVersionError`).
* Work runs in local processes by default; given a Dask scheduler address (or a
  :class:`distributed.Client`) the same function runs on the cluster.

Units: SI inside (metres, seconds, cycles/m); the few columns in mm or mm/s say
so in their names.  See ``docs/batch.md`` for the columns and the options.
"""

from __future__ import annotations

from ..errors import CatalogError, CatalogVersionError
from .analysis import (
    ANALYSIS_VERSION,
    DEFAULT_SPEEDS_M_S,
    FORMAT_VERSION,
    AnalysisSettings,
    analyse_chunk,
    analyse_item,
    catalog_columns,
)
from .batch import BatchSummary, ProgressCallback, TerminalProgress, run_batch
from .reader import Catalog, StoredFeatures, read_catalog
from .runners import default_workers
from .sources import IMAGE_SUFFIXES, CatalogItem, discover
from .stores import is_sql_url

__all__ = [
    "ANALYSIS_VERSION",
    "DEFAULT_SPEEDS_M_S",
    "FORMAT_VERSION",
    "IMAGE_SUFFIXES",
    "AnalysisSettings",
    "BatchSummary",
    "Catalog",
    "CatalogError",
    "CatalogItem",
    "CatalogVersionError",
    "ProgressCallback",
    "StoredFeatures",
    "TerminalProgress",
    "analyse_chunk",
    "analyse_item",
    "catalog_columns",
    "default_workers",
    "discover",
    "is_sql_url",
    "read_catalog",
    "run_batch",
]
