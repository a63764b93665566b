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

Every item is optional for the participant (an empty answer is stored as
nothing): a person may decline any of them and still take part.  Answers are
stored with the session (table ``participant_info``) and exported beside the
ratings.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import select

from .tables import ExperimentSession, Participant, ParticipantInfo

__all__ = ["DemographicItem", "parse_demographics", "check_answers", "ParticipantInfo", "record", "all_answers"]


@dataclass(frozen=True)
class DemographicItem:
    """One optional question: ``kind`` ``integer`` (``minimum`` .. ``maximum``) or ``choice`` (``options``)."""

    id: str
    text: str
    kind: str = "choice"
    minimum: int = 0
    maximum: int = 150
    options: tuple[str, ...] = field(default_factory=tuple)

    def to_dict(self) -> dict[str, Any]:
        d = {"id": self.id, "text": self.text, "kind": self.kind}
        d.update({"min": self.minimum, "max": self.maximum} if self.kind == "integer" else {"options": list(self.options)})
        return d


def parse_demographics(source: str, items: Any) -> tuple[DemographicItem, ...]:
    """The ``[[demographics]]`` tables of a protocol, validated (raises ProtocolError)."""
    from .protocols import ProtocolError

    if items is None:
        return ()
    if not isinstance(items, list):
        raise ProtocolError(source, "demographics must be [[demographics]] tables")
    out = []
    for i, it in enumerate(items):
        where = f"demographics[{i}]"
        if not isinstance(it, dict):
            raise ProtocolError(source, f"{where} must be a table")
        extra = set(it) - {"id", "text", "kind", "min", "max", "options"}
        if extra:
            raise ProtocolError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        iid, text, kind = it.get("id"), it.get("text"), it.get("kind", "choice")
        if not isinstance(iid, str) or not iid.isidentifier() or not isinstance(text, str) or not text:
            raise ProtocolError(source, f"{where} needs an id (letters, digits, _) and a text")
        if kind == "integer":
            lo, hi = it.get("min", 0), it.get("max", 150)
            if not all(isinstance(v, int) and not isinstance(v, bool) for v in (lo, hi)) or lo > hi:
                raise ProtocolError(source, f"{where}: min and max must be whole numbers, min <= max")
            out.append(DemographicItem(iid, text, kind, lo, hi))
        elif kind == "choice":
            opts = it.get("options")
            if not isinstance(opts, list) or not opts or not all(isinstance(o, str) and o for o in opts):
                raise ProtocolError(source, f"{where}: a choice needs options = [\"...\", ...]")
            out.append(DemographicItem(iid, text, kind, options=tuple(opts)))
        else:
            raise ProtocolError(source, f"{where}.kind must be integer or choice, got {kind!r}")
    if len({d.id for d in out}) != len(out):
        raise ProtocolError(source, "demographics ids must be unique")
    return tuple(out)


def check_answers(items: tuple[DemographicItem, ...], answers: Any) -> dict[str, str]:
    """Validated answers ``{id: value as text}``; empty or missing answers are left out.

    Raises
    ------
    FlowError
        (422) For an unknown item, an integer out of range or an unknown option.
    """
    from .flow import FlowError

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
        q = (select(Participant.protocol_name, Participant.code, ParticipantInfo.key, ParticipantInfo.value)
             .join(ExperimentSession, ExperimentSession.id == ParticipantInfo.session_id)
             .join(Participant, Participant.id == ExperimentSession.participant_id))
        for p, c, k, v in s.execute(q):
            out.setdefault((p, c), {})[k] = v
    return out
