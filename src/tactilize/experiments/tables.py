"""Every table of the experiment store, and the timestamps they use (the store's bottom layer).

The durability rules the tables carry (unique answers, unique batches, the
whole plan written at the start) are described in :mod:`.store`; the queries
live there and in :mod:`.labdata`, :mod:`.demographics` and :mod:`.samples`.
Every table is declared here, on one :class:`Base`, so creating the schema
needs no module to be imported for its side effects.
"""

from __future__ import annotations

import datetime as dt
import json

from sqlalchemy import (
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

__all__ = [
    "SCHEMA_VERSION", "utcnow", "iso", "Base", "Meta", "ProtocolVersion", "DesignVersion", "Participant",
    "ExperimentSession", "Trial", "Answer", "StrokeSample", "StrokeBatch", "ParticipantInfo", "TrialEvent",
    "Exclusion",
]

SCHEMA_VERSION = 1


def utcnow() -> dt.datetime:
    """Now, in UTC (every stored timestamp is UTC)."""
    return dt.datetime.now(dt.timezone.utc)


def iso(t: dt.datetime | None) -> str | None:
    """ISO 8601 in UTC with a ``Z``; SQLite hands datetimes back naive, and they are UTC."""
    if t is None:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.timezone.utc)
    return t.astimezone(dt.timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


class Base(DeclarativeBase):
    pass


class Meta(Base):
    __tablename__ = "meta"
    key: Mapped[str] = mapped_column(String(64), primary_key=True)
    value: Mapped[str] = mapped_column(Text)


class DesignVersion(Base):
    """One exact design text (a protocol file), identified by its SHA-256."""

    __tablename__ = "protocol_versions"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(64), index=True)
    version: Mapped[str] = mapped_column(String(32))
    sha256: Mapped[str] = mapped_column(String(64), unique=True)
    text: Mapped[str] = mapped_column(Text)
    created_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class Participant(Base):
    """A participant of one protocol: the code they were given and their number
    (1, 2, ... in registration order), which picks their Latin-square row."""

    __tablename__ = "participants"
    __table_args__ = (
        UniqueConstraint("protocol_name", "code", name="uq_participant_code"),
        UniqueConstraint("protocol_name", "number", name="uq_participant_number"),
    )
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    # the column keeps its name: databases written before the rename load as they are
    design_name: Mapped[str] = mapped_column("protocol_name", String(64))
    code: Mapped[str] = mapped_column(String(64))
    number: Mapped[int] = mapped_column(Integer)
    simulated: Mapped[bool] = mapped_column(Boolean, default=False)
    created_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class ExperimentSession(Base):
    """One participant's run through one protocol version."""

    __tablename__ = "sessions"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    token: Mapped[str] = mapped_column(String(64), unique=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participants.id"), unique=True)
    design_version_id: Mapped[int] = mapped_column("protocol_version_id", ForeignKey("protocol_versions.id"))
    seed: Mapped[int] = mapped_column(Integer)
    order_json: Mapped[str] = mapped_column(Text)
    consent_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True))
    calibration_json: Mapped[str | None] = mapped_column(Text, nullable=True)
    calibrated_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    breaks_done: Mapped[int] = mapped_column(Integer, default=0)
    provenance_json: Mapped[str] = mapped_column(Text)
    created_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    completed_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)

    participant: Mapped[Participant] = relationship()
    design_version: Mapped[DesignVersion] = relationship()
    trials: Mapped[list["Trial"]] = relationship(order_by="Trial.index", back_populates="session")


class Trial(Base):
    __tablename__ = "trials"
    __table_args__ = (UniqueConstraint("session_id", "index", name="uq_trial_index"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id"), index=True)
    index: Mapped[int] = mapped_column(Integer)
    condition_id: Mapped[str] = mapped_column(String(64))
    repetition: Mapped[int] = mapped_column(Integer)
    image_ids_json: Mapped[str] = mapped_column(Text)
    started_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    completed_at: Mapped[dt.datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)

    session: Mapped[ExperimentSession] = relationship(back_populates="trials")
    answers: Mapped[list["Answer"]] = relationship(back_populates="trial", order_by="Answer.id")

    @property
    def image_ids(self) -> list[str]:
        return json.loads(self.image_ids_json)


class Answer(Base):
    __tablename__ = "answers"
    __table_args__ = (UniqueConstraint("trial_id", "question_id", name="uq_answer"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trials.id"), index=True)
    question_id: Mapped[str] = mapped_column(String(64))
    rating: Mapped[int] = mapped_column(Integer)
    answered_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    response_time_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    submission_id: Mapped[str | None] = mapped_column(String(64), nullable=True)

    trial: Mapped[Trial] = relationship(back_populates="answers")


class StrokeSample(Base):
    """One pen sample of a trial and the drive the server answered with (SI units)."""

    __tablename__ = "stroke_samples"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trials.id"), index=True)
    image_id: Mapped[str] = mapped_column(String(64))
    t_s: Mapped[float] = mapped_column(Float)
    x_m: Mapped[float] = mapped_column(Float)
    y_m: Mapped[float] = mapped_column(Float)
    pressure: Mapped[float | None] = mapped_column(Float, nullable=True)
    speed_m_s: Mapped[float] = mapped_column(Float)
    pulse_frequency_hz: Mapped[float] = mapped_column(Float)
    pulse_width_s: Mapped[float] = mapped_column(Float)
    amplitude: Mapped[float] = mapped_column(Float)
    received_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


#: The name the store used before designs were called designs.
ProtocolVersion = DesignVersion


class StrokeBatch(Base):
    """One stored batch of pen samples: the page's id for it, its trial and size."""

    __tablename__ = "stroke_batches"
    __table_args__ = (UniqueConstraint("session_id", "batch_id", name="uq_stroke_batch"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id"))
    trial_id: Mapped[int] = mapped_column(ForeignKey("trials.id"), index=True)
    batch_id: Mapped[str] = mapped_column(String(64))
    n_samples: Mapped[int] = mapped_column(Integer)
    received_at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class ParticipantInfo(Base):
    """One demographic answer of a session."""

    __tablename__ = "participant_info"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id"), index=True)
    key: Mapped[str] = mapped_column(String(64))
    value: Mapped[str] = mapped_column(String(200))


class TrialEvent(Base):
    """Something that happened to a trial (``kind``: ``interrupted``), with a JSON detail."""

    __tablename__ = "trial_events"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trials.id"), index=True)
    kind: Mapped[str] = mapped_column(String(32))
    detail_json: Mapped[str] = mapped_column(Text, default="{}")
    at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class Exclusion(Base):
    """A participant excluded from the analysis (their data stay), and the square row they had."""

    __tablename__ = "exclusions"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participants.id"), unique=True)
    square_number: Mapped[int] = mapped_column(Integer)
    reason: Mapped[str] = mapped_column(Text, default="")
    at: Mapped[dt.datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
