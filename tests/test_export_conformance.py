"""Every export keeps the rules of the tools that read it, and each rule refuses what breaks it.

The validators (tactilize.export.conformance) state the rules of the MPEG-I reference reader (.hjif), Meta's
haptic data model (.haptic), Apple's AHAP documentation and Google's VibrationEffect documentation. Here every
export of the built-in textures and of recorded strokes passes them, and for every rule one invalid document
breaks that rule and no other.
"""

from __future__ import annotations

import copy
import json

import pytest

from tactilize.data import builtin_map, texture_ids
from tactilize.drive import Drive
from tactilize.errors import SignalError
from tactilize.export import DriveTimeline, hjif_document, parse_stroke, render, run_stroke, synthetic_stroke
from tactilize.export.conformance import RULES, ConformanceError, check, validate
from tactilize.image import load_image
from tactilize.mapping import Profile
from tactilize.maps.texturemap import texture_map

from test_export_stroke import DPI, accelerating_rows, tapping_profile, two_textures

FORMATS = ("hjif", "haptic", "ahap", "android")


@pytest.fixture(scope="module")
def stroke_timeline():
    tmap = texture_map(load_image(two_textures(), dpi=DPI))
    stroke = parse_stroke(accelerating_rows(), "<test>", tmap.width_m, tmap.height_m)
    return run_stroke(stroke, tmap, tapping_profile(), meta={"image": "two-textures"})


@pytest.fixture(scope="module")
def docs(stroke_timeline):
    """One valid document per format, from the recorded stroke (continuous runs and taps both)."""
    return {f: json.loads(render(stroke_timeline, f)) for f in FORMATS}


# ----------------------------------------------------------------- every export passes


@pytest.mark.parametrize("texture_id", texture_ids())
def test_every_export_of_a_builtin_texture_conforms(texture_id):
    profile = Profile.preset("paper")
    feats = builtin_map(texture_id).whole
    # 2 mm/s gives taps below 65 Hz; 50 mm/s a continuous train
    for speed_m_s in (0.002, 0.05):
        drive = profile.drive(feats, speed_m_s)
        assert not drive.is_off
        for fmt in FORMATS:
            assert check(render(drive, fmt, 2.0), fmt) == [], (texture_id, speed_m_s, fmt)
            assert check(render([drive, drive], fmt, 2.0), fmt) == [], (texture_id, fmt)


@pytest.mark.parametrize("kind", ["profile", "wire"])
def test_every_export_of_recorded_strokes_conforms(stroke_timeline, kind):
    for fmt in FORMATS:
        assert check(render(stroke_timeline, fmt, drive=kind), fmt) == [], (fmt, kind)


def test_a_synthetic_stroke_on_a_builtin_texture_conforms():
    tmap = builtin_map("corduroy")
    stroke = synthetic_stroke(tmap.width_m, tmap.height_m, 0.03, 1.0)
    tl = run_stroke(stroke, tmap, Profile.preset("paper"), start_s=0.0, end_s=1.0, mirror=True)
    for fmt in FORMATS:
        assert check(render(tl, fmt), fmt) == [], fmt


def test_a_long_continuous_run_is_cut_into_hjif_effects_that_fit():
    # 130 s at 150 Hz: one run; a keyframe's relative_position is 16 bits, so it must be cut
    doc = json.loads(render(Drive(150.0, 0.002, 0.8), "hjif", 130.0))
    assert check(doc, "hjif") == []
    (band,) = [b for b in doc["perceptions"][0]["channels"][0]["bands"] if b["band_type"] == "VectorialWave"]
    assert len(band["effects"]) == 3
    ends = [e["position"] + e["keyframes"][-1]["relative_position"] for e in band["effects"]]
    assert [e["position"] for e in band["effects"][1:]] == ends[:-1] and ends[-1] == 130_000


# ----------------------------------------------------------------- the two .hjif faults


