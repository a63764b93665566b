"""The experiment store: the database and its queries, written so that no answer is ever lost,
duplicated or overwritten (the tables are in :mod:`.tables`).

An SQLite file under the user's data directory by default (see
:func:`default_db_url`), any SQLAlchemy URL otherwise (``postgresql://...``).

Durability rules, and why:

- every answer form is one transaction, committed before the HTTP response
  leaves, so "the page moved on" implies "the answers are on disk";
- ``UNIQUE(trial_id, question_id)`` makes a second copy of an answer impossible
  whatever the client does (double clicks, retries after a timeout, a restarted
  server); a resubmission with the same ratings is recognised and answered as
  success, a different one is refused (data are never overwritten);
- the whole trial plan is written when the session starts, so resuming is a
  query ("the first trial without all its answers"), not a reconstruction;
- SQLite runs in WAL mode with ``synchronous=FULL``: a committed transaction
  survives the process being killed (SIGKILL) and the machine losing power.
"""

from __future__ import annotations

import json
import platform
import secrets
from pathlib import Path
from typing import Any

import platformdirs
import sqlalchemy
from sqlalchemy import create_engine, event, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import sessionmaker

from .. import __version__
from ..errors import TactilizeError
from ..redact import ambiguous_user, redact_text, redact_url
from .design import Design
from .tables import (
    SCHEMA_VERSION,
    Answer,
    Base,
    Exclusion,
    ExperimentSession,
    Meta,
    Participant,
    ProtocolVersion,
    StrokeSample,
    Trial,
    iso,
    utcnow,
)

__all__ = [
    "SCHEMA_VERSION",
    "Store",
    "default_db_url",
    "provenance",
    "utcnow",
    "ProtocolVersion",
    "Participant",
    "ExperimentSession",
    "Trial",
    "Answer",
    "StrokeSample",
]

def default_db_url() -> str:
    """``sqlite:///<user data dir>/tactilize/experiments.sqlite3`` (the directory is created)."""
    root = Path(platformdirs.user_data_dir("tactilize", appauthor=False))
    root.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{root / 'experiments.sqlite3'}"


def provenance(**extra: Any) -> dict[str, Any]:
    """Versions of everything that shaped the data (written with every export)."""
    doc = {
        "tactilize": __version__,
        "python": platform.python_version(),
        "sqlalchemy": sqlalchemy.__version__,
        "platform": platform.platform(terse=True),
        "schema_version": SCHEMA_VERSION,
    }
    doc.update(extra)
    return doc


#: Size an SQLite write-ahead log is cut back to after a checkpoint [bytes].
WAL_LIMIT_BYTES = 16 * 1024 * 1024


def _sqlite_pragmas(dbapi_conn, _record) -> None:
    cur = dbapi_conn.cursor()
    # WAL + FULL: a commit is on disk when it returns, and readers (the
    # experimenter's view) never block the participant's writes.
    cur.execute("PRAGMA journal_mode=WAL")
    cur.execute("PRAGMA synchronous=FULL")
    # A WAL keeps the size it once grew to (while the disk was full and commits
    # failed, or the pages resent what they kept); cut back after each
    # checkpoint, the space freed on the disk stays free for the run.
    cur.execute(f"PRAGMA journal_size_limit={WAL_LIMIT_BYTES}")
    cur.execute("PRAGMA foreign_keys=ON")
    cur.execute("PRAGMA busy_timeout=10000")
    cur.close()


