"""The rules an MPEG-I Haptics ``.hjif`` document must keep for the MPEG reference reader to load and play it.

Stated in docs/references.md, section 6: (MPEG-I reader rules) are what the
reference software's JSON reader requires or refuses; (MPEG-I conformance
cases) the ranges its conformance suite tests; (MPEG-I binary ranges) the
field widths of the binary form every ``.hjif`` must fit to be encoded;
(MPEG-I synthesiser) what its synthesiser needs to play a band as written.

References
----------
.. [1] docs/references.md, section 6 (MPEG-I reader rules).
.. [2] docs/references.md, section 6 (MPEG-I conformance cases).
.. [3] docs/references.md, section 6 (MPEG-I binary ranges).
.. [4] docs/references.md, section 6 (MPEG-I synthesiser).
"""

from __future__ import annotations

import math
import re
from typing import Any

from ._core import Checker, Violation, at, is_int, is_num, rule_table

__all__ = ["HJIF_RULES", "check_hjif"]

_READER = "docs/references.md, section 6 (MPEG-I reader rules)"
_CASES = "docs/references.md, section 6 (MPEG-I conformance cases)"
_BINARY = "docs/references.md, section 6 (MPEG-I binary ranges)"
_SYNTH = "docs/references.md, section 6 (MPEG-I synthesiser)"

