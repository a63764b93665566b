"""The paper's user experiments, ready to run (``tactilize experiment``).

The package keeps the three concerns of an experiment apart, as expyriment does:

- **design** -- :mod:`.protocols`: a protocol is data (TOML): conditions (profile
  variations), images, questions with 1..7 anchors, repetitions and the order
  (a balanced Latin square by participant number, seeded and recorded);
- **IO** -- :mod:`.store`: SQLAlchemy tables for protocol versions, participants,
  sessions, trials, answers and stroke logs; every answer is committed before the
  page moves on, and nothing is ever overwritten;
- **control** -- :mod:`.flow`: the participant's state machine (consent,
  participant ID, calibration check, trials, breaks, end), used by the HTTP
  routes in :mod:`.web` and by the synthetic participants in :mod:`.simulate`.

On top: :mod:`.analysis` (descriptives, Friedman with Kendall's W, Wilcoxon with
Holm), :mod:`.figures` (the paper's Figs. 10, 12, 14 and 17) and
:mod:`.calibration` (a participant's own profile fitted from their ratings).

Heavy dependencies (pandas, pingouin, matplotlib) load only in the modules that
need them.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Protocol": "protocols",
    "Condition": "protocols",
    "Question": "protocols",
    "ImageSpec": "protocols",
    "load_protocol": "protocols",
    "builtin_protocols": "protocols",
    "balanced_latin_square": "protocols",
    "Store": "store",
    "default_db_url": "store",
    "Flow": "flow",
    "FlowError": "flow",
    "create_experiment_app": "web",
    "experiment_router": "web",
    "tidy_answers": "analysis",
    "analyze": "analysis",
    "make_figures": "figures",
    "fit_personal_profile": "calibration",
    "refinement_protocol": "calibration",
    "simulate_participants": "simulate",
}

# Names whose function is called differently from its module (the submodule
# ``simulate`` would otherwise shadow the function of the same name).
_ALIASES = {"simulate_participants": "simulate"}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'tactilize.experiments' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), _ALIASES.get(name, name))
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
