"""Reading a design from a protocol file (TOML): plain validation, one line per fault.

Every key is checked against the keys the design knows, every number against
its range, and every condition is tried on the simulated wire before a
participant meets it (:mod:`.checks`).  The built-in protocol files live in
``experiments/protocols``; ``tactilize experiment protocols`` lists them.
"""

from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from ..errors import ProfileError, check_finite
from ..pen.display import CARD_MM
from .checks import check_condition
from .design import (
    PROFILE_ROLES,
    Condition,
    DemographicItem,
    Design,
    ImageSpec,
    Question,
)
from .errors import DesignError

__all__ = [
    "design_from_toml",
    "load_design",
    "builtin_designs",
    "builtin_names",
    "parse_demographics",
    "load_protocol",
    "builtin_protocols",
    "protocol_from_toml",
]

_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$")


def _num(source: str, where: str, value: Any, lo: float | None = None, hi: float | None = None) -> float:
    check_finite(value, source, what=where, error=DesignError)
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise DesignError(source, f"{where} must be in [{lo}, {hi}], got {value!r}")
    return float(value)


def _int(source: str, where: str, value: Any, lo: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise DesignError(source, f"{where} must be an integer >= {lo}, got {value!r}")
    return value


def _consent(source: str, data: dict) -> str:
    """The consent text: inline ``consent``, or ``consent_file`` next to the protocol file."""
    if "consent" in data and "consent_file" in data:
        raise DesignError(source, "give consent or consent_file, not both")
    if "consent_file" in data:
        name = data["consent_file"]
        if not isinstance(name, str) or not name or not source.endswith(".toml"):
            raise DesignError(source, "consent_file must name a file next to a protocol file")
        path = Path(source).parent / name
        try:
            return path.read_text("utf-8").strip()
        except (OSError, UnicodeDecodeError) as exc:
            raise DesignError(str(path), f"cannot read the consent file ({exc.__class__.__name__})") from None
    text = data.get("consent", "")
    if not isinstance(text, str):
        raise DesignError(source, "consent must be text")
    return text.strip()


def _bool(source: str, where: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise DesignError(source, f"{where} must be true or false, got {value!r}")
    return value


def _id(source: str, where: str, value: Any) -> str:
    if not isinstance(value, str) or not _ID.match(value):
        raise DesignError(source, f"{where} must be a short id (letters, digits, _ . -), got {value!r}")
    return value


def design_from_toml(text: str, source: str = "<toml>") -> Design:
    """Read and validate a design from a protocol file's TOML text.

    Raises
    ------
    DesignError
        Invalid TOML, an unknown key, a value out of range, or a condition the
        wire would not follow (:func:`.checks.check_condition`).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DesignError(source, f"invalid TOML ({exc})") from None
    known = {
        "name", "version", "title", "description", "reference", "base_profile", "repetitions",
        "trial_unit", "break_every", "min_stroke_s", "participants_planned", "order", "images",
        "conditions", "questions", "calibration", "require_every_image", "consent", "consent_file",
        "demographics", "practice_trials",
    }
    unknown = set(data) - known
    if unknown:
        raise DesignError(source, f"unknown key(s) {', '.join(sorted(unknown))}")
    name = _id(source, "name", data.get("name"))
    for section in ("images", "conditions", "questions"):
        if not isinstance(data.get(section), list) or not data[section]:
            raise DesignError(source, f"needs at least one [[{section}]]")

    images = []
    for i, im in enumerate(data["images"]):
        where = f"images[{i}]"
        extra = set(im) - {"id", "label", "texture", "spatial_frequency_per_m", "spectral_intensity",
                           "orientation_deg", "anisotropy", "path", "source"}
        if extra:
            raise DesignError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        texture = im.get("texture", "grating")
        if texture not in ("grating", "weave", "dots", "noise"):
            raise DesignError(source, f"{where}.texture must be grating, weave, dots or noise")
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
            raise DesignError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        overrides = {role: dict(c[role]) for role in PROFILE_ROLES if role in c}
        conditions.append(Condition(_id(source, f"{where}.id", c.get("id")), str(c.get("label", c.get("id"))), overrides))

    questions = []
    for i, q in enumerate(data["questions"]):
        where = f"questions[{i}]"
        extra = set(q) - {"id", "text", "scale_min", "scale_max", "anchors"}
        if extra:
            raise DesignError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        lo = _int(source, f"{where}.scale_min", q.get("scale_min", 1), 0)
        hi = _int(source, f"{where}.scale_max", q.get("scale_max", 7), lo + 1)
        anchors = {}
        for k, v in dict(q.get("anchors", {})).items():
            try:
                kk = int(k)
            except ValueError:
                raise DesignError(source, f"{where}.anchors keys must be scale points, got {k!r}") from None
            if not lo <= kk <= hi:
                raise DesignError(source, f"{where}.anchors key {kk} is outside {lo}..{hi}")
            anchors[kk] = str(v)
        if not isinstance(q.get("text"), str) or not q["text"].strip():
            raise DesignError(source, f"{where}.text is missing")
        questions.append(Question(_id(source, f"{where}.id", q.get("id")), q["text"].strip(), lo, hi, anchors))

    for label, items in (("image", images), ("condition", conditions), ("question", questions)):
        ids = [x.id for x in items]
        if len(set(ids)) != len(ids):
            raise DesignError(source, f"{label} ids must be unique")

    order = dict(data.get("order", {}))
    extra = set(order) - {"method", "seed", "shuffle_images"}
    if extra:
        raise DesignError(source, f"[order]: unknown key(s) {', '.join(sorted(extra))}")
    method = order.get("method", "williams")
    if method not in ("williams", "random", "fixed"):
        raise DesignError(source, "[order].method must be williams, random or fixed")
    trial_unit = data.get("trial_unit", "condition")
    if trial_unit not in ("condition", "condition_image"):
        raise DesignError(source, "trial_unit must be condition or condition_image")
    calib = dict(data.get("calibration", {}))

    proto = Design(
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
        calibration_card_mm=_num(source, "[calibration].card_width_mm", calib.get("card_width_mm", CARD_MM[0]), 10, 500),
        require_every_image=_bool(source, "require_every_image", data.get("require_every_image", False)),
        consent=_consent(source, data),
        demographics=parse_demographics(source, data.get("demographics")),
        practice_trials=_int(source, "practice_trials", data.get("practice_trials", 0), 0),
        text=text,
        source=source,
    )
    # Fail now, not in front of a participant: every condition must make a valid profile
    # that the wire follows.
    for c in proto.conditions:
        try:
            proto.profile(c.id)
        except ProfileError as exc:
            raise DesignError(source, f"condition {c.id}: {exc.fault}") from None
        check_condition(proto, c, source)
    return proto


def parse_demographics(source: str, items: Any) -> tuple[DemographicItem, ...]:
    """The ``[[demographics]]`` tables of a protocol, validated (raises DesignError)."""
    if items is None:
        return ()
    if not isinstance(items, list):
        raise DesignError(source, "demographics must be [[demographics]] tables")
    out = []
    for i, it in enumerate(items):
        where = f"demographics[{i}]"
        if not isinstance(it, dict):
            raise DesignError(source, f"{where} must be a table")
        extra = set(it) - {"id", "text", "kind", "min", "max", "options"}
        if extra:
            raise DesignError(source, f"{where}: unknown key(s) {', '.join(sorted(extra))}")
        iid, text, kind = it.get("id"), it.get("text"), it.get("kind", "choice")
        if not isinstance(iid, str) or not iid.isidentifier() or not isinstance(text, str) or not text:
            raise DesignError(source, f"{where} needs an id (letters, digits, _) and a text")
        if kind == "integer":
            lo, hi = it.get("min", 0), it.get("max", 150)
            if not all(isinstance(v, int) and not isinstance(v, bool) for v in (lo, hi)) or lo > hi:
                raise DesignError(source, f"{where}: min and max must be whole numbers, min <= max")
            out.append(DemographicItem(iid, text, kind, lo, hi))
        elif kind == "choice":
            opts = it.get("options")
            if not isinstance(opts, list) or not opts or not all(isinstance(o, str) and o for o in opts):
                raise DesignError(source, f"{where}: a choice needs options = [\"...\", ...]")
            out.append(DemographicItem(iid, text, kind, options=tuple(opts)))
        else:
            raise DesignError(source, f"{where}.kind must be integer or choice, got {kind!r}")
    if len({d.id for d in out}) != len(out):
        raise DesignError(source, "demographics ids must be unique")
    return tuple(out)


def builtin_names() -> list[str]:
    """Names of the protocols shipped with tactilize."""
    root = resources.files("tactilize.experiments").joinpath("protocols")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def builtin_designs() -> list[Design]:
    """The built-in protocol files' designs that mirror the paper (g-law, h-law, alpha-law, assessment...)."""
    return [load_design(n) for n in builtin_names()]


def load_design(name_or_path: str | Path) -> Design:
    """The design of a built-in protocol by name, or of a protocol TOML file by path."""
    text_name = str(name_or_path)
    if text_name in builtin_names():
        text = resources.files("tactilize.experiments").joinpath("protocols", f"{text_name}.toml").read_text("utf-8")
        return design_from_toml(text, source=f"protocol {text_name}")
    p = Path(text_name)
    if not p.exists():
        raise DesignError(text_name, f"neither a built-in protocol ({', '.join(builtin_names())}) nor a file")
    try:
        text = p.read_text("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DesignError(text_name, f"cannot read ({exc.__class__.__name__})") from None
    return design_from_toml(text, source=str(p))


# The names users meet: ``experiment protocols``, protocol files, and code written before.
load_protocol = load_design
builtin_protocols = builtin_designs
protocol_from_toml = design_from_toml