HJIF_RULES = rule_table(_READER, [
    ("hjif.root", "an object with version, profile, level, date, description, timescale, and arrays avatars, perceptions, syncs"),
    ("hjif.version", "version is a string YYYY or YYYY-N: year 2023 or later, amendment N at least 1"),
    ("hjif.profile", "profile is 'Main' or 'Simple Parametric'"),
    ("hjif.level", "level is the integer 1 or 2"),
    ("hjif.date", "date is an ISO 8601 date, YYYY-MM-DD"),
    ("hjif.description", "description is a string"),
    ("hjif.timescale", "timescale is an integer >= 1: at most 48000 in Main, exactly 1000 in Simple Parametric"),
    ("hjif.perceptions-count", "at least one perception"),
    ("hjif.avatar-fields", "an avatar is an object with integer id, integer lod and string type"),
    ("hjif.avatar-id", "avatar id is 1..255 (0 is reserved for unspecified avatars)"),
    ("hjif.avatar-unique", "avatar ids are unique"),
    ("hjif.avatar-lod", "avatar lod is >= 0"),
    ("hjif.avatar-type", "avatar type is Vibration, Pressure, Temperature or Custom"),
    ("hjif.perception-fields", "a perception is an object with integer id and avatar_id, string description and "
                               "perception_modality, arrays channels and effect_library"),
    ("hjif.perception-id", "perception id is 0..255 and unique"),
    ("hjif.perception-avatar", "perception avatar_id is 0 (unspecified) or the id of an avatar"),
    ("hjif.perception-modality", "perception_modality is a known modality (in Simple Parametric level 1: Force, "
                                 "Vibrotactile, Stiffness or Vibrotactile Texture)"),
    ("hjif.semantic-scheme", "no effect_semantic_scheme (the reference reader refuses every one)"),
    ("hjif.channels-count", "1..127 channels per perception at level 1, 1..65535 at level 2"),
    ("hjif.device-fields", "a reference device is an object with integer id and string name"),
    ("hjif.device-id", "reference device id is 1..255 and unique within its perception"),
    ("hjif.device-values", "reference device body_part_mask is an integer 0..2^32-1; its frequencies, amplitude, "
                           "impedance, voltage, current, displacement, weight and size are numbers >= 0"),
    ("hjif.device-frequencies", "minimum_frequency <= resonance_frequency <= maximum_frequency"),
    ("hjif.device-type", "reference device type is Unknown, LRA, VCA, ERM or Piezo"),
    ("hjif.channel-fields", "a channel is an object with integer id, string description, numbers gain and "
                            "mixing_coefficient, integer body_part_mask and array bands"),
    ("hjif.channel-id", "channel id is 0..65535 and unique within its perception"),
    ("hjif.channel-values", "channel gain > 0, mixing_coefficient >= 0, body_part_mask 0..2^32-1"),
    ("hjif.channel-device", "a channel's reference_device_id names a reference device of its perception"),
    ("hjif.bands-count", "at most 7 bands per channel at level 1, 63 at level 2"),
    ("hjif.band-fields", "a band is an object with string band_type, integer lower_frequency_limit and "
                         "upper_frequency_limit, array effects (and integer block_length if WaveletWave)"),
    ("hjif.band-type", "band_type is Transient, Curve, VectorialWave or WaveletWave (no WaveletWave in Simple Parametric)"),
    ("hjif.band-limits", "0 <= lower_frequency_limit <= upper_frequency_limit <= 65535 [Hz]"),
    ("hjif.band-curve-type", "curve_type only on Curve bands, one of Unknown, Cubic, Linear, Akima, Bezier, Bspline"),
    ("hjif.effect-fields", "an effect is an object with string effect_type and integer position (and integer id if Reference)"),
    ("hjif.effect-type", "effect_type is Basis, Reference or Composite (no Composite in Simple Parametric)"),
    ("hjif.effect-position", "effect position is 0 .. 2^25-1 ticks"),
    ("hjif.effect-id", "effect id is 0..65535"),
    ("hjif.effect-phase", "effect phase is a number in 0 .. 2 pi"),
    ("hjif.effect-base-signal", "base_signal is Sine, Square, Triangle, SawToothUp or SawToothDown"),
    ("hjif.effect-order", "the effects of a band are in order of position"),
    ("hjif.effect-library", "library effect ids are unique; a Reference effect names a library effect"),
    ("hjif.keyframe-position", "every keyframe has an integer relative_position 0..65535 [ticks]"),
    ("hjif.keyframe-order", "keyframe relative_positions increase within an effect"),
    ("hjif.keyframe-amplitude", "amplitude_modulation is a number in -1..1"),
    ("hjif.keyframe-frequency", "frequency_modulation is an integer 0..65535 [Hz] (the reader drops any other number)"),
    ("hjif.keyframe-in-band", "frequency_modulation lies within its band's frequency limits"),
    ("hjif.transient-amplitude", "every keyframe of a Transient band carries amplitude_modulation"),
    ("hjif.vectorial-frequency", "every VectorialWave effect has a keyframe with frequency_modulation > 0 (else it plays 0 Hz: silence)"),
    ("hjif.sync", "a sync is an object with integer timestamp >= 0 and, if given, integer timescale >= 1"),
], sources={
    **{k: _CASES for k in ("hjif.avatar-lod", "hjif.perceptions-count", "hjif.device-values", "hjif.channel-values",
                           "hjif.band-limits", "hjif.effect-phase", "hjif.keyframe-amplitude", "hjif.sync")},
    **{k: _BINARY for k in ("hjif.effect-position", "hjif.effect-id", "hjif.keyframe-position")},
    **{k: _SYNTH for k in ("hjif.effect-order", "hjif.keyframe-order", "hjif.keyframe-in-band",
                           "hjif.transient-amplitude", "hjif.vectorial-frequency")},
})

_AVATAR_TYPES = {"Vibration", "Pressure", "Temperature", "Custom"}
_MODALITIES = {"Other", "Pressure", "Acceleration", "Velocity", "Position", "Temperature", "Vibration", "Vibrotactile",
               "Water", "Wind", "Kinesthetic", "Force", "Vibrotactile Texture", "Texture", "Stiffness", "Friction",
               "Electrotactile"}
_SIMPLE_L1_MODALITIES = {"Force", "Kinesthetic", "Vibrotactile", "Vibration", "Stiffness", "Vibrotactile Texture", "Texture"}
_DEVICE_TYPES = {"Unknown", "LRA", "VCA", "ERM", "Piezo"}
_DEVICE_NUMBERS = ("minimum_frequency", "maximum_frequency", "resonance_frequency", "maximum_amplitude", "impedance",
                   "maximum_voltage", "maximum_current", "maximum_displacement", "weight", "size")