def test_hjif_names_no_reserved_id_and_gives_whole_hertz(docs):
    doc = docs["hjif"]
    assert [a["id"] for a in doc["avatars"]] == [1] and doc["perceptions"][0]["avatar_id"] == 1
    kfs = [k for c in doc["perceptions"][0]["channels"] for b in c["bands"] for e in b["effects"] for k in e["keyframes"]]
    assert kfs and all(type(k["frequency_modulation"]) is int for k in kfs)


def test_the_old_hjif_faults_are_refused(docs):
    old = copy.deepcopy(docs["hjif"])
    old["avatars"][0]["id"] = 0
    old["perceptions"][0]["avatar_id"] = 0
    for c in old["perceptions"][0]["channels"]:
        for b in c["bands"]:
            for e in b["effects"]:
                for k in e["keyframes"]:
                    k["frequency_modulation"] += 0.25
    rules = {v.rule for v in check(old, "hjif")}
    assert rules == {"hjif.avatar-id", "hjif.keyframe-frequency", "hjif.vectorial-frequency"}
    with pytest.raises(ConformanceError) as err:
        validate(old, "hjif")
    assert isinstance(err.value, SignalError) and "hjif.avatar-id" in str(err.value)
    assert len(err.value.violations) > 2


def test_check_reads_text_and_refuses_what_is_not_json():
    text = json.dumps(hjif_document(DriveTimeline.steady(Drive(120.0, 0.002, 0.5), 1.0)))
    assert check(text, "hjif") == [] and check(text.encode(), "hjif") == []
    with pytest.raises(SignalError, match="not valid JSON"):
        check("{", "hjif")
    with pytest.raises(SignalError, match="no validator"):
        check({}, "wav")
    assert [v.rule for v in check([], "hjif")] == ["hjif.root"]
    assert [v.rule for v in check("[]", "haptic")] == ["haptic.root"]


def test_every_rule_names_its_source_in_the_references():
    refs = open("docs/references.md", encoding="utf-8").read()
    for fmt, rules in RULES.items():
        for rule in rules.values():
            assert rule.id.startswith(fmt + ".") and rule.text
            label = rule.source.split("section 6 (", 1)[1].rstrip(")")
            assert f"**{label}.**" in refs, (rule.id, label)  # the entry the citation names exists


# ----------------------------------------------------------------- each rule refuses what breaks it


def _perc(d):
    return d["perceptions"][0]


def _bands(d, c=0):
    return _perc(d)["channels"][c]["bands"]


def _band(d, kind):
    return next(b for b in _bands(d) if b["band_type"] == kind)


def _vkf(d):
    return _band(d, "VectorialWave")["effects"][0]["keyframes"]


def _set(path_fn, key, value):
    def mutate(d):
        path_fn(d)[key] = value
    return mutate


def _do(*steps):
    def mutate(d):
        for s in steps:
            s(d)
    return mutate


def _no_device_refs(d):
    for c in _perc(d)["channels"]:
        c.pop("reference_device_id", None)


def _swap_first_taps(d):
    effs = _band(d, "Transient")["effects"]
    effs[0]["position"], effs[1]["position"] = effs[1]["position"], effs[0]["position"]


