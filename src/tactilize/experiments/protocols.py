"""Experiment protocols: the design of an experiment, as data.

A protocol is a TOML file (the built-ins live in ``experiments/protocols``)::

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
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from ..errors import TactilizeError, check_finite

__all__ = [
    "ProtocolError",
    "ImageSpec",
    "Condition",
    "Question",
    "Protocol",
    "TrialPlan",
    "balanced_latin_square",
    "williams_row",
    "load_protocol",
    "builtin_protocols",
    "builtin_names",
]

PROFILE_ROLES = ("frequency", "speed", "width", "amplitude", "direction", "regularity")
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$")


class ProtocolError(TactilizeError):
    """A protocol file (or name) is unknown, unreadable or invalid."""


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
class TrialPlan:
    """One planned trial of one participant (before anything is stored)."""

    index: int
    condition_id: str
    repetition: int
    image_ids: tuple[str, ...]


# --------------------------------------------------------------------------- protocol


@dataclass(frozen=True)
class Protocol:
    """An experiment's design.  Build with :func:`load_protocol`.

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
    calibration_card_mm: float = 85.60
    require_every_image: bool = False  # the rating opens only once every picture of the trial was stroked
    consent: str = ""  # the information a participant consents to (``consent`` or ``consent_file``)
    demographics: tuple = ()  # optional questions (:mod:`.demographics`)
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
        raise ProtocolError(self.name, f"no condition {cid!r}")

    def image(self, iid: str) -> ImageSpec:
        for im in self.images:
            if im.id == iid:
                return im
        raise ProtocolError(self.name, f"no image {iid!r}")

    def question(self, qid: str) -> Question:
        for q in self.questions:
            if q.id == qid:
                return q
        raise ProtocolError(self.name, f"no question {qid!r}")

    # -- profiles

    def profile(self, cid: str, base: Any = None):
        """The :class:`~tactilize.mapping.Profile` a condition drives with."""
        from ..mapping import Profile

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
            raise ProtocolError(self.name, "participant numbers start at 1")
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


# --------------------------------------------------------------------------- loading


def _num(source: str, where: str, value: Any, lo: float | None = None, hi: float | None = None) -> float:
    check_finite(value, source, what=where, error=ProtocolError)
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise ProtocolError(source, f"{where} must be in [{lo}, {hi}], got {value!r}")
    return float(value)