_BAND_TYPES = {"Transient", "Curve", "VectorialWave", "WaveletWave"}
_CURVE_TYPES = {"Unknown", "Cubic", "Linear", "Akima", "Bezier", "Bspline"}
_EFFECT_TYPES = {"Basis", "Reference", "Composite"}
_BASE_SIGNALS = {"Sine", "Square", "Triangle", "SawToothUp", "SawToothDown"}
_VERSION = re.compile(r"^([0-9]{4})(?:-([0-9]+))?$")
_DATE = re.compile(r"^[0-9]{4}-[01][0-9]-[0-3][0-9]")
_MASK_MAX = 2**32 - 1


def _unique(ck: Checker, ids: list[tuple[str, Any]], rule: str, what: str) -> None:
    seen: set[int] = set()
    for path, i in ids:
        ck.need(i not in seen, rule, path, f"{what} {i} is not unique")
        seen.add(i)


def check_hjif(doc: Any) -> list[Violation]:
    """Every rule of :data:`HJIF_RULES` that ``doc`` (a parsed ``.hjif``) breaks."""
    ck = Checker(HJIF_RULES)
    if not ck.need(isinstance(doc, dict), "hjif.root", "", "not a JSON object"):
        return ck.violations
    missing = [k for k in ("version", "profile", "level", "date", "description", "timescale") if k not in doc]
    missing += [k for k in ("avatars", "perceptions", "syncs") if not isinstance(doc.get(k), list)]
    ck.need(not missing, "hjif.root", "", f"missing or not an array: {', '.join(missing)}")
    _root(ck, doc)
    profile, level = doc.get("profile"), doc.get("level")
    avatar_ids = _avatars(ck, doc)
    perceptions = ck.items(doc, "perceptions", "")
    if isinstance(doc.get("perceptions"), list):
        ck.need(len(perceptions) >= 1, "hjif.perceptions-count", "perceptions", "no perception")
    ids = []
    for path, p in perceptions:
        if not ck.need(isinstance(p, dict), "hjif.perception-fields", path, "not an object"):
            continue
        _perception(ck, p, path, avatar_ids, profile, level)
        if is_int(p.get("id")):
            ids.append((at(path, "id"), p["id"]))
    _unique(ck, ids, "hjif.perception-id", "perception id")
    for path, s in ck.items(doc, "syncs", ""):
        ok = isinstance(s, dict) and is_int(s.get("timestamp")) and s["timestamp"] >= 0
        ok = ok and ("timescale" not in s or (is_int(s["timescale"]) and s["timescale"] >= 1))
        ck.need(ok, "hjif.sync", path, "a sync needs an integer timestamp >= 0 and an integer timescale >= 1 if any")
    return ck.violations


def _root(ck: Checker, doc: dict[str, Any]) -> None:
    v = doc.get("version")
    if "version" in doc:
        m = _VERSION.match(v) if isinstance(v, str) else None
        ok = m is not None and int(m.group(1)) >= 2023 and (m.group(2) is None or int(m.group(2)) >= 1)
        ck.need(ok, "hjif.version", "version", f"{v!r} is not YYYY or YYYY-N from 2023 on")
    if "profile" in doc:
        ck.need(doc["profile"] in ("Main", "Simple Parametric"), "hjif.profile", "profile", f"{doc['profile']!r}")
    if "level" in doc:
        ck.need(is_int(doc["level"]) and doc["level"] in (1, 2), "hjif.level", "level", f"{doc['level']!r}")
    if "date" in doc:
        d = doc["date"]
        ck.need(isinstance(d, str) and bool(_DATE.match(d)), "hjif.date", "date", f"{d!r} is not an ISO 8601 date")
    if "description" in doc:
        ck.need(isinstance(doc["description"], str), "hjif.description", "description", "not a string")
    if "timescale" in doc:
        t = doc["timescale"]
        ok = is_int(t) and t >= 1
        if ok and doc.get("profile") == "Simple Parametric":
            ok = t == 1000
        elif ok and doc.get("profile") == "Main":
            ok = t <= 48000
        ck.need(ok, "hjif.timescale", "timescale", f"{t!r} for profile {doc.get('profile')!r}")


