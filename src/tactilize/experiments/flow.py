"""The participant flow: a small state machine over the store.

::

    (consent + participant ID) --start--> calibration --calibrate--> trial 1
        trial i --answers--> [break] --> trial i+1 ... --> done

Each state is computed from the database, never kept in memory, so a restarted
server (or a second browser tab) sees exactly what is stored: a session resumes
at the first trial without answers, and a page showing an old state is told so
instead of writing over the present.  The HTTP routes (:mod:`.web`) and the
synthetic participants (:mod:`.simulate`) both go through this class.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import time
from typing import Any

from ..actuators.base import Output
from ..errors import TactilizeError
from ..mapping import FeaturesForDrive
from ..pen.display import MM_PER_PX_RANGE, display_scale_error
from ..surface import SurfaceModel
from . import demographics as demo
from .design import Design
from .errors import FlowError
from .labdata import record_event, stroked_images
from .pictures import Pictures
from .samples import writer_for
from .store import Store
from .strokes import StrokeHandler
from .tables import ExperimentSession, iso, utcnow

__all__ = ["Flow", "FlowError", "StrokeHandler", "CODE_PATTERN", "OPEN_TRIAL_TTL_S"]

CODE_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$")
#: How long the open trial of a session is taken from memory (seconds): bounds how long
#: another process's answer may go unseen by the pen socket's drive.
OPEN_TRIAL_TTL_S = 1.0


class Flow:
    """The control layer for one protocol.

    Parameters
    ----------
    protocol : Design
        The experiment's design (a protocol file's).
    store : Store
    admin_token : str, optional
        When set, the experimenter endpoints require it (see :mod:`.web`).
    """

    def __init__(self, protocol: Design, store: Store, admin_token: str | None = None):
        self.design = protocol
        self.store = store
        self.admin_token = admin_token
        self.design_version = store.design_version(protocol)
        self._profiles = {c.id: protocol.profile(c.id) for c in protocol.conditions}
        self.pictures = Pictures(protocol)
        self._open_cache: dict[int, tuple[int | None, float]] = {}

    # ------------------------------------------------------------ pictures and laws

    def image_png(self, image_id: str) -> bytes:
        """The picture shown for a protocol image, as PNG bytes."""
        try:
            return self.pictures.png(image_id)
        except TactilizeError:
            raise FlowError("image", f"no image {image_id!r} in this protocol", 404) from None

    def image_features(self, image_id: str) -> FeaturesForDrive:
        """The features a protocol image drives with."""
        return self.pictures.features[image_id]

    def image_surface(self, image_id: str) -> SurfaceModel:
        """The surface model of a protocol image as shown (:meth:`.Pictures.surface`)."""
        return self.pictures.surface(image_id)

    def _image_doc(self, image_id: str) -> dict:
        # The size goes with the URL: the page lays the picture's box out before it loads.
        (w_px, h_px), (w_mm, h_mm) = self.pictures.size_px(image_id), self.pictures.display_mm(image_id)
        return {"id": image_id, "label": self.design.image(image_id).label, "url": f"images/{image_id}.png",
                "width_px": w_px, "height_px": h_px, "width_mm": w_mm, "height_mm": h_mm}

    def profile(self, condition_id: str):
        return self._profiles[condition_id]

    def session_of(self, token: str) -> ExperimentSession:
        """The session of ``token`` in this flow; raises :class:`FlowError` (404, or 409 for another version)."""
        sess = self.store.session_by_token(token) if isinstance(token, str) and len(token) < 100 else None
        if sess is None:
            raise FlowError("session", "unknown session; start again or resume with your participant ID", 404)
        if sess.design_version_id != self.design_version.id:
            raise FlowError("session", "this session belongs to another protocol version than the one being served", 409)
        return sess

    @staticmethod
    def _check_code(code: Any) -> str:
        if not isinstance(code, str) or not CODE_PATTERN.match(code.strip()):
            raise FlowError(
                "participant_id",
                "must be 1 to 32 letters, digits, - or _ (starting with a letter or digit)",
                422,
            )
        return code.strip()

    # ------------------------------------------------------------ transitions

    def start(self, code: Any, consent: Any, *, simulated: bool = False, extra_provenance: dict | None = None,
              demographics: Any = None) -> dict:
        """Consent given and participant ID entered: register and plan the session.

        ``demographics``: optional answers to the protocol's demographic items
        (``{id: value}``; empty values are declined answers)."""
        code = self._check_code(code)
        info = demo.check_answers(self.design.demographics, demographics)
        if consent is not True:
            raise FlowError("consent", "the participant must give consent before the session starts", 422)
        if not simulated and code.upper().startswith("SIM-"):
            # The prefix belongs to synthetic participants (simulate.py), who are
            # numbered and analysed apart; a person must not be mistaken for one.
            raise FlowError("participant_id", "IDs starting with SIM- are reserved for simulated participants", 422)
        try:
            # The consent text may live in its own file: record which text was agreed to.
            consent = {"consent_sha256": hashlib.sha256(self.design.consent.encode("utf-8")).hexdigest()}
            sess = self.store.create_session(self.design, code, simulated=simulated,
                                             extra_provenance={**consent, **(extra_provenance or {})})
        except KeyError:
            existing = self.store.session_by_code(self.design.name, code)
            done = existing is not None and existing.completed_at is not None
            raise FlowError(
                "participant_id",
                f"{code} is already registered for {self.design.name}"
                + (" and has finished" if done else "; use 'resume' to continue that session"),
                409,
                finished=done,
            ) from None
        demo.record(self.store, sess.id, info)
        return self.state(sess.token)

    def resume(self, code: Any) -> dict:
        """The state of an existing participant's session (to continue after a crash)."""
        code = self._check_code(code)
        sess = self.store.session_by_code(self.design.name, code)
        if sess is None:
            raise FlowError("participant_id", f"{code} is not registered for {self.design.name}; start a new session", 404)
        return self.state(sess.token)

    def calibrate(self, token: str, data: Any) -> dict:
        """Record the calibration check: the on-screen scale and whether the pen was felt.

        ``data``: ``card_width_px`` (the ID-1 card's width measured on screen, in
        CSS px) or ``mm_per_px`` directly, and ``felt`` (bool: the test vibration
        was felt).
        """
        sess = self.session_of(token)
        if not isinstance(data, dict):
            raise FlowError("calibration", "expected a JSON object", 422)
        card_mm = self.design.calibration_card_mm
        mm_per_px = data.get("mm_per_px")
        if mm_per_px is None and data.get("card_width_px") is not None:
            w = data["card_width_px"]
            if isinstance(w, (int, float)) and not isinstance(w, bool) and math.isfinite(w) and w > 0:
                mm_per_px = card_mm / float(w)
        if mm_per_px is None or display_scale_error(mm_per_px) is not None:  # the pen page's rule
            raise FlowError("calibration", f"screen scale must be {MM_PER_PX_RANGE[0]} .. {MM_PER_PX_RANGE[1]} mm per px "
                            f"(measure the {card_mm} mm card again)", 422)
        if data.get("felt") is not True:
            raise FlowError("calibration", "the test vibration must be felt before the trials start; "
                            "check the pen and its connection", 422)
        if sess.calibrated_at is not None:
            # Recorded once, never replaced: the stroke log of earlier trials was
            # converted with this scale.  A repeated identical request (a double
            # click, a retry) is fine; a different one is refused.
            stored = json.loads(sess.calibration_json or "{}")  # written with calibrated_at
            if abs(stored["mm_per_px"] - float(mm_per_px)) > 1e-9:
                raise FlowError("calibration", "the calibration of this session is already recorded; "
                                "reload to continue", 409)
            out = self.state(token)
            out["recorded"] = "duplicate"
            return out
        self.store.set_calibration(sess.id, {"mm_per_px": float(mm_per_px), "felt": True,
                                             "card_width_mm": card_mm, "at": iso(utcnow())})
        out = self.state(token)
        out["recorded"] = "recorded"
        return out

    def end_break(self, token: str, trial_index: Any) -> dict:
        sess = self.session_of(token)
        n = self._break_due(sess, self._first_open(sess))
        if n and trial_index == self._first_open(sess):
            self.store.set_breaks_done(sess.id, n)
        return self.state(token)

    def submit(self, token: str, trial_index: Any, ratings: Any, *, response_time_s: Any = None,
               submission_id: Any = None, comment: Any = None) -> dict:
        """Record the answers of one trial; returns the next state plus ``recorded``.

        Idempotent: resubmitting the same answers (a double click, a retry
        after a lost response) reports ``"duplicate"`` and changes nothing.
        ``comment`` is optional free text (at most 2000 characters), stored
        with the trial when the answers are recorded.
        """
        if comment is not None and (not isinstance(comment, str) or len(comment) > 2000):
            raise FlowError("comment", "must be text of at most 2000 characters", 422)
        comment = (comment or "").strip()
        sess = self.session_of(token)
        trials = self.store.trials(sess.id)
        if isinstance(trial_index, bool) or not isinstance(trial_index, int) or not 0 <= trial_index < len(trials):
            raise FlowError("trial", f"trial must be an index 0 .. {len(trials) - 1}", 422)
        ratings = self._check_ratings(ratings)
        if response_time_s is not None and (not isinstance(response_time_s, (int, float)) or isinstance(response_time_s, bool)
                                            or not math.isfinite(response_time_s) or response_time_s < 0):
            response_time_s = None
        trial = trials[trial_index]
        answered = self.store.answers_of(sess.id)
        current = self._first_open(sess, trials, answered)
        if trial_index in answered:
            stored = answered[trial_index]
            if all(stored.get(q) == r for q, r in ratings.items()) and len(stored) == len(ratings):
                out = self.state(token)
                out["recorded"] = "duplicate"
                return out
            raise FlowError("trial", f"trial {trial_index + 1} was already answered (a stale page?); answers are "
                            "never overwritten. Reload to continue.", 409, current_trial=current)
        if sess.calibrated_at is None:
            raise FlowError("trial", "the calibration check comes first; reload the page", 409, current_trial=current)
        if trial_index != current:
            raise FlowError("trial", f"trial {trial_index + 1} is not open (a stale page?); the current trial is "
                            f"{(current or 0) + 1}. Reload to continue.", 409, current_trial=current)
        if self._break_due(sess, current):
            raise FlowError("trial", "a break is due first; reload the page", 409, current_trial=current)
        if self.design.require_every_image:
            # Samples sent before the answer may still be in the writer's queue.
            writer_for(self.store).barrier()

            missing = [i for i in trial.image_ids if i not in stroked_images(self.store, trial.id)]
            if missing:
                labels = ", ".join(self.design.image(i).label for i in missing)
                raise FlowError("trial", f"stroke every picture before rating; not yet: {labels}", 409,
                                current_trial=current, unstroked=missing)
        try:
            status = self.store.record_answers(trial.id, ratings, response_time_s=response_time_s,
                                               submission_id=str(submission_id)[:64] if submission_id else None)
        except ValueError:
            raise FlowError("trial", f"trial {trial_index + 1} was already answered differently; answers are never "
                            "overwritten. Reload to continue.", 409, current_trial=current) from None
        self._open_cache.pop(sess.id, None)
        if status == "recorded" and comment:
            record_event(self.store, trial.id, "comment", {"text": comment})
        out = self.state(token)
        out["recorded"] = status
        return out

    def _check_ratings(self, ratings: Any) -> dict[str, int]:
        if not isinstance(ratings, dict):
            raise FlowError("ratings", "expected an object {question id: rating}", 422)
        expected = {q.id: q for q in self.design.questions}
        missing = sorted(set(expected) - set(ratings))
        extra = sorted(set(ratings) - set(expected))
        if missing:
            raise FlowError("ratings", f"missing answer(s) to {', '.join(missing)}", 422)
        if extra:
            raise FlowError("ratings", f"unknown question(s) {', '.join(map(str, extra))}", 422)
        out = {}
        for qid, r in ratings.items():
            q = expected[qid]
            if isinstance(r, bool) or not isinstance(r, int) or not q.scale_min <= r <= q.scale_max:
                raise FlowError("ratings", f"{qid}: rating must be a whole number {q.scale_min} .. {q.scale_max}, "
                                f"got {r!r}", 422)
            out[qid] = r
        return out

    # ------------------------------------------------------------ state

    def _first_open(self, sess, trials=None, answered=None) -> int | None:
        trials = trials if trials is not None else self.store.trials(sess.id)
        answered = answered if answered is not None else self.store.answers_of(sess.id)
        nq = len(self.design.questions)
        for t in trials:
            if len(answered.get(t.index, {})) < nq:
                return t.index
        return None

    def _break_due(self, sess, index: int | None) -> int:
        """The number of the break due before trial ``index`` (0: none)."""
        every = self.design.break_every
        if not every or not index or index % every:
            return 0
        n = index // every
        return n if (sess.breaks_done or 0) < n else 0

    def state(self, token: str) -> dict[str, Any]:
        """Where the session stands, for the page: one of ``calibration``, ``trial``,
        ``break`` or ``done``, with progress and (for a trial) what to show.

        The condition is not revealed to the participant (the page is blind)."""
        sess = self.session_of(token)
        part = self.store.participant(sess)
        trials = self.store.trials(sess.id)
        answered = self.store.answers_of(sess.id)
        current = self._first_open(sess, trials, answered)
        # Read from the database just now: the pen socket's next message needs no query.
        self._open_cache[sess.id] = (current, time.monotonic())
        done = sum(1 for t in trials if len(answered.get(t.index, {})) >= len(self.design.questions))
        doc: dict[str, Any] = {
            "session": token,
            "participant": part.code,
            "protocol": {"name": self.design.name, "title": self.design.title,
                         "description": self.design.description,
                         "calibration_card_mm": self.design.calibration_card_mm},
            "progress": {"done": done, "total": len(trials)},
            "calibration": json.loads(sess.calibration_json) if sess.calibration_json else None,
        }
        if current is None:
            doc["state"] = "done"
            return doc
        if sess.calibrated_at is None:
            doc["state"] = "calibration"
            doc["next_trial"] = current
            return doc
        brk = self._break_due(sess, current)
        if brk:
            doc["state"] = "break"
            doc["break"] = brk
            doc["next_trial"] = current
            return doc
        t = trials[current]
        self.store.mark_trial_started(t.id)
        doc["state"] = "trial"
        doc["trial"] = {
            "index": t.index,
            "number": t.index + 1,
            "images": [self._image_doc(iid) for iid in t.image_ids],
            "questions": [q.to_dict() for q in self.design.questions],
            "min_stroke_s": self.design.min_stroke_s,
            "require_every_image": self.design.require_every_image,
            "practice": t.repetition < 0,
        }
        return doc

    # ------------------------------------------------------------ strokes

    def stroke_handler(self, token: str, output: Output | None = None) -> StrokeHandler:
        """A handler for one page's pen WebSocket (:class:`.strokes.StrokeHandler`);
        drives go to ``output`` too when given."""
        handler = StrokeHandler(self, self.session_of(token), output)
        # Read now, while the socket opens, what the first pen message would
        # otherwise query on the drive's path: the trial plan and the open trial.
        handler.prefetch()
        return handler

    def open_trial(self, sess: ExperimentSession, fresh: bool = False, stale_ok: bool = False) -> int | None:
        """The index of the session's first trial without all its answers (None: done).

        Asked for every pen message, so it is kept in memory for
        :data:`OPEN_TRIAL_TTL_S` seconds (an answer through this flow updates it
        at once) and the drive back to the page never waits for a query.
        ``stale_ok``: an expired value is returned as it is (the pen socket
        refreshes it after answering, :meth:`open_trial_due`); a query is made
        only when nothing is known."""
        now = time.monotonic()
        hit = self._open_cache.get(sess.id)
        if fresh or hit is None or (not stale_ok and now - hit[1] > OPEN_TRIAL_TTL_S):
            hit = self._open_cache[sess.id] = (self._first_open(sess), now)
        return hit[0]

    def open_trial_known(self, sess: ExperimentSession) -> tuple[bool, int | None]:
        """``(known, index)``: whether :meth:`open_trial` has a value of ``sess`` in
        memory (expired or not, so ``stale_ok`` needs no query), and that value."""
        hit = self._open_cache.get(sess.id)
        return (False, None) if hit is None else (True, hit[0])

    def open_trial_due(self, sess: ExperimentSession) -> bool:
        """True when :meth:`open_trial`'s value of ``sess`` is older than :data:`OPEN_TRIAL_TTL_S`."""
        hit = self._open_cache.get(sess.id)
        return hit is None or time.monotonic() - hit[1] > OPEN_TRIAL_TTL_S
