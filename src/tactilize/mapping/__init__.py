"""The laws that turn texture features and stroking speed into pulse drives.

=============  ==============================================================
``laws``       the paper's g, h, alpha, the amplitude, direction and regularity laws
``limits``     :class:`ActuatorLimits`: an actuator's band, applied with a record
``profile``    :class:`Profile` (TOML), presets, and what a drive needs to know
=============  ==============================================================

The value they make, :class:`~tactilize.drive.Drive`, lives in
:mod:`tactilize.drive` so that the actuators need none of this.
"""

from ..drive import Drive
from .laws import (
    ConstantAmplitude,
    ConstantSpeed,
    ConstantWidth,
    EvenPulses,
    InverseWidth,
    LinearFrequency,
    LinearWidth,
    LogFrequency,
    NoDirection,
    PeriodicityRegularity,
    PowerFrequency,
    PowerSpeed,
    PressureAmplitude,
    ProjectedSpeed,
    ProportionalSpeed,
    SigmoidSpeed,
    law_from_dict,
    law_kinds,
)
from .limits import ActuatorLimits
from .profile import DEFAULT_PRESET, DriveFeatures, FeaturesForDrive, Profile, preset_names

__all__ = [
    "DEFAULT_PRESET",
    "Drive",
    "ActuatorLimits",
    "LinearFrequency",
    "LogFrequency",
    "SigmoidSpeed",
    "ConstantSpeed",
    "ProportionalSpeed",
    "LinearWidth",
    "InverseWidth",
    "ConstantWidth",
    "ConstantAmplitude",
    "PressureAmplitude",
    "NoDirection",
    "ProjectedSpeed",
    "PowerFrequency",
    "PowerSpeed",
    "EvenPulses",
    "PeriodicityRegularity",
    "Profile",
    "preset_names",
    "DriveFeatures",
    "FeaturesForDrive",
    "law_from_dict",
    "law_kinds",
]