def _avatars(ck: Checker, doc: dict[str, Any]) -> set[int]:
    ids = []
    for path, a in ck.items(doc, "avatars", ""):
        ok = isinstance(a, dict) and is_int(a.get("id")) and is_int(a.get("lod")) and isinstance(a.get("type"), str)
        if not ck.need(ok, "hjif.avatar-fields", path, "an avatar needs integer id and lod and a string type"):
            continue
        ck.need(1 <= a["id"] <= 255, "hjif.avatar-id", at(path, "id"),
                f"avatar id {a['id']} (0 is reserved for unspecified avatars; at most 255)")
        ck.need(a["lod"] >= 0, "hjif.avatar-lod", at(path, "lod"), f"lod {a['lod']} < 0")
        ck.need(a["type"] in _AVATAR_TYPES, "hjif.avatar-type", at(path, "type"), f"{a['type']!r}")
        ids.append((at(path, "id"), a["id"]))
    _unique(ck, ids, "hjif.avatar-unique", "avatar id")
    return {i for _, i in ids}


def _perception(ck: Checker, p: dict[str, Any], path: str, avatar_ids: set[int], profile: Any, level: Any) -> None:
    ok = (is_int(p.get("id")) and is_int(p.get("avatar_id")) and isinstance(p.get("description"), str)
          and isinstance(p.get("perception_modality"), str) and isinstance(p.get("channels"), list)
          and isinstance(p.get("effect_library"), list))
    ck.need(ok, "hjif.perception-fields", path, "a perception needs integer id and avatar_id, strings description "
            "and perception_modality, arrays channels and effect_library")
    if is_int(p.get("id")):
        ck.need(0 <= p["id"] <= 255, "hjif.perception-id", at(path, "id"), f"perception id {p['id']} not in 0..255")
    if is_int(p.get("avatar_id")):
        a = p["avatar_id"]
        ck.need(a == 0 or a in avatar_ids, "hjif.perception-avatar", at(path, "avatar_id"), f"no avatar with id {a}")
    mod = p.get("perception_modality")
    if isinstance(mod, str):
        ok = mod in _MODALITIES and not (profile == "Simple Parametric" and level == 1 and mod not in _SIMPLE_L1_MODALITIES)
        ck.need(ok, "hjif.perception-modality", at(path, "perception_modality"), f"{mod!r} for {profile!r} level {level!r}")
    ck.need("effect_semantic_scheme" not in p, "hjif.semantic-scheme", at(path, "effect_semantic_scheme"),
            "the reference reader refuses every effect_semantic_scheme")
    devices = _devices(ck, p, path)
    chans = ck.items(p, "channels", path)
    if isinstance(p.get("channels"), list) and level in (1, 2):
        top = 127 if level == 1 else 65535
        ck.need(1 <= len(chans) <= top, "hjif.channels-count", at(path, "channels"), f"{len(chans)} channels at level {level}")
    library = _library(ck, p, path)
    ids = []
    for cpath, c in chans:
        if not ck.need(isinstance(c, dict), "hjif.channel-fields", cpath, "not an object"):
            continue
        _channel(ck, c, cpath, devices, library, profile, level)
        if is_int(c.get("id")):
            ids.append((at(cpath, "id"), c["id"]))
    _unique(ck, ids, "hjif.channel-id", "channel id")


def _devices(ck: Checker, p: dict[str, Any], path: str) -> set[int]:
    ids = []
    for dpath, d in ck.items(p, "reference_devices", path):
        if not ck.need(isinstance(d, dict) and is_int(d.get("id")) and isinstance(d.get("name"), str),
                       "hjif.device-fields", dpath, "a reference device needs an integer id and a string name"):
            continue
        ck.need(1 <= d["id"] <= 255, "hjif.device-id", at(dpath, "id"), f"reference device id {d['id']} not in 1..255")
        ids.append((at(dpath, "id"), d["id"]))
        mask = d.get("body_part_mask", 0)
        ck.need(is_int(mask) and 0 <= mask <= _MASK_MAX, "hjif.device-values", at(dpath, "body_part_mask"), f"{mask!r}")
        for k in _DEVICE_NUMBERS:
            if k in d:
                ck.need(is_num(d[k]) and d[k] >= 0, "hjif.device-values", at(dpath, k), f"{d[k]!r} is not a number >= 0")
        lo, hi, res = (d.get(k) for k in ("minimum_frequency", "maximum_frequency", "resonance_frequency"))
        pairs = [(lo, hi), (lo, res), (res, hi)]
        ok = all(not (is_num(a) and is_num(b)) or a <= b for a, b in pairs)
        ck.need(ok, "hjif.device-frequencies", dpath, f"minimum {lo!r}, resonance {res!r}, maximum {hi!r} out of order")
        if "type" in d:
            ck.need(d["type"] in _DEVICE_TYPES, "hjif.device-type", at(dpath, "type"), f"{d['type']!r}")
    _unique(ck, ids, "hjif.device-id", "reference device id")
    return {i for _, i in ids}


