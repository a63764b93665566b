"""An experiment's design, as data: images, conditions, questions, demographic items, the order.

A design is written as a protocol file, TOML (read by :mod:`.design_toml`) (the built-ins live in ``experiments/protocols``)::

    name = "g-law"
    version = "1"
    base_profile = "paper"        # every condition is a variation of this profile
    repetitions = 1
    trial_unit = "condition"      # or "condition_image": one trial per image
    break_every = 5               # a break screen every 5 trials (0: none)
    min_stroke_s = 5.0            # stroking time before the answer form opens [s]

    [order]
    method = "williams"           # balanced Latin square by participant number
    seed = 1001                   # maps square symbols to conditions, shuffles images

    [[images]]                    # a stand-in texture with the paper's features,
    id = "image1"                 # or ``path = "cloth.png"`` for a real picture
    texture = "grating"
    spatial_frequency_per_m = 799.0
    spectral_intensity = 0.874

    [[conditions]]
    id = "I"
    label = "log, k2 = 40"
    frequency = { law = "log", k2 = 40.0 }   # replaces the base profile's [frequency]

    [[questions]]
    id = "match"
    text = "How well did the touch match the pictures?"
    anchors = { 1 = "not at all", 4 = "somewhat", 7 = "perfectly" }

The order is a Williams design (a Latin square balanced for first-order
carry-over): participant *p* (numbered from 1 in the order they register) gets
row *p - 1* of the square; for an odd number of conditions the square is doubled
with its mirror image.  The protocol's seed fixes which condition is which
symbol of the square and how images are shuffled within a trial, so the order of
every participant can be recomputed from the protocol and their number alone;
the store records it anyway.
"""

from __future__ import annotations

import hashlib
import random
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..mapping import Profile
from ..pen.display import CARD_MM
from .errors import DesignError

__all__ = [
    "PROFILE_ROLES",
    "ImageSpec",
    "Condition",
    "Question",
    "DemographicItem",
    "Design",
    "TrialPlan",
    "balanced_latin_square",
    "williams_row",
]

#: The profile tables a condition may replace.
PROFILE_ROLES = ("frequency", "speed", "width", "amplitude", "direction", "regularity")


# --------------------------------------------------------------------------- order


def williams_row(n: int, row: int) -> list[int]:
    """One row of a Williams (carry-over balanced Latin) square.

    Parameters
    ----------
    n : int
        Number of conditions (>= 1).
    row : int
        Row index, >= 0; taken modulo the square's height (``n`` when ``n`` is
        even, ``2 n`` when odd, the second half being the mirror images).

    Returns
    -------
    list of int
        A permutation of ``range(n)``.
    """
    if n < 1:
        raise ValueError("n must be >= 1")
    height = n if n % 2 == 0 else 2 * n
    r = row % height
    # 0, 1, n-1, 2, n-2, ...: consecutive differences take every value once,
    # which is what balances first-order carry-over.
    base = [0]
    for j in range(1, n):
        base.append((j + 1) // 2 if j % 2 == 1 else n - j // 2)
    seq = [(b + r) % n for b in base]
    if n % 2 == 1 and r >= n:
        seq = [(b + r - n) % n for b in base][::-1]
    return seq


def balanced_latin_square(n: int) -> list[list[int]]:
    """The full Williams square: ``n`` rows for even ``n``, ``2 n`` for odd ``n``."""
    height = n if n % 2 == 0 else 2 * n
    return [williams_row(n, r) for r in range(height)]


# --------------------------------------------------------------------------- parts


@dataclass(frozen=True)
class ImageSpec:
    """One image shown in a trial.

    Either a stand-in texture rendered from the stated features (``texture`` is
    ``grating``, ``weave``, ``dots`` or ``noise``) or a real picture (``path``,
    relative to the protocol file), whose features are then measured.

    Parameters
    ----------
    id, label : str
    texture : str
    spatial_frequency_per_m : float
        Dominant spatial frequency [cycles/m] that drives the condition's g law.
    spectral_intensity : float
        In [0, 1], drives the h law.
    orientation_deg : float
        Wave-vector direction [deg].
    path : str, optional
    source : str
        Where the numbers come from (e.g. "paper Table 1").
    """

    id: str
    label: str
    texture: str = "grating"
    spatial_frequency_per_m: float = 500.0
    spectral_intensity: float = 0.8
    orientation_deg: float = 0.0
    anisotropy: float = 1.0
    path: str | None = None
    source: str = ""

    def to_dict(self) -> dict[str, Any]:
        d = {k: v for k, v in self.__dict__.items() if v is not None}
        return d


@dataclass(frozen=True)
class Condition:
    """One condition: the base profile with some law tables replaced."""

    id: str
    label: str
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"id": self.id, "label": self.label, **self.overrides}


@dataclass(frozen=True)
class Question:
    """A rating item on an integer scale (1..7 in the paper) with anchor texts."""

    id: str
    text: str
    scale_min: int = 1
    scale_max: int = 7
    anchors: dict[int, str] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "text": self.text,
            "scale_min": self.scale_min,
            "scale_max": self.scale_max,
            "anchors": {str(k): v for k, v in sorted(self.anchors.items())},
        }


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
        d: dict[str, Any] = {"id": self.id, "text": self.text, "kind": self.kind}
        d.update({"min": self.minimum, "max": self.maximum} if self.kind == "integer" else {"options": list(self.options)})
        return d


@dataclass(frozen=True)
class TrialPlan:
    """One planned trial of one participant (before anything is stored)."""

    index: int
    condition_id: str
    repetition: int
    image_ids: tuple[str, ...]


