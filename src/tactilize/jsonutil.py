"""JSON for reports, the CLI and the web page: JSON has no NaN, infinity or numpy scalars."""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["jsonable", "dumps"]


def jsonable(x: Any) -> Any:
    """A copy of ``x`` that ``json.dumps`` accepts: non-finite floats become None,
    tuples lists, numpy scalars and arrays plain Python values."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if hasattr(x, "tolist") and callable(x.tolist):  # numpy arrays and scalars
        return jsonable(x.tolist())
    return x


def dumps(doc: Any, *, compact: bool = False) -> str:
    """Serialise a report; ``compact`` for the wire, indented for people."""
    if compact:
        return json.dumps(jsonable(doc), separators=(",", ":"))
    return json.dumps(jsonable(doc), indent=2)
