"""The old name of the experiment's design modules, kept for code and notebooks written before.

A *protocol* is what the user meets: a protocol file (TOML), ``tactilize experiment
protocols``, the built-ins in ``experiments/protocols``.  In code the experiment's
design is a design (:mod:`.design`, read by :mod:`.design_toml`); "protocol"
names the serial byte format and the Output interface elsewhere in tactilize.
"""

from __future__ import annotations

from .design import (
    PROFILE_ROLES,
    Condition,
    DemographicItem,
    Design,
    ImageSpec,
    Question,
    TrialPlan,
    balanced_latin_square,
    williams_row,
)
from .design_toml import (
    builtin_designs,
    builtin_names,
    builtin_protocols,
    design_from_toml,
    load_design,
    load_protocol,
    protocol_from_toml,
)
from .errors import DesignError, ProtocolError

#: An experiment's design (:class:`.design.Design`).
Protocol = Design

__all__ = [
    "PROFILE_ROLES", "Condition", "DemographicItem", "Design", "DesignError", "ImageSpec", "Protocol",
    "ProtocolError", "Question", "TrialPlan", "balanced_latin_square", "builtin_designs", "builtin_names",
    "builtin_protocols", "design_from_toml", "load_design", "load_protocol", "protocol_from_toml", "williams_row",
]
