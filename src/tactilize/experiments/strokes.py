"""The experiment's pen messages: samples in, drives out at once, acknowledgements after the commit.

:class:`StrokeHandler` handles one page's messages (the socket that carries
them is :mod:`.pen_socket`).

Messages from the page (JSON); the samples are the pen socket's one sample
message (:func:`tactilize.web.rows.pen_batch`, the pen page's too), with the
trial and image the samples were taken in::

    {"type": "samples", "batch": "<page id>-17", "samples": [[t_ms, x_mm, y_mm, pressure?, tilt_x_deg?, tilt_y_deg?], ...],
     "trial": 3, "image": "image2"}
    {"type": "lift"}
    {"type": "reconnected", "trial": 3, "gap_s": 2.5, "queued": 120}
    {"type": "ping"}

Answers::

    {"type": "drive", "trial", "image", "batch", "speed_mm_s", "logged", "drive"}   at once
    {"type": "ack", "batch", "trial", "stored": "stored" | "duplicate"}            after the commit
    {"type": "error", "error", "source", "status", "batch"?, "retry"?}
    {"type": "marked", ...}, {"type": "lifted"}, {"type": "pong"}

The page keeps every batch until its ``ack`` and resends the ones not yet
acknowledged after a reconnect (and any left unacknowledged for a few
seconds); the batch id makes the resend harmless (:mod:`.samples`).  A batch
is stored under the trial and image the page stamped it with when the samples
were taken, also when it arrives after that trial was answered (the participant
may press Save while the last samples are on their way); only a trial the
session has not reached yet is refused.  The drive answers only batches of the
open trial: a late batch is logged, not felt.
"""

from __future__ import annotations

import math
import time
import uuid
from concurrent.futures import Future
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Callable

from ..actuators.base import Output
from ..drive import Drive
from ..surface.rendering import Rendering
from ..web.rows import PenMessageError, pen_batch
from .errors import FlowError
from .feel import TrialPen
from .labdata import record_event
from .samples import writer_for
from .tables import ExperimentSession

__all__ = ["StrokeHandler"]


