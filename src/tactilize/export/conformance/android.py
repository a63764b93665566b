"""The rules the Android export's document must keep so that each part builds on a device.

``timings_ms``/``amplitudes``/``repeat`` go to ``VibrationEffect.createWaveform``;
``waveform_envelopes`` to ``WaveformEnvelopeBuilder``, ``basic_envelopes``
to ``BasicEnvelopeBuilder`` and ``compositions`` (a stroke over a surface) to
``VibrationEffect.startComposition``.  Stated in docs/references.md, section 6
(Android waveform), (Android envelopes) and (Android compositions).

References
----------
.. [1] docs/references.md, section 6 (Android waveform).
.. [2] docs/references.md, section 6 (Android envelopes).
.. [3] docs/references.md, section 6 (Android compositions).
"""

from __future__ import annotations

from typing import Any

from ._core import Checker, Violation, at, is_int, is_num, rule_table

__all__ = ["ANDROID_RULES", "check_android"]

_WAVE = "docs/references.md, section 6 (Android waveform)"
_ENV = "docs/references.md, section 6 (Android envelopes)"
_COMP = "docs/references.md, section 6 (Android compositions)"

ANDROID_RULES = rule_table(_WAVE, [
    ("android.root", "an object with arrays timings_ms, amplitudes, waveform_envelopes, basic_envelopes and an integer repeat"),
    ("android.waveform-arrays", "timings_ms and amplitudes are non-empty arrays of integers of one length"),
    ("android.timings", "every timing is >= 0 ms"),
    ("android.amplitudes", "every amplitude is 0..255 (or -1, the device default)"),
    ("android.repeat", "repeat is -1 or an index into timings_ms"),
    ("android.envelope-fields", "a waveform envelope has a number initial_frequency_hz and control points of numbers "
                                "amplitude and frequency_hz and an integer duration_ms; a basic envelope a number "
                                "initial_sharpness and control points of numbers intensity and sharpness and an integer duration_ms"),
    ("android.envelope-values", "amplitude, intensity, sharpness and initial_sharpness are 0..1; frequencies are > 0 Hz"),
    ("android.envelope-points", "each envelope has 1..16 control points"),
    ("android.envelope-segments", "each control point's duration is 20..1000 ms"),
    ("android.basic-ends-at-zero", "a basic envelope ends at intensity 0"),
    ("android.composition-fields", "compositions, if given, is an array of objects with an integer start_ms >= 0, "
                                   "a known delay_type and an array primitives of objects with a known primitive, "
                                   "a number scale and an integer delay_ms"),
    ("android.composition-values", "a primitive's scale is 0..1 and its delay_ms >= 0"),
], sources={**{k: _ENV for k in ("android.envelope-fields", "android.envelope-values", "android.envelope-points",
                                 "android.envelope-segments", "android.basic-ends-at-zero")},
            **{k: _COMP for k in ("android.composition-fields", "android.composition-values")}})

_PRIMITIVES = {"PRIMITIVE_CLICK", "PRIMITIVE_TICK", "PRIMITIVE_LOW_TICK", "PRIMITIVE_THUD", "PRIMITIVE_SPIN",
               "PRIMITIVE_QUICK_RISE", "PRIMITIVE_SLOW_RISE", "PRIMITIVE_QUICK_FALL"}
_DELAY_TYPES = {"DELAY_TYPE_PAUSE", "DELAY_TYPE_RELATIVE_START_OFFSET"}

#: What an envelope's control points hold, by kind: the value fields and the initial field.
_KINDS = {
    "waveform_envelopes": (("amplitude", "frequency_hz"), "initial_frequency_hz"),
    "basic_envelopes": (("intensity", "sharpness"), "initial_sharpness"),
}