class Store:
    """The experiment database.

    Parameters
    ----------
    url : str, optional
        An SQLAlchemy URL; :func:`default_db_url` when None.  A bare file path is
        taken as an SQLite file.
    must_exist : bool
        Refuse an SQLite file that does not exist yet instead of creating it
        (the reading commands: a typo must not make an empty study database).
    """

    def __init__(self, url: str | None = None, must_exist: bool = False):
        url = url or default_db_url()
        if "://" not in url and redact_url(url) != url:
            # user:password@host without a scheme would become a file path, printed whole.
            raise TactilizeError(redact_url(url), "not a database URL (it needs a scheme, e.g. postgresql+psycopg://)")
        if ambiguous_user(url):
            raise TactilizeError(redact_url(url), "more than one '@' before the host: write an '@' inside the "
                                 "password as %40")
        if "://" not in url:
            url = f"sqlite:///{Path(url).expanduser().resolve()}"
        self.url = url
        if must_exist and url.startswith("sqlite:///"):
            path = url[len("sqlite:///"):].split("?", 1)[0]
            if path and path != ":memory:" and not Path(path).is_file():
                raise TactilizeError(path, "no such database (check the --db path)")
        try:
            self.engine = create_engine(url, future=True)
        except Exception as exc:  # a malformed URL or a missing driver
            raise TactilizeError(redact_url(url), f"cannot open database ({exc.__class__.__name__}: "
                                 f"{redact_text(str(exc), url)})") from None
        if self.engine.dialect.name == "sqlite":
            event.listen(self.engine, "connect", _sqlite_pragmas)

        try:
            Base.metadata.create_all(self.engine)
        except Exception as exc:
            raise TactilizeError(redact_url(url), f"cannot open database ({exc.__class__.__name__})") from None
        self.Session = sessionmaker(self.engine, expire_on_commit=False)
        with self.Session.begin() as s:
            if s.get(Meta, "schema_version") is None:
                s.add(Meta(key="schema_version", value=str(SCHEMA_VERSION)))
                s.add(Meta(key="created_with", value=json.dumps(provenance())))
        # Insert races on the Meta rows are harmless: both writers write the same.

    def set_meta(self, key: str, value: str) -> None:
        """Record a provenance note (first writer wins: notes are never overwritten)."""
        with self.Session() as s:
            if s.get(Meta, key) is None:
                s.add(Meta(key=key, value=value))
                try:
                    s.commit()
                except IntegrityError:
                    s.rollback()

    def meta(self) -> dict[str, str]:
        with self.Session() as s:
            return {m.key: m.value for m in s.scalars(select(Meta))}

    def close(self) -> None:
        self.engine.dispose()

    # ------------------------------------------------------------ protocols

    def design_version(self, protocol: Design) -> ProtocolVersion:
        """The stored row for this exact protocol text, inserted on first use."""
        with self.Session() as s:
            row = s.scalar(select(ProtocolVersion).where(ProtocolVersion.sha256 == protocol.sha256))
            if row is not None:
                return row
            row = ProtocolVersion(name=protocol.name, version=protocol.version, sha256=protocol.sha256, text=protocol.text)
            s.add(row)
            try:
                s.commit()
            except IntegrityError:  # another process stored it first
                s.rollback()
                row = s.scalars(select(ProtocolVersion).where(ProtocolVersion.sha256 == protocol.sha256)).one()
            return row

    # ------------------------------------------------------------ sessions

    def create_session(self, protocol: Design, code: str, *, simulated: bool = False, extra_provenance: dict | None = None) -> ExperimentSession:
        """Register participant ``code`` and write their whole trial plan.

        Returns the new :class:`ExperimentSession`.  Raises ``KeyError`` with the
        existing session when the code is already registered for this protocol.
        """
        pv = self.design_version(protocol)
        for _attempt in range(20):
            with self.Session() as s:
                existing = s.scalar(
                    select(Participant).where(Participant.design_name == protocol.name, Participant.code == code)
                )
                if existing is not None:
                    raise KeyError(code)
                # Simulated participants count apart (stored as -1, -2, ...): a pilot run
                # into the study database must not take real participants' square rows.
                # The lowest free row: an excluded participant's row (moved out of the way,
                # see labdata.exclude) goes to the next person, so the square stays balanced.
                sign = -1 if simulated else 1
                taken = set(s.scalars(select(Participant.number).where(
                    Participant.design_name == protocol.name, Participant.number * sign > 0)))
                number = next(n for n in range(1, len(taken) + 2) if sign * n not in taken)
                part = Participant(design_name=protocol.name, code=code, number=sign * number, simulated=simulated)
                s.add(part)
                plan = protocol.plan(number)
                sess = ExperimentSession(
                    token=secrets.token_urlsafe(18),
                    participant=part,
                    design_version_id=pv.id,
                    seed=protocol.seed,
                    order_json=json.dumps([t.condition_id for t in plan]),
                    consent_at=utcnow(),
                    provenance_json=json.dumps(
                        provenance(protocol=protocol.name, protocol_version=protocol.version,
                                   protocol_sha256=protocol.sha256, seed=protocol.seed,
                                   order_method=protocol.order_method, participant_number=number,
                                   **(extra_provenance or {}))
                    ),
                )
                s.add(sess)
                for t in plan:
                    s.add(Trial(session=sess, index=t.index, condition_id=t.condition_id,
                                repetition=t.repetition, image_ids_json=json.dumps(list(t.image_ids))))
                try:
                    s.commit()
                except IntegrityError:
                    # Two registrations raced for the same number (or code): retry,
                    # the loser recomputes; a taken code is reported above.
                    s.rollback()
                    continue
                with self.Session() as s2:
                    return s2.scalars(select(ExperimentSession).where(ExperimentSession.token == sess.token)).one()
        raise RuntimeError("could not allocate a participant number")

    def session_by_token(self, token: str) -> ExperimentSession | None:
        with self.Session() as s:
            return s.scalar(select(ExperimentSession).where(ExperimentSession.token == token))

    def session_by_code(self, protocol_name: str, code: str) -> ExperimentSession | None:
        with self.Session() as s:
            return s.scalar(
                select(ExperimentSession)
                .join(Participant)
                .where(Participant.design_name == protocol_name, Participant.code == code)
            )

    def participant(self, session: ExperimentSession) -> Participant:
        with self.Session() as s:
            return s.get_one(Participant, session.participant_id)

    def trials(self, session_id: int) -> list[Trial]:
        with self.Session() as s:
            return list(s.scalars(select(Trial).where(Trial.session_id == session_id).order_by(Trial.index)))

    def answers_of(self, session_id: int) -> dict[int, dict[str, int]]:
        """``{trial index: {question id: rating}}`` for one session."""
        with self.Session() as s:
            rows = s.execute(
                select(Trial.index, Answer.question_id, Answer.rating)
                .join(Answer, Answer.trial_id == Trial.id)
                .where(Trial.session_id == session_id)
            )
            out: dict[int, dict[str, int]] = {}
            for idx, q, r in rows:
                out.setdefault(idx, {})[q] = r
            return out

    def set_calibration(self, session_id: int, calibration: dict) -> None:
        with self.Session.begin() as s:
            sess = s.get_one(ExperimentSession, session_id)
            sess.calibration_json = json.dumps(calibration)
            sess.calibrated_at = utcnow()

    def set_breaks_done(self, session_id: int, n: int) -> None:
        with self.Session.begin() as s:
            sess = s.get_one(ExperimentSession, session_id)
            # Monotone: a stale page acknowledging an old break changes nothing.
            sess.breaks_done = max(sess.breaks_done or 0, n)

    def mark_trial_started(self, trial_id: int) -> None:
        with self.Session.begin() as s:
            t = s.get_one(Trial, trial_id)
            if t.started_at is None:
                t.started_at = utcnow()

    def record_answers(
        self,
        trial_id: int,
        ratings: dict[str, int],
        *,
        response_time_s: float | None = None,
        submission_id: str | None = None,
        complete_session_if_last: bool = True,
    ) -> str:
        """Write a trial's answers in one transaction.

        Returns ``"recorded"`` or ``"duplicate"`` (every rating already stored,
        identical).  Raises ``ValueError`` when a stored rating differs (answers
        are never overwritten).
        """
        with self.Session() as s:
            trial = s.get_one(Trial, trial_id)
            stored = {a.question_id: a.rating for a in trial.answers}
            clash = {q: (stored[q], r) for q, r in ratings.items() if q in stored and stored[q] != r}
            if clash:
                raise ValueError(clash)
            new = {q: r for q, r in ratings.items() if q not in stored}
            if not new:
                return "duplicate"
            now = utcnow()
            for q, r in new.items():
                s.add(Answer(trial_id=trial_id, question_id=q, rating=int(r), answered_at=now,
                             response_time_s=response_time_s, submission_id=submission_id))
            trial.completed_at = now
            if trial.started_at is None:
                trial.started_at = now
            if complete_session_if_last:
                remaining = s.scalar(
                    select(func.count(Trial.id)).where(
                        Trial.session_id == trial.session_id, Trial.completed_at.is_(None), Trial.id != trial.id
                    )
                )
                if remaining == 0:
                    s.get_one(ExperimentSession, trial.session_id).completed_at = now
            try:
                s.commit()
            except IntegrityError:
                # A concurrent identical submission won the race; the unique
                # constraint kept the data single.  Report what is stored now.
                s.rollback()
                again = {a.question_id: a.rating for a in s.get_one(Trial, trial_id).answers}
                if all(again.get(q) == r for q, r in ratings.items()):
                    return "duplicate"
                raise ValueError({q: (again.get(q), r) for q, r in ratings.items() if again.get(q) != r}) from None
            return "recorded"

    # ------------------------------------------------------------ reporting

    def sessions_overview(self, protocol_name: str | None = None) -> list[dict[str, Any]]:
        """One dict per session: participant, protocol, progress, timestamps."""
        with self.Session() as s:
            q = select(ExperimentSession, Participant, ProtocolVersion).join(Participant).join(ProtocolVersion)
            if protocol_name:
                q = q.where(Participant.design_name == protocol_name)
            excluded = {e.participant_id: e.square_number for e in s.scalars(select(Exclusion))}
            out = []
            for sess, part, pv in s.execute(q.order_by(ExperimentSession.id)):
                n_trials = s.scalar(select(func.count(Trial.id)).where(Trial.session_id == sess.id))
                n_done = s.scalar(
                    select(func.count(Trial.id)).where(Trial.session_id == sess.id, Trial.completed_at.is_not(None))
                )
                n_samples = s.scalar(
                    select(func.count(StrokeSample.id)).join(Trial).where(Trial.session_id == sess.id)
                )
                out.append({
                    "session": sess.id,
                    "participant": part.code,
                    "participant_number": excluded.get(part.id, abs(part.number)),
                    "simulated": part.simulated,
                    "excluded": part.id in excluded,
                    "protocol": pv.name,
                    "protocol_version": pv.version,
                    "protocol_sha256": pv.sha256,
                    "seed": sess.seed,
                    "trials_done": n_done,
                    "trials_total": n_trials,
                    "stroke_samples": n_samples,
                    "calibrated": sess.calibrated_at is not None,
                    "created_at": iso(sess.created_at),
                    "completed_at": iso(sess.completed_at),
                })
            return out

    def answer_rows(self, protocol_name: str | None = None) -> list[dict[str, Any]]:
        """Tidy rows, one per answer (see :func:`tactilize.experiments.analysis.tidy_answers`)."""
        with self.Session() as s:
            q = (
                select(Answer, Trial, ExperimentSession, Participant, ProtocolVersion)
                .join(Trial, Answer.trial_id == Trial.id)
                .join(ExperimentSession, Trial.session_id == ExperimentSession.id)
                .join(Participant, ExperimentSession.participant_id == Participant.id)
                .join(ProtocolVersion, ExperimentSession.design_version_id == ProtocolVersion.id)
            )
            if protocol_name:
                q = q.where(Participant.design_name == protocol_name)
            rows = []
            for a, t, sess, part, pv in s.execute(q.order_by(ExperimentSession.id, Trial.index, Answer.id)):
                images = json.loads(t.image_ids_json)
                rows.append({
                    "protocol": pv.name,
                    "protocol_version": pv.version,
                    "protocol_sha256": pv.sha256,
                    "seed": sess.seed,
                    "participant": part.code,
                    "participant_number": abs(part.number),
                    "simulated": part.simulated,
                    "session": sess.id,
                    "trial": t.index,
                    "repetition": t.repetition,
                    "condition": t.condition_id,
                    "image": "+".join(images),
                    "question": a.question_id,
                    "rating": a.rating,
                    "trial_started_at": iso(t.started_at),
                    "answered_at": iso(a.answered_at),
                    "response_time_s": a.response_time_s,
                })
            return rows

    def stroke_rows(self, session_id: int | None = None) -> list[dict[str, Any]]:
        with self.Session() as s:
            q = select(StrokeSample, Trial).join(Trial, StrokeSample.trial_id == Trial.id)
            if session_id is not None:
                q = q.where(Trial.session_id == session_id)
            return [
                {
                    "session": t.session_id, "trial": t.index, "condition": t.condition_id, "image": ss.image_id, "t_s": ss.t_s, "x_m": ss.x_m,
                    "y_m": ss.y_m, "pressure": ss.pressure, "speed_m_s": ss.speed_m_s,
                    "pulse_frequency_hz": ss.pulse_frequency_hz, "pulse_width_s": ss.pulse_width_s,
                    "amplitude": ss.amplitude, "received_at": iso(ss.received_at),
                }
                for ss, t in s.execute(q.order_by(StrokeSample.id))
            ]

    def protocol_names(self) -> list[str]:
        """Names of the protocols with a stored version."""
        with self.Session() as s:
            return sorted(set(s.scalars(select(ProtocolVersion.name))))

    def require_protocol(self, name: str | None) -> None:
        """Raise when ``name`` (a ``--protocol`` filter) has no data here: a typo
        must not give an empty export that looks like a result."""
        if name is not None and name not in self.protocol_names():
            known = ", ".join(self.protocol_names()) or "none"
            raise TactilizeError(f"--protocol {name}", f"no such protocol in this database (stored: {known})")

    def protocol_texts(self) -> list[dict[str, Any]]:
        with self.Session() as s:
            return [
                {"name": pv.name, "version": pv.version, "sha256": pv.sha256, "created_at": iso(pv.created_at),
                 "text": pv.text}
                for pv in s.scalars(select(ProtocolVersion).order_by(ProtocolVersion.id))
            ]