def _library(ck: Checker, p: dict[str, Any], path: str) -> set[int]:
    ids = []
    for epath, e in ck.items(p, "effect_library", path):
        if isinstance(e, dict) and is_int(e.get("id")):
            ids.append((at(epath, "id"), e["id"]))
    _unique(ck, ids, "hjif.effect-library", "library effect id")
    return {i for _, i in ids}


def _channel(ck: Checker, c: dict[str, Any], path: str, devices: set[int], library: set[int], profile: Any,
             level: Any) -> None:
    ok = (is_int(c.get("id")) and isinstance(c.get("description"), str) and is_num(c.get("gain"))
          and is_num(c.get("mixing_coefficient")) and is_int(c.get("body_part_mask")) and isinstance(c.get("bands"), list))
    ck.need(ok, "hjif.channel-fields", path, "a channel needs integer id, string description, numbers gain and "
            "mixing_coefficient, integer body_part_mask, array bands")
    if is_int(c.get("id")):
        ck.need(0 <= c["id"] <= 65535, "hjif.channel-id", at(path, "id"), f"channel id {c['id']} not in 0..65535")
    if is_num(c.get("gain")):
        ck.need(c["gain"] > 0, "hjif.channel-values", at(path, "gain"), f"gain {c['gain']} <= 0")
    if is_num(c.get("mixing_coefficient")):
        ck.need(c["mixing_coefficient"] >= 0, "hjif.channel-values", at(path, "mixing_coefficient"), "negative")
    if is_int(c.get("body_part_mask")):
        ck.need(0 <= c["body_part_mask"] <= _MASK_MAX, "hjif.channel-values", at(path, "body_part_mask"), "out of 0..2^32-1")
    if "reference_device_id" in c:
        r = c["reference_device_id"]
        ck.need(is_int(r) and r in devices, "hjif.channel-device", at(path, "reference_device_id"),
                f"no reference device with id {r!r}")
    bands = ck.items(c, "bands", path)
    if level in (1, 2):
        top = 7 if level == 1 else 63
        ck.need(len(bands) <= top, "hjif.bands-count", at(path, "bands"), f"{len(bands)} bands at level {level}")
    for bpath, b in bands:
        if ck.need(isinstance(b, dict), "hjif.band-fields", bpath, "not an object"):
            _band(ck, b, bpath, library, profile)


def _band(ck: Checker, b: dict[str, Any], path: str, library: set[int], profile: Any) -> None:
    bt = b.get("band_type")
    ok = (isinstance(bt, str) and is_int(b.get("lower_frequency_limit")) and is_int(b.get("upper_frequency_limit"))
          and isinstance(b.get("effects"), list) and (bt != "WaveletWave" or is_int(b.get("block_length"))))
    ck.need(ok, "hjif.band-fields", path, "a band needs string band_type, integer frequency limits, array effects")
    if isinstance(bt, str):
        ck.need(bt in _BAND_TYPES and not (profile == "Simple Parametric" and bt == "WaveletWave"), "hjif.band-type",
                at(path, "band_type"), f"{bt!r} for {profile!r}")
    lo, hi = b.get("lower_frequency_limit"), b.get("upper_frequency_limit")
    limits = (lo, hi) if is_int(lo) and is_int(hi) else None
    if limits:
        ck.need(0 <= limits[0] <= limits[1] <= 65535, "hjif.band-limits", path, f"limits {lo}..{hi} Hz")
    if "curve_type" in b:
        ck.need(bt == "Curve" and b["curve_type"] in _CURVE_TYPES, "hjif.band-curve-type", at(path, "curve_type"),
                f"{b['curve_type']!r} on a {bt!r} band")
    last = None
    for epath, e in ck.items(b, "effects", path):
        if not ck.need(isinstance(e, dict), "hjif.effect-fields", epath, "not an object"):
            continue
        pos = _effect(ck, e, epath, bt, limits, library, profile)
        if pos is not None:
            ck.need(last is None or pos >= last, "hjif.effect-order", at(epath, "position"),
                    f"position {pos} before the previous effect's {last}")
            last = pos


