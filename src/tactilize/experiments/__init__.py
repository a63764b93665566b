"""The paper's user experiments, ready to run (``tactilize experiment``).

The package keeps the three concerns of an experiment apart, as expyriment does,
in layers that import one way (each only from those below it; the import contract
is ``experiments-layers`` in pyproject.toml):

- **web** -- :mod:`.cli`, :mod:`.web` (the participant and experimenter pages),
  :mod:`.pen_socket` (the pen's WebSocket);
- on the flow: :mod:`.calibration` (a participant's own profile fitted from
  their ratings), :mod:`.figures` (the paper's Figs. 10, 12, 14 and 17),
  :mod:`.simulate` (synthetic participants), :mod:`.visit` (several protocols in
  one visit), all over :mod:`.analysis` (descriptives, Friedman with Kendall's W,
  Wilcoxon with Holm);
- **control** -- :mod:`.flow`: the participant's state machine (consent,
  participant ID, calibration check, trials, breaks, end); :mod:`.strokes`
  handles the pen's messages, rendered by ``tactilize serve``'s renderer
  (:mod:`.feel`) on the protocol's pictures (:mod:`.pictures`);
- **IO** -- the store's queries: :mod:`.store` (sessions, answers: every answer
  committed before the page moves on, nothing ever overwritten),
  :mod:`.samples` (the stroke log's group commits), :mod:`.labdata` (events,
  backups, withdrawal, exclusions), :mod:`.demographics` (the answers);
- **design** -- :mod:`.design`: an experiment's design is data: conditions
  (profile variations), images, questions with 1..7 anchors, demographic items,
  repetitions and the order (a balanced Latin square by participant number,
  seeded and recorded); :mod:`.design_toml` reads it from a protocol file
  (TOML; the user meets "protocols": ``tactilize experiment protocols``, the
  built-ins in ``experiments/protocols``, and :mod:`.protocols` keeps the old
  names), :mod:`.checks` tries every condition on the simulated wire;
- :mod:`.tables`, every table of the store; :mod:`.errors` at the bottom.

Heavy dependencies (pandas, pingouin, matplotlib) load only in the functions
that need them; ``import tactilize.experiments`` loads none of the package.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Design": "design",
    "DesignError": "errors",
    "Condition": "design",
    "Question": "design",
    "ImageSpec": "design",
    "balanced_latin_square": "design",
    "load_design": "design_toml",
    "builtin_designs": "design_toml",
    "Protocol": "protocols",
    "ProtocolError": "errors",
    "load_protocol": "design_toml",
    "builtin_protocols": "design_toml",
    "Store": "store",
    "default_db_url": "store",
    "Flow": "flow",
    "FlowError": "errors",
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