# --------------------------------------------------------------------------- protocol


@dataclass(frozen=True)
class Design:
    """An experiment's design.  Build with :func:`.design_toml.load_design`.

    Attributes
    ----------
    text : str
        The TOML text it was read from; its SHA-256 identifies the version in the
        store, so a changed protocol is never confused with an earlier one.
    """

    name: str
    version: str
    title: str
    description: str
    reference: str
    base_profile: str
    images: tuple[ImageSpec, ...]
    conditions: tuple[Condition, ...]
    questions: tuple[Question, ...]
    repetitions: int = 1
    trial_unit: str = "condition"
    break_every: int = 0
    min_stroke_s: float = 0.0
    order_method: str = "williams"
    seed: int = 0
    shuffle_images: bool = True
    participants_planned: int = 0
    calibration_card_mm: float = CARD_MM[0]
    require_every_image: bool = False  # the rating opens only once every picture of the trial was stroked
    consent: str = ""  # the information a participant consents to (``consent`` or ``consent_file``)
    demographics: tuple[DemographicItem, ...] = ()  # optional questions a participant may decline
    practice_trials: int = 0  # trials first, with repetition -1, left out of the analysis
    text: str = ""
    source: str = "<protocol>"

    # -- identity

    @property
    def sha256(self) -> str:
        """SHA-256 of the protocol text (the version's identity in the store)."""
        return hashlib.sha256(self.text.encode("utf-8")).hexdigest()

    def condition(self, cid: str) -> Condition:
        for c in self.conditions:
            if c.id == cid:
                return c
        raise DesignError(self.name, f"no condition {cid!r}")

    def image(self, iid: str) -> ImageSpec:
        for im in self.images:
            if im.id == iid:
                return im
        raise DesignError(self.name, f"no image {iid!r}")

    def question(self, qid: str) -> Question:
        for q in self.questions:
            if q.id == qid:
                return q
        raise DesignError(self.name, f"no question {qid!r}")

    # -- profiles

    def profile(self, cid: str, base: Any = None):
        """The :class:`~tactilize.mapping.Profile` a condition drives with."""
        cond = self.condition(cid)
        base = base or Profile.resolve(self._base_profile_path())
        data = base.to_dict()
        for role, table in cond.overrides.items():
            data[role] = dict(table)
        data["name"] = f"{self.name}:{cid}"
        data["description"] = f"protocol {self.name} v{self.version}, condition {cid}: {cond.label}"
        return Profile.from_dict(data, source=f"{self.source} condition {cid}")

    def _base_profile_path(self) -> str:
        bp = self.base_profile
        if bp.endswith(".toml") and not Path(bp).is_absolute() and self.source.endswith(".toml"):
            cand = Path(self.source).parent / bp
            if cand.exists():
                return str(cand)
        return bp

    # -- order

    def condition_order(self, participant_number: int, repetition: int = 0) -> list[str]:
        """Condition ids in the order participant ``participant_number`` (>= 1) meets them.

        Participant *p* gets row *p - 1* of the square (repetition *r* uses row
        *p - 1 + r*, so a repeated block is not a copy of the first).  The
        protocol's seed maps square symbols to conditions, fixed per protocol,
        so the balance of the square carries over unchanged.
        """
        if participant_number < 1:
            raise DesignError(self.name, "participant numbers start at 1")
        ids = [c.id for c in self.conditions]
        if self.order_method == "fixed":
            return ids
        if self.order_method == "random":
            row = list(range(len(ids)))
            random.Random(f"{self.seed}:p{participant_number}:r{repetition}").shuffle(row)
            return [ids[s] for s in row]
        symbols = list(range(len(ids)))
        random.Random(f"{self.seed}:symbols").shuffle(symbols)
        row = williams_row(len(ids), participant_number - 1 + repetition)
        return [ids[symbols[s]] for s in row]

    def plan(self, participant_number: int) -> list[TrialPlan]:
        """Every trial of one participant, in order."""
        trials: list[TrialPlan] = []
        image_ids = [im.id for im in self.images]
        first = self.condition_order(participant_number, 0)
        for k in range(self.practice_trials):  # familiarisation: repetition -1, never analysed
            trials.append(TrialPlan(len(trials), first[k % len(first)], -1, tuple(image_ids)))
        for rep in range(self.repetitions):
            for cid in self.condition_order(participant_number, rep):
                imgs = list(image_ids)
                if self.shuffle_images:
                    random.Random(f"{self.seed}:p{participant_number}:r{rep}:{cid}").shuffle(imgs)
                if self.trial_unit == "condition_image":
                    for iid in imgs:
                        trials.append(TrialPlan(len(trials), cid, rep, (iid,)))
                else:
                    trials.append(TrialPlan(len(trials), cid, rep, tuple(imgs)))
        return trials

    # -- reporting

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary (with the version hash for provenance)."""
        return {
            "name": self.name,
            "version": self.version,
            "sha256": self.sha256,
            "title": self.title,
            "description": self.description,
            "reference": self.reference,
            "base_profile": self.base_profile,
            "repetitions": self.repetitions,
            "trial_unit": self.trial_unit,
            "break_every": self.break_every,
            "min_stroke_s": self.min_stroke_s,
            "order": {"method": self.order_method, "seed": self.seed, "shuffle_images": self.shuffle_images},
            "participants_planned": self.participants_planned,
            "trials_per_participant": len(self.plan(1)),
            "images": [im.to_dict() for im in self.images],
            "conditions": [c.to_dict() for c in self.conditions],
            "questions": [q.to_dict() for q in self.questions],
        }
