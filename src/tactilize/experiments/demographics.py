"""Optional demographic questions a protocol defines (age, handedness...).

Written in the protocol next to its rating questions::

    [[demographics]]
    id = "age"
    text = "Age"
    kind = "integer"          # a whole number in [min, max]
    min = 18
    max = 99

    [[demographics]]
    id = "handedness"
    text = "Which hand do you write with?"
    kind = "choice"
    options = ["left", "right", "both"]

The items are part of the design (:class:`.design.DemographicItem`, read by
:func:`.design_toml.parse_demographics`); this module checks and stores a
participant's answers.  Every item is optional for the participant (an empty answer is stored as
nothing): a person may decline any of them and still take part.  Answers are
stored with the session (table ``participant_info``) and exported beside the
ratings.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import select

from .design import DemographicItem
from .design_toml import parse_demographics
from .errors import FlowError
from .tables import ExperimentSession, Participant, ParticipantInfo

__all__ = ["DemographicItem", "parse_demographics", "check_answers", "ParticipantInfo", "record", "all_answers"]


def check_answers(items: tuple[DemographicItem, ...], answers: Any) -> dict[str, str]:
    """Validated answers ``{id: value as text}``; empty or missing answers are left out.

    Raises
    ------
    FlowError
        (422) For an unknown item, an integer out of range or an unknown option.
    """
    if answers is None:
        return {}
    if not isinstance(answers, dict):
        raise FlowError("demographics", "expected an object {item id: answer}", 422)
    known = {d.id: d for d in items}
    out = {}
    for k, v in answers.items():
        if k not in known:
            raise FlowError("demographics", f"unknown item {k!r}", 422)
        if v is None or v == "":
            continue  # declined: every item is optional
        d = known[k]
        if d.kind == "integer":
            if isinstance(v, str) and v.strip().lstrip("-").isdigit():
                v = int(v)
            if isinstance(v, bool) or not isinstance(v, int) or not d.minimum <= v <= d.maximum:
                raise FlowError("demographics", f"{k}: a whole number {d.minimum} .. {d.maximum}, or nothing", 422)
        elif v not in d.options:
            raise FlowError("demographics", f"{k}: one of {', '.join(d.options)}, or nothing", 422)
        out[k] = str(v)
    return out


def record(store, session_id: int, answers: dict[str, str]) -> None:
    """Store a session's demographic answers (one transaction)."""
    if answers:
        with store.Session.begin() as s:
            s.add_all([ParticipantInfo(session_id=session_id, key=k, value=v) for k, v in answers.items()])


def all_answers(store) -> dict[tuple[str, str], dict[str, str]]:
    """``{(protocol, participant code): {item: value}}``."""
    out: dict[tuple[str, str], dict[str, str]] = {}
    with store.Session() as s:
        q = (select(Participant.design_name, Participant.code, ParticipantInfo.key, ParticipantInfo.value)
             .join(ExperimentSession, ExperimentSession.id == ParticipantInfo.session_id)
             .join(Participant, Participant.id == ExperimentSession.participant_id))
        for p, c, k, v in s.execute(q):
            out.setdefault((p, c), {})[k] = v
    return out
