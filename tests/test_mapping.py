"""mapping.py: the paper's laws, limits with a record, profiles as TOML."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

import tactilize as tz
from tactilize.mapping import (
    ActuatorLimits,
    ConstantSpeed,
    InverseWidth,
    LinearFrequency,
    LinearWidth,
    LogFrequency,
    PressureAmplitude,
    ProjectedSpeed,
    SigmoidSpeed,
)


@dataclass
class Feat:
    spatial_frequency_per_m: float
    spectral_intensity: float
    orientation_deg: float = 0.0
    anisotropy: float = 1.0


PAPER = tz.Profile.preset("paper")
WIDE_OPEN = ActuatorLimits(name="test", min_frequency_hz=0, max_frequency_hz=1e6, min_pulse_width_s=0,
                           max_pulse_width_s=1.0, max_duty_ratio=1.0)


def test_paper_alpha_values_from_facts():
    # docs/references.md, section 1 (values of the laws): alpha(0) = 0.237, alpha(60) = 1.55,
    # alpha(120) = 2.86 (v in mm/s), given to three digits.
    assert PAPER.speed(0.0) == pytest.approx(0.237, abs=1e-3)
    assert PAPER.speed(0.060) == pytest.approx(1.55, abs=5e-4)
    assert PAPER.speed(0.120) == pytest.approx(2.86, abs=5e-3)


def test_paper_g_value_from_facts():
    # g(799) = 40 ln 800 = 267.4 Hz
    assert PAPER.frequency(799) == pytest.approx(267.4, abs=0.05)
    assert isinstance(PAPER.frequency, LogFrequency) and PAPER.frequency.k2 == 40
    assert isinstance(PAPER.speed, SigmoidSpeed) and PAPER.speed.slope_per_mm_s == 0.05
    assert isinstance(PAPER.width, LinearWidth) and PAPER.width.k3 == 40


def test_paper_law_composition_without_limits():
    feat = Feat(443.0, 0.857)
    d = PAPER.drive(feat, speed_m_s=0.030, limits=WIDE_OPEN)
    alpha = 2.9 / (1 + math.exp(-0.05 * (30 - 60))) + 0.1
    assert d.pulse_frequency_hz == pytest.approx(alpha * 40 * math.log(444.0))
    assert d.pulse_width_s == pytest.approx(40 * 0.857 * 1e-5)
    assert d.clamped == ()
    assert d.duty_ratio == pytest.approx(d.pulse_frequency_hz * d.pulse_width_s)


def test_paper_at_60_mm_s_is_clamped_visibly():
    # At 60 mm/s the paper's law asks for more than 300 Hz for most images:
    # docs/references.md, section 1 (values of the laws).
    d = PAPER.drive(Feat(799, 0.874), speed_m_s=0.060)
    assert d.pulse_frequency_hz == 300.0
    assert "max_frequency_hz" in d.clamped
    assert d.duty_ratio <= PAPER.limits.max_duty_ratio + 1e-12


def test_limits_record_each_clamp():
    lim = ActuatorLimits(min_frequency_hz=5, max_frequency_hz=200, min_pulse_width_s=1e-4,
                         max_pulse_width_s=1e-3, max_duty_ratio=0.05)
    d = lim.apply(tz.Drive(pulse_frequency_hz=2, pulse_width_s=5e-5, amplitude=1))
    assert d.pulse_frequency_hz == 5 and d.pulse_width_s == 1e-4
    assert set(d.clamped) == {"min_frequency_hz", "min_pulse_width_s"}
    d = lim.apply(tz.Drive(pulse_frequency_hz=150, pulse_width_s=9e-4))
    assert d.clamped == ("max_duty_ratio",)
    assert d.duty_ratio == pytest.approx(0.05)
    d = lim.apply(tz.Drive(pulse_frequency_hz=100, pulse_width_s=2e-4))
    assert d.clamped == () and d.pulse_width_s == 2e-4


def test_drive_is_constructible_with_defaults_and_validates():
    d = tz.Drive(pulse_frequency_hz=120.0, pulse_width_s=4e-4, amplitude=0.5)
    assert d.duty_ratio == pytest.approx(0.048) and d.clamped == ()
    assert tz.Drive(pulse_frequency_hz=50, pulse_width_s=1e-3).amplitude == 1.0
    with pytest.raises(tz.DriveError):
        tz.Drive(pulse_frequency_hz=-1, pulse_width_s=1e-3)
    with pytest.raises(tz.DriveError):
        tz.Drive(pulse_frequency_hz=float("nan"), pulse_width_s=1e-3)
    with pytest.raises(tz.DriveError):
        tz.Drive(pulse_frequency_hz=10, pulse_width_s=1e-3, amplitude=1.5)
    assert tz.Drive.off().is_off


def test_laws_as_written_in_the_paper():
    assert LinearFrequency(k1=0.5)(400) == 200
    assert InverseWidth(k4=4, c=5, unit_s=1e-4)(0.5) == pytest.approx(3e-4)
    assert LinearWidth(k3=40, l=10, unit_s=1e-5)(0.5) == pytest.approx(30e-5)
    assert ConstantSpeed(2.0)(1.0) == 2.0


def test_no_periodic_content_means_no_vibration():
    d = PAPER.drive(Feat(0.0, 0.0), speed_m_s=0.06)
    assert d.is_off and d.pulse_frequency_hz == 0.0


def test_bad_speed_is_a_drive_error():
    for bad in (-0.01, float("nan"), float("inf")):
        with pytest.raises(tz.DriveError):
            PAPER.drive(Feat(500, 0.5), speed_m_s=bad)


def test_physical_profile_projects_the_stroke_on_the_wave_vector():
    phys = tz.Profile.preset("physical")
    feat = Feat(1000.0, 0.9, orientation_deg=0.0)  # vertical ridges: wave vector along x
    across = phys.drive(feat, 0.05, direction_rad=0.0, limits=WIDE_OPEN)
    diagonal = phys.drive(feat, 0.05, direction_rad=math.radians(60), limits=WIDE_OPEN)
    along = phys.drive(feat, 0.05, direction_rad=math.pi / 2, limits=WIDE_OPEN)
    assert across.pulse_frequency_hz == pytest.approx(0.05 * 1000)  # f = v f_s
    assert diagonal.pulse_frequency_hz == pytest.approx(0.05 * 1000 * 0.5)
    assert along.is_off or along.pulse_frequency_hz < 1e-9
    # the paper preset ignores direction
    assert PAPER.drive(feat, 0.05, direction_rad=0.0) == PAPER.drive(feat, 0.05, direction_rad=1.2)
    # isotropic textures keep the full speed under the projecting law
    iso = Feat(1000.0, 0.9, orientation_deg=0.0, anisotropy=0.05)
    assert phys.drive(iso, 0.05, direction_rad=math.pi / 2, limits=WIDE_OPEN).pulse_frequency_hz == pytest.approx(50)
    assert isinstance(phys.direction, ProjectedSpeed)


def test_pressure_amplitude_law():
    law = PressureAmplitude(minimum=0.2, maximum=1.0, default=0.7)
    assert law(None) == 0.7 and law(0.0) == 0.2 and law(1.0) == 1.0 and law(0.5) == pytest.approx(0.6)
    prof = PAPER.replace(amplitude=law)
    assert prof.drive(Feat(500, 0.5), 0.03, pressure=0.5).amplitude == pytest.approx(0.6)


def test_profile_round_trips_through_toml(tmp_path):
    prof = PAPER.replace(name="mine", frequency=LogFrequency(k2=33.0))
    path = prof.save(tmp_path / "mine.toml")
    back = tz.Profile.load(path)
    assert back == prof
    assert tz.Profile.resolve(str(path)) == prof
    assert tz.Profile.resolve("paper") == PAPER


def test_presets_are_listed_and_valid():
    names = tz.preset_names()
    assert {"paper", "physical"} <= set(names)
    for name in names:
        assert tz.Profile.preset(name).name == name


@pytest.mark.parametrize(
    "text, fault",
    [
        ("this is = not [toml", "invalid TOML"),
        ('[frequency]\nlaw = "cubic"\n[speed]\nlaw="constant"\n[width]\nlaw="constant"', "unknown"),
        ('[speed]\nlaw="constant"\n[width]\nlaw="constant"', "missing [frequency]"),
        ('[frequency]\nlaw = "log"\nk2 = "forty"\n[speed]\nlaw="constant"\n[width]\nlaw="constant"', "finite number"),
        ('[frequency]\nlaw = "log"\nk9 = 1\n[speed]\nlaw="constant"\n[width]\nlaw="constant"', "unknown key"),
        ('[frequency]\nlaw = "log"\n[speed]\nlaw="constant"\n[width]\nlaw="constant"\n[actuator]\nmax_duty_ratio = 3', "max_duty_ratio"),
    ],
)
def test_bad_profiles_raise_profile_error(tmp_path, text, fault):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(tz.ProfileError) as info:
        tz.Profile.load(path)
    assert fault in str(info.value) and str(path) in str(info.value)


def test_unknown_preset_and_missing_file():
    with pytest.raises(tz.ProfileError, match="no such preset"):
        tz.Profile.preset("nope")
    with pytest.raises(tz.ProfileError, match="file not found"):
        tz.Profile.load("/nonexistent/x.toml")
    with pytest.raises(tz.ProfileError, match="neither a preset"):
        tz.Profile.resolve("nope")


def test_one_check_for_finite_numbers():
    from tactilize.errors import DriveError, TactilizeError, check_finite

    assert check_finite(3, "<x>", minimum=0) == 3.0
    for bad in (float("nan"), float("inf"), True, "1", None, -1.0):
        with pytest.raises(DriveError) as exc:
            check_finite(bad, "<speed>", what="speed", error=DriveError, minimum=0.0, unit="m/s")
        assert exc.value.source == "<speed>" and "speed must be a finite number >= 0 [m/s]" in exc.value.fault
    with pytest.raises(TactilizeError):
        check_finite(2.0, "<a>", minimum=0.0, maximum=1.0)
    with pytest.raises(TactilizeError):
        check_finite(0.0, "<a>", above=0.0)


def test_catalog_and_experiments_share_one_features_value():
    from tactilize.catalog import StoredFeatures
    from tactilize.catalog.reader import Catalog
    from tactilize.experiments import pictures
    from tactilize.mapping import DriveFeatures, FeaturesForDrive, Profile

    assert StoredFeatures is DriveFeatures
    assert pictures.DriveFeatures is DriveFeatures
    # an unknown anisotropy is directional everywhere, as Profile.drive assumes
    assert DriveFeatures(500.0, 0.5).anisotropy == 1.0
    row = {"status": "ok", "spatial_frequency_per_m": 500.0, "spectral_intensity": 0.5, "orientation_deg": 10.0}
    assert Catalog.features_of(row).anisotropy == 1.0
    assert isinstance(DriveFeatures(500.0, 0.5), FeaturesForDrive)
    # and the paper's law gives the same drive from it as from a full analysis
    d1 = Profile.preset("physical").drive(DriveFeatures(500.0, 0.5, 30.0, 0.9), 0.05, math.radians(30.0))
    assert d1.pulse_frequency_hz == pytest.approx(0.05 * 500.0)