HJIF_BAD = {
    "hjif.root": lambda d: d.pop("syncs"),
    "hjif.version": _set(lambda d: d, "version", "2022"),
    "hjif.profile": _set(lambda d: d, "profile", "Advanced"),
    "hjif.level": _set(lambda d: d, "level", 3),
    "hjif.date": _set(lambda d: d, "date", "24/11/2026"),
    "hjif.description": _set(lambda d: d, "description", 5),
    "hjif.timescale": _set(lambda d: d, "timescale", 0),
    "hjif.perceptions-count": _set(lambda d: d, "perceptions", []),
    "hjif.avatar-fields": _do(_set(lambda d: d["avatars"][0], "lod", "0"), _set(_perc, "avatar_id", 0)),
    # the first fault: id 0 is reserved
    "hjif.avatar-id": _do(_set(lambda d: d["avatars"][0], "id", 0), _set(_perc, "avatar_id", 0)),
    "hjif.avatar-unique": lambda d: d["avatars"].append(dict(d["avatars"][0])),
    "hjif.avatar-lod": _set(lambda d: d["avatars"][0], "lod", -1),
    "hjif.avatar-type": _set(lambda d: d["avatars"][0], "type", "Smell"),
    "hjif.perception-fields": lambda d: _perc(d).pop("effect_library"),
    "hjif.perception-id": _set(_perc, "id", 300),
    "hjif.perception-avatar": _set(_perc, "avatar_id", 7),
    "hjif.perception-modality": _set(_perc, "perception_modality", "Smell"),
    "hjif.semantic-scheme": _set(_perc, "effect_semantic_scheme", "urn:mpeg:mpegi:haptics:effectsemantic:2023"),
    "hjif.channels-count": _set(_perc, "channels", []),
    "hjif.device-fields": _do(_set(lambda d: _perc(d)["reference_devices"][0], "name", 3), _no_device_refs),
    "hjif.device-id": _do(_set(lambda d: _perc(d)["reference_devices"][0], "id", 0),
                          *[_set(lambda d, c=c: _perc(d)["channels"][c], "reference_device_id", 0) for c in (0, 1)]),
    "hjif.device-values": _set(lambda d: _perc(d)["reference_devices"][0], "weight", -1.0),
    "hjif.device-frequencies": lambda d: _perc(d)["reference_devices"][0].update(
        resonance_frequency=_perc(d)["reference_devices"][0]["maximum_frequency"] + 100.0),
    "hjif.device-type": _set(lambda d: _perc(d)["reference_devices"][0], "type", "Magnet"),
    "hjif.channel-fields": _set(lambda d: _perc(d)["channels"][0], "gain", "1"),
    "hjif.channel-id": _set(lambda d: _perc(d)["channels"][1], "id", 0),
    "hjif.channel-values": _set(lambda d: _perc(d)["channels"][0], "gain", 0.0),
    "hjif.channel-device": _set(lambda d: _perc(d)["channels"][0], "reference_device_id", 9),
    "hjif.bands-count": lambda d: _bands(d).extend(copy.deepcopy(_bands(d)[-1]) for _ in range(6)),
    "hjif.band-fields": _set(lambda d: _band(d, "VectorialWave"), "lower_frequency_limit", 65.5),
    "hjif.band-type": _set(lambda d: _band(d, "Transient"), "band_type", "Wobble"),
    "hjif.band-limits": _set(lambda d: _band(d, "VectorialWave"), "upper_frequency_limit", 70_000),
    "hjif.band-curve-type": _set(lambda d: _band(d, "VectorialWave"), "curve_type", "Linear"),
    "hjif.effect-fields": _set(lambda d: _band(d, "Transient")["effects"][0], "position", "0"),
    "hjif.effect-type": _set(lambda d: _band(d, "Transient")["effects"][0], "effect_type", "Magic"),
    "hjif.effect-position": _set(lambda d: _band(d, "Transient")["effects"][-1], "position", 2**25),
    "hjif.effect-id": _set(lambda d: _band(d, "Transient")["effects"][0], "id", -1),
    "hjif.effect-phase": _set(lambda d: _band(d, "Transient")["effects"][0], "phase", 7.0),
    "hjif.effect-base-signal": _set(lambda d: _band(d, "Transient")["effects"][0], "base_signal", "Noise"),
    "hjif.effect-order": _swap_first_taps,
    "hjif.effect-library": _set(_perc, "effect_library", [{"id": 0, "effect_type": "Basis", "position": 0}] * 2),
    "hjif.keyframe-position": _set(lambda d: _vkf(d)[0], "relative_position", 1.5),
    "hjif.keyframe-order": lambda d: _vkf(d)[1].update(relative_position=_vkf(d)[0]["relative_position"]),
    "hjif.keyframe-amplitude": _set(lambda d: _vkf(d)[0], "amplitude_modulation", 1.5),
    # the second fault: a fractional frequency, which the reader drops
    "hjif.keyframe-frequency": lambda d: _vkf(d)[1].update(frequency_modulation=_vkf(d)[1]["frequency_modulation"] + 0.5),
    "hjif.keyframe-in-band": lambda d: _vkf(d)[0].update(
        frequency_modulation=_band(d, "VectorialWave")["upper_frequency_limit"] + 5),
    "hjif.transient-amplitude": lambda d: _band(d, "Transient")["effects"][0]["keyframes"][0].pop("amplitude_modulation"),
    "hjif.vectorial-frequency": lambda d: [k.pop("frequency_modulation") for k in _vkf(d)],
    "hjif.sync": _set(lambda d: d, "syncs", [{"timestamp": -1}]),
}


