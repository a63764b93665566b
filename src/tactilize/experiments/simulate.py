"""Synthetic participants, for piloting a protocol and for power analysis.

They go through the same flow object as people's HTTP and WebSocket routes
(:class:`~.flow.Flow` and its stroke handler, called directly, so that no HTTP
client is needed), so a simulation tests the state machine, the checks and the
store as well as the analysis.  Simulated participants are flagged and numbered
apart from real ones (see :meth:`.store.Store.create_session`).  Like a real session, a
simulation is resumable: participant *i* of seed *S* is ``SIM-S-i``; a rerun
resumes unfinished ones at their first unanswered trial and skips finished ones,
and since each participant's random stream depends only on ``(S, i)``, the rerun
gives the same ratings the interrupted run would have.

The rating model (stated here, recorded in the store's ``meta`` table):

1. Each participant has an *ideal profile*: the paper preset with its
   coefficients k1/k2 (frequency law), k3/k4 (width law) and k5 (speed slope)
   multiplied by independent log-normal factors, ``exp(N(0, IDEAL_SD))``.
2. The *mismatch* D of a condition is the mean, over the trial's images and
   the speeds 30, 60 and 120 mm/s, of ``|log2(f_cond / f_ideal)| +
   |log2(w_cond / w_ideal)|``: octaves of pulse frequency and width between
   what the condition renders and what this person would like.  The actuator's
   limits act first, so differences the hardware cannot render are not felt.
3. ``rating = clip(round(MU + b_participant + b_question - SLOPE * D + e), 1, 7)``
   with ``b_participant ~ N(0, BIAS_SD)`` (scale use), ``b_question ~ N(0,
   QUESTION_SD)`` per participant and question, and ``e ~ N(0, NOISE_SD)`` per
   answer.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any, Callable

import numpy as np

from ..errors import RequestError, TactilizeError
from ..mapping import Profile
from .design import Design
from .design_toml import load_design
from .flow import Flow
from .store import Store

__all__ = ["simulate", "RATING_MODEL", "ideal_profile", "mismatch"]

MU = 5.5
SLOPE = 2.0  # rating points per octave of mismatch
BIAS_SD = 0.5
QUESTION_SD = 0.3
NOISE_SD = 0.7
IDEAL_SD = 0.25
SPEEDS_M_S = (0.03, 0.06, 0.12)

RATING_MODEL = {
    "formula": "clip(round(mu + b_participant + b_question - slope * mismatch_octaves + noise), 1, 7)",
    "mu": MU, "slope_per_octave": SLOPE, "bias_sd": BIAS_SD, "question_sd": QUESTION_SD, "noise_sd": NOISE_SD,
    "ideal_profile": f"paper preset, k1/k2, k3/k4, k5 times exp(N(0, {IDEAL_SD}))",
    "speeds_m_s": list(SPEEDS_M_S),
}


def ideal_profile(rng: np.random.Generator, base=None):
    """One synthetic person's preferred profile (see the module docstring)."""
    base = base or Profile.preset("paper")

    def jitter(law, names):
        changes = {n: getattr(law, n) * float(np.exp(rng.normal(0, IDEAL_SD))) for n in names if hasattr(law, n)}
        return dataclasses.replace(law, **changes)

    return base.replace(
        frequency=jitter(base.frequency, ("k1", "k2")),
        width=jitter(base.width, ("k3", "k4")),
        speed=jitter(base.speed, ("slope_per_mm_s",)),
    )


def mismatch(profile, ideal, features: list[Any]) -> float:
    """Mean octave distance of frequency plus width between two profiles' drives."""
    total, n = 0.0, 0
    for feat in features:
        for v in SPEEDS_M_S:
            a, b = profile.drive(feat, v), ideal.drive(feat, v)
            if a.is_off or b.is_off:
                total += 0.0 if a.is_off == b.is_off else 3.0  # silence where vibration is expected
            else:
                total += abs(math.log2(a.pulse_frequency_hz / b.pulse_frequency_hz))
                total += abs(math.log2(a.pulse_width_s / b.pulse_width_s))
            n += 1
    return total / max(n, 1)