@dataclass
class StrokeHandler:
    """Turns pen samples of one session into drives, and logs both.

    Positions are millimetres on the displayed image (the page converts CSS
    pixels with the calibrated scale, :mod:`tactilize.pen.display`).  Each
    trial is rendered by ``tactilize serve``'s :class:`~tactilize.pen.PenRenderer`
    with its condition's profile (:class:`.feel.TrialPen`), one stroke per
    trial and image, so switching pictures starts a new stroke and a late
    batch does not disturb the stroke of the open trial.

    When the app has an actuator output (``tactilize serve``'s), the drives go
    to it as the pen page sends them: split over the pen's channels, resting in
    standby on a lift, an error or the end of the connection.
    """

    flow: Any
    session: ExperimentSession
    output: Output | None = None
    clock: Callable[[], float] = time.monotonic
    trial_cache: dict[int, Any] = field(default_factory=dict)
    pen: TrialPen = field(init=False)

    def __post_init__(self) -> None:
        self.pen = TrialPen(self.output, self._now)

    def _now(self) -> float:
        return self.clock()

    def stop(self) -> None:
        """Every stroke ends; the output rests (standby), as on the pen page."""
        self.pen.lift()

    def _trials(self) -> dict[int, Any]:
        if not self.trial_cache:  # the plan never changes once the session exists
            self.trial_cache = {t.index: t for t in self.flow.store.trials(self.session.id)}
        return self.trial_cache

    def _reconnected(self, msg: dict) -> dict[str, Any]:
        """The page lost its socket during trial ``msg["trial"]`` and is back: mark
        the trial interrupted (once per reconnection), whatever samples follow."""
        idx = msg.get("trial")
        trials = self._trials()
        if isinstance(idx, bool) or not isinstance(idx, int) or idx not in trials:
            raise FlowError("stroke", "unknown trial", 422)
        gap = msg.get("gap_s")
        gap = float(gap) if isinstance(gap, (int, float)) and not isinstance(gap, bool) and math.isfinite(gap) else None
        record_event(self.flow.store, trials[idx].id, "interrupted",
                     {"gap_s": gap, "queued_samples": msg.get("queued") if isinstance(msg.get("queued"), int) else None})
        return {"type": "marked", "trial": idx, "kind": "interrupted"}

    def prefetch(self) -> None:
        """Read the trial plan and the open trial (when not in memory) before the first message."""
        self._trials()
        self.flow.open_trial(self.session, stale_ok=True)

    def needs_store(self, msg: Any) -> bool:
        """True when :meth:`take` may query or write the store for ``msg``.

        The first message (the trial plan and the open trial are read once), a
        reconnection mark (written), and a batch for a trial past the open one
        (re-read) do; every other batch is answered from memory."""
        if not isinstance(msg, dict):
            return False
        if msg.get("type") == "reconnected" or not self.trial_cache:
            return True
        if msg.get("type") in ("lift", "ping"):
            return False
        known, current = self.flow.open_trial_known(self.session)
        idx = msg.get("trial")
        return not known or (isinstance(idx, int) and current is not None and idx > current)

    def take(self, msg: Any) -> tuple[dict[str, Any] | None, Future | None]:
        """Handle one message without waiting for the database.

        Returns the answer to send now (None for a late batch) and, for a batch
        of samples, the future of its write (see :meth:`.SampleWriter.submit`).
        Raises :class:`~.flow.FlowError` for a message refused as a whole.
        """
        if not isinstance(msg, dict):
            raise FlowError("stroke", "expected a JSON object", 422)
        kind = msg.get("type")
        if kind == "lift":
            self.stop()
            return {"type": "lifted"}, None
        if kind == "reconnected":
            return self._reconnected(msg), None
        if kind == "ping":
            return {"type": "pong"}, None
        if kind != "samples":
            raise FlowError("stroke", f"unknown message type {kind!r} (known: samples, lift, reconnected, ping)", 422)
        try:
            batch_given, batch_samples = pen_batch(msg)
        except PenMessageError as exc:
            raise FlowError("stroke", str(exc), 422) from None
        if not batch_samples:
            raise FlowError("stroke", "a batch carries at least one sample", 422)
        # A client without ids: stored, but a resend would be stored again.
        batch = batch_given or "server-" + uuid.uuid4().hex
        idx = msg.get("trial")
        image_id = msg.get("image")
        trials = self._trials()
        if isinstance(idx, bool) or not isinstance(idx, int) or idx not in trials:
            raise FlowError("stroke", "unknown trial", 422)
        trial = trials[idx]
        if not isinstance(image_id, str) or image_id not in trial.image_ids:
            raise FlowError("stroke", f"image {image_id!r} is not part of trial {idx + 1}", 422)
        # An expired value is used once more rather than querying on the drive's
        # path; pump() refreshes it right after the reply (refresh_open_trial).
        current = self.flow.open_trial(self.session, stale_ok=True)
        if current is not None and idx > current:
            current = self.flow.open_trial(self.session, fresh=True)
            if current is not None and idx > current:
                raise FlowError("stroke", f"trial {idx + 1} is not open yet (a stale page?)", 409, current_trial=current)
        profile = self.flow.profile(trial.condition_id)
        feats = self.flow.image_features(image_id)
        if len(self.pen.renderers) > 16:  # strokes of trials long answered
            self.pen.keep(lambda k: current is None or k[0] >= current - 1)
        key = (idx, image_id)
        # The picture's surface (made once per picture): the profile's rendering reads it or not.
        surface = self.flow.image_surface(image_id)
        if idx != current:  # logged under its own trial, not felt: the page has moved on
            taken = self.pen.track(key, feats, profile, batch_samples, surface)
            rows = partial(_logged_rows, self.pen.renderers[key].rendering, feats, image_id, taken, None)
            return None, writer_for(self.flow.store).submit(self.session.id, trial.id, batch, rows)
        taken, drive, result = self.pen.feel(key, feats, profile, surface, batch_samples)
        # The stroke's state after each sample is logged with it; the drive the
        # batch's frame rendered is computed here (the page feels one drive per
        # message), the drives the rendering gives the other samples by the
        # writer's thread (:func:`_logged_rows`), off the socket's path.
        rows = partial(_logged_rows, self.pen.renderers[key].rendering, feats, image_id, taken, drive)
        future = writer_for(self.flow.store).submit(self.session.id, trial.id, batch, rows)
        if drive is None:
            drive = Drive.off()
        return {"type": "drive", "trial": idx, "image": image_id, "batch": batch,
                "speed_mm_s": (taken[-1][1] if taken else 0.0) * 1e3, "logged": len(taken),
                "drive": drive.to_dict(), "pulses": result.pulses}, future

    def refresh_open_trial(self) -> None:
        """Re-read the open trial if its remembered value expired (after a reply, off the drive's path)."""
        if self.flow.open_trial_due(self.session):
            self.flow.open_trial(self.session, fresh=True)

    def handle(self, msg: Any, timeout_s: float = 60.0) -> dict[str, Any]:
        """Handle one message and wait for its samples' commit (synthetic participants, tests).

        The answer is :meth:`take`'s, with ``stored`` (``"stored"`` or
        ``"duplicate"``) for a batch; a late batch answers ``{"type": "logged"}``.
        """
        reply, future = self.take(msg)
        self.refresh_open_trial()
        if future is None:
            assert reply is not None, "take answers every message it writes nothing for"
            return reply
        status = future.result(timeout=timeout_s)
        reply = reply or {"type": "logged", "trial": msg.get("trial"), "image": msg.get("image")}
        return {**reply, "stored": status}


def _logged_rows(rendering: Rendering, feats, image_id: str, taken: list, frame_drive: Drive | None) -> list[dict[str, Any]]:
    """The stroke log's rows of one batch: each sample with its speed and the drive rendered for it.

    Runs in the writer's thread (:meth:`.SampleWriter.submit` takes a callable),
    off the socket's path.  ``taken`` holds ``(sample, speed_m_s, direction_rad)``
    per sample; ``frame_drive`` is the drive the batch's frame rendered (the
    reply's; None: the batch was not rendered).  The rendering gives each
    sample's (:meth:`~tactilize.surface.rendering.Rendering.sample_drives`): a
    steady one its law at that sample, by the call the frame's was made with,
    so the log holds what answering every sample would have given, exactly; the
    surface one the frame's, its operating point over the batch.
    """
    rows = []
    states = [(speed, direction, ps.pressure) for ps, speed, direction in taken]
    drives = rendering.sample_drives(feats, states, frame_drive)
    for (ps, speed, direction), drive in zip(taken, drives):
        rows.append({"image_id": image_id, "t_s": ps.t_s, "x_m": ps.x_m, "y_m": ps.y_m, "pressure": ps.pressure,
                     "speed_m_s": speed, "pulse_frequency_hz": drive.pulse_frequency_hz,
                     "pulse_width_s": drive.pulse_width_s, "amplitude": drive.amplitude})
    return rows