def _int(source: str, where: str, value: Any, lo: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise ProtocolError(source, f"{where} must be an integer >= {lo}, got {value!r}")
    return value


def _demographics(source: str, items: Any) -> tuple:
    from .demographics import parse_demographics

    return parse_demographics(source, items)


def _consent(source: str, data: dict) -> str:
    """The consent text: inline ``consent``, or ``consent_file`` next to the protocol file."""
    if "consent" in data and "consent_file" in data:
        raise ProtocolError(source, "give consent or consent_file, not both")
    if "consent_file" in data:
        name = data["consent_file"]
        if not isinstance(name, str) or not name or not source.endswith(".toml"):
            raise ProtocolError(source, "consent_file must name a file next to a protocol file")
        path = Path(source).parent / name
        try:
            return path.read_text("utf-8").strip()
        except (OSError, UnicodeDecodeError) as exc:
            raise ProtocolError(str(path), f"cannot read the consent file ({exc.__class__.__name__})") from None
    text = data.get("consent", "")
    if not isinstance(text, str):
        raise ProtocolError(source, "consent must be text")
    return text.strip()


def _bool(source: str, where: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ProtocolError(source, f"{where} must be true or false, got {value!r}")
    return value


def _id(source: str, where: str, value: Any) -> str:
    if not isinstance(value, str) or not _ID.match(value):
        raise ProtocolError(source, f"{where} must be a short id (letters, digits, _ . -), got {value!r}")
    return value


def protocol_from_toml(text: str, source: str = "<toml>") -> Protocol:
    """Parse and validate a protocol from TOML text."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProtocolError(source, f"invalid TOML ({exc})") from None
    known = {
        "name", "version", "title", "description", "reference", "base_profile", "repetitions",
        "trial_unit", "break_every", "min_stroke_s", "participants_planned", "order", "images",
        "conditions", "questions", "calibration", "require_every_image", "consent", "consent_file",
        "demographics", "practice_trials",
    }
    unknown = set(data) - known
    if unknown:
        raise ProtocolError(source, f"unknown key(s) {', '.join(sorted(unknown))}")
    name = _id(source, "name", data.get("name"))
    for section in ("images", "conditions", "questions"):
        if not isinstance(data.get(section), list) or not data[section]:
            raise ProtocolError(source, f"needs at least one [[{section}]]")

    images = []
    for i, im in enumerate(data["images"]):
        where = f"images[{i}]"
        extra = set(im) - {"id", "label", "texture", "spatial_frequency_per_m", "spectral_intensity",
                           "orientation_deg", "anisotropy", "path", "source"}
        if extra:
            raise ProtocolError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        texture = im.get("texture", "grating")
        if texture not in ("grating", "weave", "dots", "noise"):
            raise ProtocolError(source, f"{where}.texture must be grating, weave, dots or noise")
        images.append(
            ImageSpec(
                id=_id(source, f"{where}.id", im.get("id")),
                label=str(im.get("label", im.get("id"))),
                texture=texture,
                spatial_frequency_per_m=_num(source, f"{where}.spatial_frequency_per_m",
                                             im.get("spatial_frequency_per_m", 500.0), 1e-6, 1e6),
                spectral_intensity=_num(source, f"{where}.spectral_intensity", im.get("spectral_intensity", 0.8), 0, 1),
                orientation_deg=_num(source, f"{where}.orientation_deg", im.get("orientation_deg", 0.0)),
                anisotropy=_num(source, f"{where}.anisotropy", im.get("anisotropy", 1.0), 0, 1),
                path=str(im["path"]) if "path" in im else None,
                source=str(im.get("source", "")),
            )
        )

    conditions = []
    for i, c in enumerate(data["conditions"]):
        where = f"conditions[{i}]"
        extra = set(c) - {"id", "label", *PROFILE_ROLES}
        if extra:
            raise ProtocolError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        overrides = {role: dict(c[role]) for role in PROFILE_ROLES if role in c}
        conditions.append(Condition(_id(source, f"{where}.id", c.get("id")), str(c.get("label", c.get("id"))), overrides))

    questions = []
    for i, q in enumerate(data["questions"]):
        where = f"questions[{i}]"
        extra = set(q) - {"id", "text", "scale_min", "scale_max", "anchors"}
        if extra:
            raise ProtocolError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        lo = _int(source, f"{where}.scale_min", q.get("scale_min", 1), 0)
        hi = _int(source, f"{where}.scale_max", q.get("scale_max", 7), lo + 1)
        anchors = {}
        for k, v in dict(q.get("anchors", {})).items():
            try:
                kk = int(k)
            except ValueError:
                raise ProtocolError(source, f"{where}.anchors keys must be scale points, got {k!r}") from None
            if not lo <= kk <= hi:
                raise ProtocolError(source, f"{where}.anchors key {kk} is outside {lo}..{hi}")
            anchors[kk] = str(v)
        if not isinstance(q.get("text"), str) or not q["text"].strip():
            raise ProtocolError(source, f"{where}.text is missing")
        questions.append(Question(_id(source, f"{where}.id", q.get("id")), q["text"].strip(), lo, hi, anchors))

    for label, items in (("image", images), ("condition", conditions), ("question", questions)):
        ids = [x.id for x in items]
        if len(set(ids)) != len(ids):
            raise ProtocolError(source, f"{label} ids must be unique")

    order = dict(data.get("order", {}))
    extra = set(order) - {"method", "seed", "shuffle_images"}
    if extra:
        raise ProtocolError(source, f"[order]: unknown key(s) {', '.join(sorted(extra))}")
    method = order.get("method", "williams")
    if method not in ("williams", "random", "fixed"):
        raise ProtocolError(source, "[order].method must be williams, random or fixed")
    trial_unit = data.get("trial_unit", "condition")
    if trial_unit not in ("condition", "condition_image"):
        raise ProtocolError(source, "trial_unit must be condition or condition_image")
    calib = dict(data.get("calibration", {}))

    proto = Protocol(
        name=name,
        version=str(data.get("version", "1")),
        title=str(data.get("title", name)),
        description=str(data.get("description", "")).strip(),
        reference=str(data.get("reference", "")),
        base_profile=str(data.get("base_profile", "paper")),
        images=tuple(images),
        conditions=tuple(conditions),
        questions=tuple(questions),
        repetitions=_int(source, "repetitions", data.get("repetitions", 1), 1),
        trial_unit=trial_unit,
        break_every=_int(source, "break_every", data.get("break_every", 0), 0),
        min_stroke_s=_num(source, "min_stroke_s", data.get("min_stroke_s", 0.0), 0, 3600),
        order_method=method,
        seed=_int(source, "[order].seed", order.get("seed", 0), 0),
        shuffle_images=bool(order.get("shuffle_images", True)),
        participants_planned=_int(source, "participants_planned", data.get("participants_planned", 0), 0),
        calibration_card_mm=_num(source, "[calibration].card_width_mm", calib.get("card_width_mm", 85.60), 10, 500),
        require_every_image=_bool(source, "require_every_image", data.get("require_every_image", False)),
        consent=_consent(source, data),
        demographics=_demographics(source, data.get("demographics")),
        practice_trials=_int(source, "practice_trials", data.get("practice_trials", 0), 0),
        text=text,
        source=source,
    )
    # Fail now, not in front of a participant: every condition must make a valid profile
    # that the wire follows.
    from ..errors import ProfileError
    from .checks import check_condition

    for c in proto.conditions:
        try:
            proto.profile(c.id)
        except ProfileError as exc:
            raise ProtocolError(source, f"condition {c.id}: {exc.fault}") from None
        check_condition(proto, c, source)
    return proto


def builtin_names() -> list[str]:
    """Names of the protocols shipped with tactilize."""
    root = resources.files("tactilize.experiments").joinpath("protocols")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def builtin_protocols() -> list[Protocol]:
    """The four built-in protocols that mirror the paper (g-law, h-law, alpha-law, assessment)."""
    return [load_protocol(n) for n in builtin_names()]


def load_protocol(name_or_path: str | Path) -> Protocol:
    """A built-in protocol by name, or a protocol TOML file by path."""
    text_name = str(name_or_path)
    if text_name in builtin_names():
        text = resources.files("tactilize.experiments").joinpath("protocols", f"{text_name}.toml").read_text("utf-8")
        return protocol_from_toml(text, source=f"protocol {text_name}")
    p = Path(text_name)
    if not p.exists():
        raise ProtocolError(text_name, f"neither a built-in protocol ({', '.join(builtin_names())}) nor a file")
    try:
        text = p.read_text("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ProtocolError(text_name, f"cannot read ({exc.__class__.__name__})") from None
    return protocol_from_toml(text, source=str(p))
