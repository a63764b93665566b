"""Personal calibration: one participant's own laws, fitted from their ratings.

The paper ends by noting that the image-to-touch relation "should be
established individually".  Each of the preliminary protocols varies one law
(g, h or alpha) across conditions; from one participant's ratings in any of
them this module picks that person's law and coefficient:

1. per condition, the participant's mean rating (over questions, images and
   repetitions, or over the questions given);
2. the law family (e.g. linear vs log g) whose best condition is rated highest
   (ties: the higher family mean);
3. within the family, a quadratic in log(coefficient) fitted to the ratings
   (the coefficients are spaced roughly geometrically and perception is
   roughly logarithmic); its vertex when the fit is concave, clamped to the
   tested range so nothing is extrapolated; otherwise the best-rated
   coefficient (several tied: their geometric mean).

A short adaptive step refines a fit: :func:`refinement_protocol` writes a
protocol around the person's fitted coefficient (a finer grid, half an octave
either side, repeated), which they run like any other; calibrating again then
uses the refinement, the latest protocol superseding the earlier fit.

The fitted laws replace those of a base profile (the paper preset by default)
and the result is an ordinary profile TOML, usable with ``tactilize serve
--profile FILE``.  Its description records where every number came from.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import tomli_w

from .. import __version__
from ..errors import TactilizeError
from ..mapping import Profile
from .analysis import tidy_answers
from .design import PROFILE_ROLES
from .design_toml import design_from_toml
from .tables import DesignVersion, utcnow

__all__ = ["fit_personal_profile", "fit_law", "refinement_protocol", "PRIMARY"]

# The coefficient each law family is calibrated on.
PRIMARY = {
    ("frequency", "linear"): "k1",
    ("frequency", "log"): "k2",
    ("width", "linear"): "k3",
    ("width", "inverse"): "k4",
    ("speed", "sigmoid"): "slope_per_mm_s",
    ("speed", "proportional"): "gain_per_m_s",
    ("speed", "constant"): "value",
    # The perceptual profile's laws (src/tactilize/profiles/perceptual.toml).
    ("frequency", "power"): "exponent",
    ("speed", "power"): "exponent",
    ("regularity", "periodicity"): "regular_above",
}


def fit_law(points: list[tuple[dict[str, Any], float]], role: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """Pick a law table from (law table, mean rating) pairs of one role.

    Returns the fitted law table and a report of how it was chosen.
    """
    families: dict[str, list[tuple[dict[str, Any], float]]] = {}
    for table, rating in points:
        families.setdefault(table["law"], []).append((table, rating))
    best_kind = max(families, key=lambda k: (max(r for _, r in families[k]), np.mean([r for _, r in families[k]])))
    fam = families[best_kind]
    key = PRIMARY.get((role, best_kind))
    report: dict[str, Any] = {"role": role, "law": best_kind, "families": {
        k: [{**{kk: vv for kk, vv in t.items() if kk != "law"}, "rating": r} for t, r in v] for k, v in families.items()}}
    best_table, best_rating = max(fam, key=lambda tr: tr[1])
    if key is None:
        report["method"] = "best-rated condition (no calibrated coefficient for this law)"
        return dict(best_table), report
    coefs = np.array([float(t[key]) for t, _ in fam])
    ratings = np.array([r for _, r in fam], dtype=float)
    table = dict(best_table)
    if len(set(coefs.tolist())) >= 3 and np.all(coefs > 0):
        x = np.log(coefs)
        a, b, _c = np.polyfit(x, ratings, 2)
        if a < 0:
            vertex = -b / (2 * a)
            value = float(np.exp(np.clip(vertex, x.min(), x.max())))
            report["method"] = "vertex of a quadratic in log(coefficient), clamped to the tested range"
            report["quadratic"] = {"a": float(a), "b": float(b)}
            table[key] = value
            report["coefficient"] = {key: value}
            return table, report
    top = coefs[ratings == ratings.max()]
    value = float(np.exp(np.mean(np.log(top)))) if np.all(top > 0) else float(top.mean())
    table[key] = value
    report["method"] = "best-rated coefficient" + (" (geometric mean of ties)" if len(top) > 1 else "")
    report["coefficient"] = {key: value}
    return table, report


def fit_personal_profile(store, participant: str, base: str | None = None, questions: list[str] | None = None):
    """Fit one participant's profile from every protocol they rated in ``store``.

    Parameters
    ----------
    store : Store
    participant : str
        Their participant ID (the same ID across the g, h and alpha protocols).
    base : str, optional
        Preset name or profile TOML the fitted laws replace; by default the
        base profile of the newest protocol the participant rated (the paper's
        for its experiments, the perceptual preset for ``perceptual-law``).
    questions : list of str, optional
        Only these questions count (default: all).

    Returns
    -------
    (Profile, dict)
        The profile and a JSON-ready report (per role: the law, coefficient,
        method, and the ratings it came from).
    """
    df = tidy_answers(store)
    df = df[df["participant"] == participant]
    if questions:
        df = df[df["question"].isin(questions)]
    if df.empty:
        raise TactilizeError(participant, "no answers from this participant in the store")
    texts = {}
    with store.Session() as s:
        for pv in s.query(DesignVersion):
            texts[pv.sha256] = pv.text  # exports carry the full hash
    if base is None:
        newest = df.loc[df["answered_at"].idxmax()]
        base = design_from_toml(texts[newest["protocol_sha256"]], source=f"protocol {newest['protocol']}").base_profile
    base_profile = Profile.resolve(base)
    data = base_profile.to_dict()
    reports: list[dict[str, Any]] = []
    # Oldest protocol first: a later one (a refinement round) supersedes an
    # earlier fit of the same law.
    groups = sorted(df.groupby(["protocol", "protocol_sha256"]), key=lambda g: g[1]["answered_at"].max())
    for (pname, sha), pdf in groups:
        proto = design_from_toml(texts[sha], source=f"protocol {pname}")
        means = pdf.groupby("condition")["rating"].mean()
        for role in PROFILE_ROLES:
            tables = {c.id: c.overrides.get(role) for c in proto.conditions}
            varying = {cid: t for cid, t in tables.items() if t is not None}
            distinct = {tuple(sorted(t.items())) for t in varying.values()}
            if len(distinct) < 2:
                continue
            points = [(varying[cid], float(means[cid])) for cid in varying if cid in means.index]
            if len(points) < 2:
                continue
            table, rep = fit_law(points, role)
            rep.update({"protocol": pname, "protocol_sha256": sha, "n_answers": int(len(pdf)),
                        "superseded": False})
            for earlier in reports:
                if earlier["role"] == role:
                    earlier["superseded"] = True
            data[role] = table
            reports.append(rep)
    if not reports:
        raise TactilizeError(participant, "their protocols vary no law across conditions; nothing to fit")
    data["name"] = f"personal-{participant}"
    summary = "; ".join(
        f"{r['role']}: {r['law']} {', '.join(f'{k} = {v:.4g}' for k, v in r.get('coefficient', {}).items())} "
        f"from {r['protocol']} ({r['protocol_sha256']})" for r in reports if not r["superseded"])
    data["description"] = (f"Personal profile of participant {participant}, fitted by tactilize "
                           f"{_version()} from their ratings on base {base_profile.name}: {summary}.")
    prof = Profile.from_dict(data, source=f"personal profile {participant}")
    return prof, {"participant": participant, "base": base_profile.name, "fits": reports,
                  "profile": prof.to_dict()}


def _version() -> str:
    return __version__



def refinement_protocol(store, participant: str, role: str | None = None, *, span_octaves: float = 0.5,
                        steps: int = 5, repetitions: int = 2, seed: int | None = None) -> str:
    """A protocol (TOML text) that refines one of a participant's fitted laws.

    Conditions are the fitted coefficient times ``2 ** x`` for ``steps`` values
    of x evenly spaced in ``[-span_octaves, span_octaves]``, in the fitted law
    family, each repeated ``repetitions`` times; the person's other fitted laws
    are held at their fitted values in every condition.  Images, questions and
    timing come from the protocol the fit came from.

    Parameters
    ----------
    role : {"frequency", "width", "speed"}, optional
        Which law; by default the one fitted last.

    Returns
    -------
    str
        TOML text; load it with :func:`~tactilize.experiments.design_toml.design_from_toml`
        or save it and ``tactilize experiment run FILE``.
    """
    if steps < 3 or not 0 < span_octaves <= 3 or repetitions < 1:
        raise TactilizeError("refinement", "needs steps >= 3, 0 < span_octaves <= 3 and repetitions >= 1")
    prof, report = fit_personal_profile(store, participant)
    current = [f for f in report["fits"] if not f["superseded"]]
    fits = [f for f in current if role is None or f["role"] == role]
    if not fits:
        raise TactilizeError(participant, f"no fitted {role or 'law'} to refine")
    fit = fits[-1]
    if not fit.get("coefficient"):
        raise TactilizeError(participant, f"the {fit['role']} law {fit['law']} has no coefficient to refine")
    (key, centre), = fit["coefficient"].items()
    with store.Session() as s:
        source = next(pv for pv in s.query(DesignVersion) if pv.sha256.startswith(fit["protocol_sha256"]))
        source_text, source_sha = source.text, source.sha256
    src = design_from_toml(source_text, source=f"protocol {fit['protocol']}")
    fitted = {f["role"]: prof.to_dict()[f["role"]] for f in current}
    law = dict(fitted[fit["role"]])
    conditions = []
    for i in range(steps):
        x = -span_octaves + 2 * span_octaves * i / (steps - 1)
        table = dict(law, **{key: float(centre * 2.0**x)})
        cond: dict[str, Any] = {"id": f"R{i + 1}", "label": f"{law['law']}, {key} = {table[key]:.4g} ({x:+.2f} octave)"}
        for r, t in fitted.items():
            cond[r] = table if r == fit["role"] else dict(t)
        conditions.append(cond)
    stamp = utcnow().strftime("%Y%m%d%H%M%S")
    doc = {
        # A name of its own per round: participant IDs are unique per protocol name,
        # and the same person must be able to take a second round.
        "name": f"refine-{fit['role']}-{stamp}",
        "version": "1",
        "title": f"Refinement of the {fit['role']} law",
        "description": src.description,
        "reference": f"refinement of {src.name} ({source_sha[:12]}) for participant {participant}",
        "base_profile": src.base_profile,
        "repetitions": repetitions,
        "trial_unit": src.trial_unit,
        "break_every": src.break_every,
        "min_stroke_s": src.min_stroke_s,
        "participants_planned": 1,
        "order": {"method": "williams", "seed": seed if seed is not None else int(source_sha[:6], 16),
                  "shuffle_images": src.shuffle_images},
        "images": [im.to_dict() for im in src.images],
        "conditions": conditions,
        "questions": [{"id": q.id, "text": q.text, "scale_min": q.scale_min, "scale_max": q.scale_max,
                       "anchors": {str(k): v for k, v in q.anchors.items()}} for q in src.questions],
    }
    header = (f"# Generated by tactilize {_version()} for participant {participant}: a finer grid around their\n"
              f"# fitted {fit['role']} law ({law['law']}, {key} = {centre:.4g}), from protocol {src.name} "
              f"({source_sha[:12]}).\n")
    text = header + tomli_w.dumps(doc)
    design_from_toml(text, source="refinement")  # fail here, not in front of the participant
    return text