def check_android(doc: Any) -> list[Violation]:
    """Every rule of :data:`ANDROID_RULES` that ``doc`` (the Android export) breaks."""
    ck = Checker(ANDROID_RULES)
    ok = isinstance(doc, dict) and all(isinstance(doc.get(k), list) for k in
                                       ("timings_ms", "amplitudes", "waveform_envelopes", "basic_envelopes"))
    if not ck.need(ok and is_int(doc.get("repeat")), "android.root", "", "missing arrays or an integer repeat"):
        return ck.violations
    t, a = doc["timings_ms"], doc["amplitudes"]
    ok = len(t) > 0 and len(t) == len(a) and all(is_int(x) for x in t + a)
    if ck.need(ok, "android.waveform-arrays", "timings_ms", f"{len(t)} timings, {len(a)} amplitudes, all integers?"):
        bad = [x for x in t if x < 0]
        ck.need(not bad, "android.timings", "timings_ms", f"negative timings {bad[:3]}")
        bad = [x for x in a if not (0 <= x <= 255 or x == -1)]
        ck.need(not bad, "android.amplitudes", "amplitudes", f"amplitudes {bad[:3]} outside 0..255")
        r = doc["repeat"]
        ck.need(r == -1 or 0 <= r < len(t), "android.repeat", "repeat", f"{r} for {len(t)} timings")
    for key, (fields, initial) in _KINDS.items():
        for path, env in ck.items(doc, key, ""):
            _envelope(ck, env, path, fields, initial, key == "basic_envelopes")
    if "compositions" in doc:
        _compositions(ck, doc["compositions"])
    return ck.violations


def _compositions(ck: Checker, comps: Any) -> None:
    ok = isinstance(comps, list) and all(
        isinstance(c, dict) and is_int(c.get("start_ms")) and c["start_ms"] >= 0 and c.get("delay_type") in _DELAY_TYPES
        and isinstance(c.get("primitives"), list)
        and all(isinstance(p, dict) and p.get("primitive") in _PRIMITIVES and is_num(p.get("scale"))
                and is_int(p.get("delay_ms")) for p in c["primitives"])
        for c in comps)
    if not ck.need(ok, "android.composition-fields", "compositions", "needs start_ms, delay_type and primitives "
                   "of a known primitive, a number scale and an integer delay_ms"):
        return
    for i, c in enumerate(comps):
        bad = [(p["scale"], p["delay_ms"]) for p in c["primitives"] if not (0 <= p["scale"] <= 1 and p["delay_ms"] >= 0)]
        ck.need(not bad, "android.composition-values", at(at("compositions", i), "primitives"),
                f"(scale, delay_ms) {bad[:3]} out of range")


def _envelope(ck: Checker, env: Any, path: str, fields: tuple[str, str], initial: str, basic: bool) -> None:
    pts: Any = env.get("control_points") if isinstance(env, dict) else None  # JSON: checked below
    ok = (isinstance(env, dict) and is_num(env.get(initial)) and isinstance(pts, list)
          and all(isinstance(p, dict) and all(is_num(p.get(f)) for f in fields) and is_int(p.get("duration_ms"))
                  for p in pts))
    if not ck.need(ok, "android.envelope-fields", path, f"needs {initial} and control points of {fields} and duration_ms"):
        return
    ck.need(1 <= len(pts) <= 16, "android.envelope-points", at(path, "control_points"), f"{len(pts)} control points")
    unit = [(initial, env[initial])] if basic else []
    unit += [(f"{f}", p[f]) for p in pts for f in fields if f != "frequency_hz"]
    freqs = [env[initial]] + [p["frequency_hz"] for p in pts] if not basic else []
    bad = [(k, v) for k, v in unit if not 0 <= v <= 1] + [("frequency_hz", f) for f in freqs if not f > 0]
    ck.need(not bad, "android.envelope-values", path, f"out of range: {bad[:3]}")
    bad_d = [p["duration_ms"] for p in pts if not 20 <= p["duration_ms"] <= 1000]
    ck.need(not bad_d, "android.envelope-segments", at(path, "control_points"), f"durations {bad_d[:3]} ms")
    if basic and pts:
        ck.need(pts[-1]["intensity"] == 0, "android.basic-ends-at-zero", at(path, "control_points"),
                f"ends at intensity {pts[-1]['intensity']}")
