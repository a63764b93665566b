"""The rules a Meta Haptics ``.haptic`` document (data model 1.x) must keep for Meta's players to load it.

Stated in docs/references.md, section 6 (Meta .haptic rules): the data model's
fields, types and ranges, and the checks its loader makes before playing.

References
----------
.. [1] docs/references.md, section 6 (Meta .haptic rules).
"""

from __future__ import annotations

from typing import Any

from ._core import Checker, Violation, at, is_int, is_num, rule_table

__all__ = ["HAPTIC_RULES", "check_haptic"]

#: The largest value a 32-bit float holds: breakpoint times are f32 [s].
F32_MAX = 3.4028234663852886e38

HAPTIC_RULES = rule_table("docs/references.md, section 6 (Meta .haptic rules)", [
    ("haptic.root", "an object with version and signals"),
    ("haptic.version", "version is an object with integer major 1 and, if given, integers minor and patch >= 0"),
    ("haptic.metadata", "metadata, if given, is an object whose editor, author, source, project, description are "
                        "strings and whose tags is an array of strings"),
    ("haptic.signals", "signals.continuous.envelopes is an object with an array amplitude and, if given, an array frequency"),
    ("haptic.amplitude-nonempty", "the amplitude envelope has at least one breakpoint"),
    ("haptic.breakpoint-fields", "an amplitude breakpoint has numbers time and amplitude; a frequency breakpoint "
                                 "numbers time and frequency"),
    ("haptic.time-range", "breakpoint times are 0 .. 3.4e38 s (a 32-bit float)"),
    ("haptic.time-order", "breakpoint times never decrease within an envelope"),
    ("haptic.amplitude-range", "breakpoint amplitude is 0..1"),
    ("haptic.frequency-range", "breakpoint frequency is 0..1"),
    ("haptic.emphasis-fields", "an emphasis is an object with numbers amplitude and frequency"),
    ("haptic.emphasis-range", "emphasis amplitude and frequency are 0..1"),
    ("haptic.emphasis-amplitude", "an emphasis amplitude is not below its breakpoint's amplitude"),
])

_META_STRINGS = ("editor", "author", "source", "project", "description")


def check_haptic(doc: Any) -> list[Violation]:
    """Every rule of :data:`HAPTIC_RULES` that ``doc`` (a parsed ``.haptic``) breaks."""
    ck = Checker(HAPTIC_RULES)
    if not ck.need(isinstance(doc, dict) and "version" in doc and "signals" in doc, "haptic.root", "",
                   "not an object with version and signals"):
        return ck.violations
    v = doc["version"]
    ok = isinstance(v, dict) and is_int(v.get("major")) and v["major"] == 1
    ok = ok and all(is_int(v[k]) and v[k] >= 0 for k in ("minor", "patch") if k in v)
    ck.need(ok, "haptic.version", "version", f"{v!r} is not version 1.x.y")
    if "metadata" in doc:
        m = doc["metadata"]
        ok = isinstance(m, dict) and all(isinstance(m[k], str) for k in _META_STRINGS if k in m)
        ok = ok and ("tags" not in m or (isinstance(m["tags"], list) and all(isinstance(t, str) for t in m["tags"])))
        ck.need(ok, "haptic.metadata", "metadata", "metadata fields of the wrong type")
    sig = doc["signals"]
    cont = sig.get("continuous") if isinstance(sig, dict) else None
    env = cont.get("envelopes") if isinstance(cont, dict) else None
    env = env if isinstance(env, dict) else None
    ok = env is not None and isinstance(env.get("amplitude"), list) and isinstance(env.get("frequency", []), list)
    if not ck.need(ok, "haptic.signals", "signals", "no signals.continuous.envelopes with an amplitude array") \
            or env is None:  # (not ok)
        return ck.violations
    path = "signals.continuous.envelopes"
    ck.need(len(env["amplitude"]) > 0, "haptic.amplitude-nonempty", at(path, "amplitude"), "empty")
    _envelope(ck, env["amplitude"], at(path, "amplitude"), "amplitude")
    if "frequency" in env:
        _envelope(ck, env["frequency"], at(path, "frequency"), "frequency")
    return ck.violations


def _envelope(ck: Checker, points: list[Any], path: str, value: str) -> None:
    last = None
    for i, p in enumerate(points):
        ppath = at(path, i)
        ok = isinstance(p, dict) and is_num(p.get("time")) and is_num(p.get(value))
        if not ck.need(ok, "haptic.breakpoint-fields", ppath, f"needs numbers time and {value}"):
            continue
        t = p["time"]
        if ck.need(0 <= t <= F32_MAX, "haptic.time-range", at(ppath, "time"), f"time {t} s"):
            ck.need(last is None or t >= last, "haptic.time-order", at(ppath, "time"), f"{t} s after {last} s")
            last = t
        ck.need(0 <= p[value] <= 1, f"haptic.{value}-range", at(ppath, value), f"{p[value]} not in 0..1")
        if "emphasis" in p:
            _emphasis(ck, p, at(ppath, "emphasis"))


def _emphasis(ck: Checker, p: dict[str, Any], path: str) -> None:
    e = p["emphasis"]
    if not ck.need(isinstance(e, dict) and is_num(e.get("amplitude")) and is_num(e.get("frequency")),
                   "haptic.emphasis-fields", path, "needs numbers amplitude and frequency"):
        return
    ck.need(0 <= e["amplitude"] <= 1 and 0 <= e["frequency"] <= 1, "haptic.emphasis-range", path,
            f"amplitude {e['amplitude']}, frequency {e['frequency']} not in 0..1")
    ck.need(e["amplitude"] >= p["amplitude"], "haptic.emphasis-amplitude", at(path, "amplitude"),
            f"{e['amplitude']} below the breakpoint's {p['amplitude']}")