def _env(d):
    return d["signals"]["continuous"]["envelopes"]


def _emph(d):
    return next(p for p in _env(d)["amplitude"] if "emphasis" in p)


def _plain(d):
    return next(p for p in _env(d)["amplitude"][1:] if "emphasis" not in p)


def _swap_times(d):
    a = _env(d)["amplitude"]
    a[1]["time"], a[2]["time"] = a[2]["time"], a[1]["time"]


HAPTIC_BAD = {
    "haptic.root": lambda d: d.pop("signals"),
    "haptic.version": _set(lambda d: d["version"], "major", 2),
    "haptic.metadata": _set(lambda d: d["metadata"], "tags", "texture"),
    "haptic.signals": _set(_env, "amplitude", {}),
    "haptic.amplitude-nonempty": _set(_env, "amplitude", []),
    "haptic.breakpoint-fields": _set(lambda d: _env(d)["amplitude"][1], "time", "0.1"),
    "haptic.time-range": _set(lambda d: _env(d)["amplitude"][0], "time", -0.1),
    "haptic.time-order": _swap_times,
    "haptic.amplitude-range": _set(_plain, "amplitude", 1.2),
    "haptic.frequency-range": _set(lambda d: _env(d)["frequency"][1], "frequency", -0.1),
    "haptic.emphasis-fields": lambda d: _emph(d)["emphasis"].pop("frequency"),
    "haptic.emphasis-range": _set(lambda d: _emph(d)["emphasis"], "frequency", 1.5),
    "haptic.emphasis-amplitude": _do(_set(_emph, "amplitude", 0.5), _set(lambda d: _emph(d)["emphasis"], "amplitude", 0.3)),
}


def _events(d, kind):
    return [e["Event"] for e in d["Pattern"] if "Event" in e and e["Event"]["EventType"] == kind]


def _curve(d, pid):
    return next(e["ParameterCurve"] for e in d["Pattern"] if "ParameterCurve" in e
                and e["ParameterCurve"]["ParameterID"] == pid and len(e["ParameterCurve"]["ParameterCurveControlPoints"]) > 2)


def _seventeen(d):
    c = _curve(d, "HapticIntensityControl")
    c["ParameterCurveControlPoints"] = [{"Time": 0.01 * i, "ParameterValue": 0.5} for i in range(17)]


AHAP_BAD = {
    "ahap.root": lambda d: d.pop("Version"),
    "ahap.entry": lambda d: d["Pattern"].append({}),
    "ahap.event-fields": _set(lambda d: _events(d, "HapticTransient")[0], "Time", -1.0),
    "ahap.event-parameter": lambda d: _events(d, "HapticContinuous")[0]["EventParameters"].append(
        {"ParameterID": "AudioVolume", "ParameterValue": 0.5}),
    "ahap.event-range": _set(lambda d: _events(d, "HapticContinuous")[0]["EventParameters"][0], "ParameterValue", 1.5),
    "ahap.continuous-duration": lambda d: _events(d, "HapticContinuous")[0].pop("EventDuration"),
    "ahap.continuous-30s": _set(lambda d: _events(d, "HapticContinuous")[0], "EventDuration", 31.0),
    "ahap.curve-fields": _set(lambda d: _curve(d, "HapticIntensityControl"), "ParameterID", "HapticFooControl"),
    "ahap.curve-16": _seventeen,
    "ahap.curve-time-order": lambda d: _curve(d, "HapticIntensityControl")["ParameterCurveControlPoints"].reverse(),
    "ahap.curve-range": _set(lambda d: _curve(d, "HapticIntensityControl")["ParameterCurveControlPoints"][1],
                             "ParameterValue", 1.5),
}


