"""The rules an Apple Haptic and Audio Pattern (AHAP) document must keep to play as written.

Core Haptics clamps an out-of-range value and ignores a key it does not know,
so a faulty file still loads but plays something else; these rules refuse
what would be clamped or ignored.  Stated in docs/references.md, section 6
(AHAP document), (AHAP parameter curves) and (AHAP limits).

References
----------
.. [1] docs/references.md, section 6 (AHAP document).
.. [2] docs/references.md, section 6 (AHAP parameter curves).
.. [3] docs/references.md, section 6 (AHAP limits).
"""

from __future__ import annotations

from typing import Any

from ._core import Checker, Violation, at, is_num, rule_table

__all__ = ["AHAP_RULES", "check_ahap"]

_DOC = "docs/references.md, section 6 (AHAP document)"
_CURVES = "docs/references.md, section 6 (AHAP parameter curves)"
_LIMITS = "docs/references.md, section 6 (AHAP limits)"

AHAP_RULES = rule_table(_DOC, [
    ("ahap.root", "an object with a Pattern array and a number Version"),
    ("ahap.entry", "each Pattern entry is an object holding exactly one of Event, Parameter, ParameterCurve"),
    ("ahap.event-fields", "an Event has a number Time >= 0, a known EventType and an EventParameters array of "
                          "{ParameterID, number ParameterValue}"),
    ("ahap.event-parameter", "a haptic event's parameters are HapticIntensity, HapticSharpness, AttackTime, "
                             "DecayTime, ReleaseTime or Sustained, each at most once"),
    ("ahap.event-range", "HapticIntensity and HapticSharpness are 0..1"),
    ("ahap.continuous-duration", "a continuous event has a number EventDuration > 0 [s]"),
    ("ahap.continuous-30s", "a continuous event lasts at most 30 s"),
    ("ahap.curve-fields", "a ParameterCurve has a known ParameterID, a number Time >= 0 and a non-empty "
                          "ParameterCurveControlPoints array of {number Time, number ParameterValue}"),
    ("ahap.curve-16", "a ParameterCurve has at most 16 control points"),
    ("ahap.curve-time-order", "control point times (relative to the curve) start at 0 or later and never decrease"),
    ("ahap.curve-range", "HapticIntensityControl values are 0..1 (a multiplier); HapticSharpnessControl -1..1 (added)"),
], sources={"ahap.curve-fields": _CURVES, "ahap.curve-time-order": _CURVES, "ahap.curve-range": _CURVES,
            "ahap.continuous-30s": _LIMITS, "ahap.curve-16": _LIMITS})

_EVENT_TYPES = {"HapticTransient", "HapticContinuous", "AudioContinuous", "AudioCustom"}
_HAPTIC_PARAMS = {"HapticIntensity", "HapticSharpness", "AttackTime", "DecayTime", "ReleaseTime", "Sustained"}
_CURVE_IDS = {"HapticIntensityControl", "HapticSharpnessControl", "HapticAttackTimeControl", "HapticDecayTimeControl",
              "HapticReleaseTimeControl", "AudioVolumeControl", "AudioPanControl", "AudioBrightnessControl",
              "AudioPitchControl", "AudioAttackTimeControl", "AudioDecayTimeControl", "AudioReleaseTimeControl"}
_ENTRY_KEYS = ("Event", "Parameter", "ParameterCurve")


def check_ahap(doc: Any) -> list[Violation]:
    """Every rule of :data:`AHAP_RULES` that ``doc`` (a parsed AHAP) breaks."""
    ck = Checker(AHAP_RULES)
    ok = isinstance(doc, dict) and isinstance(doc.get("Pattern"), list) and is_num(doc.get("Version"))
    if not ck.need(ok, "ahap.root", "", "needs a Pattern array and a number Version"):
        return ck.violations
    for path, entry in ck.items(doc, "Pattern", ""):
        keys = [k for k in _ENTRY_KEYS if isinstance(entry, dict) and k in entry]
        if not ck.need(len(keys) == 1 and isinstance(entry[keys[0]], dict), "ahap.entry", path,
                       "not one Event, Parameter or ParameterCurve"):
            continue
        if keys[0] == "Event":
            _event(ck, entry["Event"], at(path, "Event"))
        elif keys[0] == "ParameterCurve":
            _curve(ck, entry["ParameterCurve"], at(path, "ParameterCurve"))
    return ck.violations


def _event(ck: Checker, ev: dict[str, Any], path: str) -> None:
    params = ev.get("EventParameters", [])
    ok = (is_num(ev.get("Time")) and ev["Time"] >= 0 and ev.get("EventType") in _EVENT_TYPES and isinstance(params, list)
          and all(isinstance(p, dict) and isinstance(p.get("ParameterID"), str) and is_num(p.get("ParameterValue"))
                  for p in params))
    if not ck.need(ok, "ahap.event-fields", path, "needs Time >= 0, a known EventType, parameters of ID and value"):
        return
    kind = ev["EventType"]
    if kind.startswith("Haptic"):
        ids = [p["ParameterID"] for p in params]
        ck.need(set(ids) <= _HAPTIC_PARAMS and len(ids) == len(set(ids)), "ahap.event-parameter",
                at(path, "EventParameters"), f"{ids} for a haptic event")
    for i, p in enumerate(params):
        if p["ParameterID"] in ("HapticIntensity", "HapticSharpness"):
            ck.need(0 <= p["ParameterValue"] <= 1, "ahap.event-range", at(at(path, "EventParameters"), i),
                    f"{p['ParameterID']} {p['ParameterValue']} not in 0..1")
    if kind == "HapticContinuous":
        d: Any = ev.get("EventDuration")
        if ck.need(is_num(d) and d > 0, "ahap.continuous-duration", at(path, "EventDuration"), f"{d!r}"):
            ck.need(d <= 30.0 + 1e-9, "ahap.continuous-30s", at(path, "EventDuration"), f"{d} s > 30 s")


def _curve(ck: Checker, c: dict[str, Any], path: str) -> None:
    pts: Any = c.get("ParameterCurveControlPoints")  # JSON: checked below
    ok = (c.get("ParameterID") in _CURVE_IDS and is_num(c.get("Time")) and c["Time"] >= 0 and isinstance(pts, list)
          and len(pts) > 0 and all(isinstance(p, dict) and is_num(p.get("Time")) and is_num(p.get("ParameterValue"))
                                   for p in pts))
    if not ck.need(ok, "ahap.curve-fields", path, "needs a known ParameterID, Time >= 0 and control points"):
        return
    ck.need(len(pts) <= 16, "ahap.curve-16", at(path, "ParameterCurveControlPoints"), f"{len(pts)} control points")
    times = [p["Time"] for p in pts]
    ck.need(times[0] >= 0 and all(b >= a for a, b in zip(times, times[1:])), "ahap.curve-time-order",
            at(path, "ParameterCurveControlPoints"), f"times {times[:4]}...")
    lo = {"HapticIntensityControl": 0.0, "HapticSharpnessControl": -1.0}.get(c["ParameterID"])
    if lo is not None:
        bad = [p["ParameterValue"] for p in pts if not lo <= p["ParameterValue"] <= 1.0]
        ck.need(not bad, "ahap.curve-range", at(path, "ParameterCurveControlPoints"),
                f"{c['ParameterID']} values {bad[:3]} outside {lo:g}..1")