def _effect(ck: Checker, e: dict[str, Any], path: str, band_type: Any, limits: tuple[int, int] | None,
            library: set[int], profile: Any) -> int | None:
    et, pos = e.get("effect_type"), e.get("position")
    ok = isinstance(et, str) and is_int(pos) and (et != "Reference" or is_int(e.get("id")))
    ck.need(ok, "hjif.effect-fields", path, "an effect needs a string effect_type and an integer position")
    if isinstance(et, str):
        ck.need(et in _EFFECT_TYPES and not (profile == "Simple Parametric" and et == "Composite"), "hjif.effect-type",
                at(path, "effect_type"), f"{et!r} for {profile!r}")
    if et == "Reference" and is_int(e.get("id")):
        ck.need(e["id"] in library, "hjif.effect-library", at(path, "id"), f"no library effect with id {e['id']}")
    if "id" in e:
        ck.need(is_int(e["id"]) and 0 <= e["id"] <= 65535, "hjif.effect-id", at(path, "id"), f"{e['id']!r}")
    if is_int(pos):
        ck.need(0 <= pos < 2**25, "hjif.effect-position", at(path, "position"), f"position {pos} ticks")
    if "phase" in e:
        ck.need(is_num(e["phase"]) and 0 <= e["phase"] <= 2 * math.pi, "hjif.effect-phase", at(path, "phase"),
                f"{e['phase']!r}")
    if "base_signal" in e:
        ck.need(e["base_signal"] in _BASE_SIGNALS, "hjif.effect-base-signal", at(path, "base_signal"), f"{e['base_signal']!r}")
    _keyframes(ck, e, path, band_type, limits)
    return pos if is_int(pos) else None


def _keyframes(ck: Checker, e: dict[str, Any], path: str, band_type: Any, limits: tuple[int, int] | None) -> None:
    last, playing = None, False
    for kpath, k in ck.items(e, "keyframes", path):
        rp = k.get("relative_position") if isinstance(k, dict) else None
        if not ck.need(is_int(rp) and 0 <= rp <= 65535, "hjif.keyframe-position", kpath,
                       f"relative_position {rp!r} is not an integer in 0..65535"):
            continue
        ck.need(last is None or rp > last, "hjif.keyframe-order", at(kpath, "relative_position"), f"{rp} after {last}")
        last = rp
        if "amplitude_modulation" in k:
            a = k["amplitude_modulation"]
            ck.need(is_num(a) and -1 <= a <= 1, "hjif.keyframe-amplitude", at(kpath, "amplitude_modulation"), f"{a!r}")
        elif band_type == "Transient":
            ck.fail("hjif.transient-amplitude", kpath, "a Transient keyframe without amplitude_modulation")
        if "frequency_modulation" in k:
            f = k["frequency_modulation"]
            if ck.need(is_int(f) and 0 <= f <= 65535, "hjif.keyframe-frequency", at(kpath, "frequency_modulation"),
                       f"{f!r} is not an integer in 0..65535 Hz"):
                playing = playing or f > 0
                if limits:
                    ck.need(limits[0] <= f <= limits[1], "hjif.keyframe-in-band", at(kpath, "frequency_modulation"),
                            f"{f} Hz outside the band's {limits[0]}..{limits[1]} Hz")
    if band_type == "VectorialWave":
        ck.need(playing, "hjif.vectorial-frequency", path, "no keyframe gives a frequency > 0: the effect plays 0 Hz")