def _wcp(d):
    return d["waveform_envelopes"][0]["control_points"]


ANDROID_BAD = {
    "android.root": _set(lambda d: d, "repeat", "none"),
    "android.waveform-arrays": lambda d: d["amplitudes"].pop(),
    "android.timings": lambda d: d["timings_ms"].__setitem__(0, -1),
    "android.amplitudes": lambda d: d["amplitudes"].__setitem__(0, 300),
    "android.repeat": lambda d: d.update(repeat=len(d["timings_ms"])),
    "android.envelope-fields": _set(lambda d: _wcp(d)[0], "duration_ms", 20.5),
    "android.envelope-values": _set(lambda d: _wcp(d)[0], "amplitude", 1.5),
    "android.envelope-points": lambda d: d["waveform_envelopes"][0].update(control_points=_wcp(d) * 17),
    "android.envelope-segments": _set(lambda d: _wcp(d)[0], "duration_ms", 10),
    "android.basic-ends-at-zero": _set(lambda d: d["basic_envelopes"][0]["control_points"][-1], "intensity", 0.3),
    "android.composition-fields": lambda d: d.update(compositions=[_composition(primitive="PRIMITIVE_BUZZ")]),
    "android.composition-values": lambda d: d.update(compositions=[_composition(scale=1.2)]),
}

def _composition(**primitive):
    """A composition of one click, its primitive's fields replaced by ``primitive``."""
    p = {"primitive": "PRIMITIVE_CLICK", "scale": 0.8, "delay_ms": 0, "t_ms": 0, **primitive}
    return {"start_ms": 0, "delay_type": "DELAY_TYPE_RELATIVE_START_OFFSET", "primitives": [p]}


BAD = {"hjif": HJIF_BAD, "haptic": HAPTIC_BAD, "ahap": AHAP_BAD, "android": ANDROID_BAD}


def test_every_rule_has_an_invalid_document():
    for fmt, rules in RULES.items():
        assert set(BAD[fmt]) == set(rules), fmt


@pytest.mark.parametrize("fmt,rule", [(f, r) for f in FORMATS for r in RULES[f]])
def test_each_rule_refuses_the_document_that_breaks_it_and_only_it(docs, fmt, rule):
    bad = copy.deepcopy(docs[fmt])
    BAD[fmt][rule](bad)
    found = check(bad, fmt)
    assert {v.rule for v in found} == {rule}, [str(v) for v in found]
    assert all(v.path is not None and v.message for v in found)
    with pytest.raises(ConformanceError, match=rule.replace(".", r"\.")):
        validate(bad, fmt)


def test_the_registry_validates_every_document_before_it_writes_it(monkeypatch, stroke_timeline):
    import tactilize.export.registry as registry

    seen, real = [], registry.validate
    monkeypatch.setattr(registry, "validate", lambda doc, fmt: seen.append(fmt) or real(doc, fmt))
    for fmt in FORMATS:
        render(stroke_timeline, fmt)
    assert seen == list(FORMATS)
    # ...and what it refuses does not get written
    monkeypatch.setattr(registry, "validate", lambda doc, fmt: real({**doc, "avatars": [{"id": 0}]}, fmt))
    with pytest.raises(ConformanceError, match="hjif.avatar-fields"):
        render(stroke_timeline, "hjif")