def simulate(protocol, participants: int, seed: int, db_url: str | None = None, *,
             max_trials: int | None = None, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run synthetic participants through the experiment server.

    Parameters
    ----------
    protocol : Protocol or str
    participants : int
        How many (participants ``SIM-<seed>-001`` .. ``-N``).
    seed : int
        Seeds every participant's random stream (with their index).
    db_url : str, optional
    max_trials : int, optional
        Stop after submitting this many trials in total (to pilot an
        interrupted run; a later call resumes).

    Returns
    -------
    dict
        Counts of started, resumed, skipped participants and submitted trials,
        the rating model and the seed.
    """
    if not isinstance(protocol, Design):
        protocol = load_design(protocol)
    if participants < 1:
        raise TactilizeError("--participants", "must be at least 1")
    if seed < 0:
        raise TactilizeError("--seed", "must be >= 0")
    # The flow object the HTTP and WebSocket routes call, driven directly: the same
    # state machine, checks and store, without an HTTP client (httpx is a test
    # extra, and `pip install tactilize[experiments]` must be enough to pilot).
    flow = Flow(protocol, Store(db_url))
    flow.store.set_meta(f"simulation:{protocol.name}:{seed}", json.dumps({"seed": seed, "model": RATING_MODEL}))
    counts = {"started": 0, "resumed": 0, "skipped": 0, "trials_submitted": 0}
    for i in range(1, participants + 1):
        code = f"SIM-{seed}-{i:03d}"
        rng = np.random.default_rng([seed, i])
        ideal = ideal_profile(rng)
        bias = rng.normal(0, BIAS_SD)
        qbias = {q.id: rng.normal(0, QUESTION_SD) for q in protocol.questions}
        try:
            state = flow.start(code, True, simulated=True)
            counts["started"] += 1
        except RequestError as exc:
            if exc.status != 409:
                raise
            if exc.detail.get("finished"):
                counts["skipped"] += 1
                continue
            state = flow.resume(code)
            counts["resumed"] += 1
        token = state["session"]
        if state["state"] == "calibration":
            state = flow.calibrate(token, {"mm_per_px": 0.2646, "felt": True})
        handler = flow.stroke_handler(token)
        while state["state"] != "done":
            if max_trials is not None and counts["trials_submitted"] >= max_trials:
                return _summary(counts, seed, protocol)
            if state["state"] == "break":
                state = flow.end_break(token, state["next_trial"])
                continue
            trial = state["trial"]
            idx = trial["index"]
            # Per-trial random streams: a resumed participant gets the same
            # numbers for a trial as an uninterrupted one would have.
            trng = np.random.default_rng([seed, i, idx])
            cond = flow.store.trials(flow.session_of(token).id)[idx].condition_id
            feats = [flow.image_features(im["id"]) for im in trial["images"]]
            for im in trial["images"]:
                v_mm_s = float(trng.uniform(30, 120))
                samples = [[k * 5.0, 5.0 + k * 5.0 * v_mm_s / 1e3, 20.0, 0.5] for k in range(12)]
                reply = handler.handle({"type": "samples", "trial": idx, "image": im["id"], "samples": samples})
                if reply.get("type") != "drive":
                    raise TactilizeError(code, f"stroke refused: {reply.get('error')}")
            handler.handle({"type": "lift"})
            # Drives, not law coefficients, are compared: a linear-g condition and the
            # person's ideal log-g profile meet in what is felt.
            d = mismatch(flow.profile(cond), ideal, feats)
            ratings = {}
            for q in trial["questions"]:
                x = MU + bias + qbias[q["id"]] - SLOPE * d + trng.normal(0, NOISE_SD)
                ratings[q["id"]] = int(min(q["scale_max"], max(q["scale_min"], round(x))))
            state = flow.submit(token, idx, ratings, response_time_s=float(trng.uniform(3, 20)),
                                submission_id=f"{code}:{idx}")
            counts["trials_submitted"] += 1
            if progress:
                progress(f"{code} trial {idx + 1}/{state['progress']['total']}")
    return _summary(counts, seed, protocol)


def _summary(counts, seed, protocol):
    return {"protocol": protocol.name, "protocol_sha256": protocol.sha256, "seed": seed, **counts,
            "rating_model": RATING_MODEL}
