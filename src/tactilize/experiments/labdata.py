"""What a lab needs around the store: trial events, backups, withdrawal, wide tables.

Kept beside :mod:`.store` (which holds the core tables and their durability
rules) so that neither module grows past what a reader can hold at once.

- :class:`TrialEvent` marks what happened to a trial besides its answers; today
  ``interrupted``: the page lost its pen WebSocket during the trial (a server
  restart, a network drop) and reconnected.  The trial's samples stay with it
  (the page stamps each sample with its trial and image when it is taken), but
  an analysis may want to know that the stroke stream had a gap.
- :func:`backup` copies an SQLite store with SQLite's online backup API, which
  copies a consistent snapshot including what is still in the WAL file (a plain
  file copy of a running store misses the last committed transactions).
- :func:`withdraw` deletes one participant's data (answers, samples, trials,
  session, events, registration) in one transaction.
- :func:`wide_table` gives one row per participant and one column per
  condition x question (the layout SPSS and JASP expect for repeated measures).
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

from sqlalchemy import delete, select

from ..errors import TactilizeError
from ..redact import redact_url
from .tables import (
    Answer,
    Exclusion,
    ExperimentSession,
    Participant,
    ParticipantInfo,
    StrokeBatch,
    StrokeSample,
    Trial,
    TrialEvent,
    iso,
    utcnow,
)

__all__ = ["TrialEvent", "Exclusion", "record_event", "trial_events", "stroked_images", "backup", "withdraw", "exclude",
           "excluded_codes", "wide_table"]


def record_event(store, trial_id: int, kind: str, detail: dict[str, Any] | None = None) -> None:
    """Store one event of a trial (committed before returning)."""
    with store.Session.begin() as s:
        s.add(TrialEvent(trial_id=trial_id, kind=kind, detail_json=json.dumps(detail or {}), at=utcnow()))


def trial_events(store, session_id: int | None = None) -> list[dict[str, Any]]:
    """Every stored event: session, trial index, kind, detail, time."""
    with store.Session() as s:
        q = select(TrialEvent, Trial).join(Trial, TrialEvent.trial_id == Trial.id)
        if session_id is not None:
            q = q.where(Trial.session_id == session_id)
        return [{"session": t.session_id, "trial": t.index, "kind": e.kind, "detail": json.loads(e.detail_json),
                 "at": iso(e.at)} for e, t in s.execute(q.order_by(TrialEvent.id))]


def stroked_images(store, trial_id: int) -> set[str]:
    """Ids of the images of a trial with at least one logged pen sample."""
    with store.Session() as s:
        return set(s.scalars(select(StrokeSample.image_id).where(StrokeSample.trial_id == trial_id).distinct()))


def interrupted_trials(store) -> set[tuple[int, int]]:
    """``{(session id, trial index)}`` of the trials marked interrupted."""
    return {(e["session"], e["trial"]) for e in trial_events(store) if e["kind"] == "interrupted"}


def backup(store, target: str | Path) -> dict[str, Any]:
    """Copy an SQLite store to ``target`` with SQLite's online backup API.

    Safe while the server writes: the copy is one consistent snapshot holding
    every transaction committed when it was taken (WAL content included).

    Raises
    ------
    TactilizeError
        For a store that is not SQLite, or a target that exists or cannot be written.
    """
    url = store.url
    if not url.startswith("sqlite:///"):
        raise TactilizeError(redact_url(url), "backup copies SQLite stores; use the database's own tools "
                             "(pg_dump for PostgreSQL)")
    target = Path(target)
    if target.exists():
        raise TactilizeError(str(target), "already exists; a backup never overwrites a file")
    src_path = url[len("sqlite:///"):].split("?", 1)[0]
    try:
        src = sqlite3.connect(f"file:{src_path}?mode=ro", uri=True)
        try:
            dst = sqlite3.connect(str(target))
            try:
                src.backup(dst)
            finally:
                dst.close()
        finally:
            src.close()
    except (sqlite3.Error, OSError) as exc:
        raise TactilizeError(str(target), f"cannot write the backup ({exc})") from None
    with sqlite3.connect(str(target)) as con:
        n = con.execute("select count(*) from answers").fetchone()[0]
    return {"source": src_path, "backup": str(target), "answers": int(n), "at": iso(utcnow())}


def withdraw(store, protocol_name: str, code: str) -> dict[str, int]:
    """Delete participant ``code``'s data in ``protocol_name`` (one transaction).

    Their Latin-square number stays taken (so nobody else's order changes);
    the next participant does not move into it.  Returns the counts deleted.

    Raises
    ------
    TactilizeError
        When no such participant is registered.
    """
    with store.Session.begin() as s:
        part = s.scalar(select(Participant).where(Participant.design_name == protocol_name,
                                                  Participant.code == code))
        if part is None:
            raise TactilizeError(code, f"not registered for {protocol_name}")
        sess_ids = list(s.scalars(select(ExperimentSession.id).where(ExperimentSession.participant_id == part.id)))
        trial_ids = list(s.scalars(select(Trial.id).where(Trial.session_id.in_(sess_ids))))
        counts = {}
        for name, model, col in (("events", TrialEvent, TrialEvent.trial_id), ("answers", Answer, Answer.trial_id),
                                 ("stroke_samples", StrokeSample, StrokeSample.trial_id)):
            counts[name] = s.execute(delete(model).where(col.in_(trial_ids))).rowcount
        counts["stroke_batches"] = s.execute(delete(StrokeBatch).where(StrokeBatch.session_id.in_(sess_ids))).rowcount

        counts["demographics"] = s.execute(delete(ParticipantInfo).where(ParticipantInfo.session_id.in_(sess_ids))).rowcount
        counts["trials"] = s.execute(delete(Trial).where(Trial.id.in_(trial_ids))).rowcount
        counts["sessions"] = s.execute(delete(ExperimentSession).where(ExperimentSession.id.in_(sess_ids))).rowcount
        # The registration row goes too, but its number is kept as a placeholder
        # so that later participants keep their square rows.
        part.code = f"withdrawn-{part.id}"
        return counts


#: Excluded participants' numbers are moved above this, out of the square's rows.
PARKED = 1_000_000_000


def exclude(store, protocol_name: str, code: str, reason: str = "") -> dict[str, Any]:
    """Exclude participant ``code`` from ``protocol_name``'s analysis and free their square row.

    Their data stay in the store (flagged ``excluded`` in exports, left out of
    :func:`.analysis.analyze` and the figures by default); the next participant
    who registers takes their row of the Latin square, so the planned balance
    still holds when the study is complete.

    Raises
    ------
    TactilizeError
        When the participant is unknown or already excluded.
    """
    with store.Session.begin() as s:
        part = s.scalar(select(Participant).where(Participant.design_name == protocol_name,
                                                  Participant.code == code))
        if part is None:
            raise TactilizeError(code, f"not registered for {protocol_name}")
        if s.scalar(select(Exclusion).where(Exclusion.participant_id == part.id)) is not None:
            raise TactilizeError(code, "already excluded")
        row = abs(part.number)
        s.add(Exclusion(participant_id=part.id, square_number=row, reason=str(reason)[:500], at=utcnow()))
        part.number = (PARKED + part.id) * (-1 if part.simulated else 1)
        return {"participant": code, "freed_square_number": row}


def excluded_codes(store) -> dict[tuple[str, str], int]:
    """``{(protocol, participant code): square number they had}`` of the excluded participants."""
    with store.Session() as s:
        q = (select(Participant.design_name, Participant.code, Exclusion.square_number)
             .join(Exclusion, Exclusion.participant_id == Participant.id))
        return {(p, c): n for p, c, n in s.execute(q)}


def wide_table(df, demographics: dict | None = None):
    """One row per participant, one column ``<condition>_<question>`` of their mean
    rating (over images and repetitions): the repeated-measures layout of SPSS and JASP.

    ``demographics`` (``{(protocol, code): {item: value}}``) adds a column per item."""
    cell = df.groupby(["protocol", "participant", "condition", "question"], as_index=False)["rating"].mean()
    cell["column"] = cell["condition"].astype(str) + "_" + cell["question"].astype(str)
    wide = cell.pivot_table(index=["protocol", "participant"], columns="column", values="rating", aggfunc="first")
    wide.columns.name = None
    wide = wide.reset_index()
    if demographics:
        items = sorted({k for v in demographics.values() for k in v})
        for item in items:
            wide.insert(2, item, [demographics.get((p, c), {}).get(item, "") for p, c in
                                  zip(wide["protocol"], wide["participant"])])
    return wide
