"""tactilize: turn pictures of surfaces into touch.

The public API, re-exported lazily so that ``import tactilize`` stays light
(numpy, scipy and Pillow load on first use of a name that needs them)::

    import tactilize as tz
    img = tz.load_image("cloth.jpg", dpi=300)
    feat = tz.extract_features(img)
    drv = tz.Profile.preset("paper").drive(feat, speed_m_s=0.06)
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

# public name -> module that defines it
_EXPORTS = {
    "TactilizeError": "errors",
    "ImageError": "errors",
    "ProfileError": "errors",
    "DriveError": "errors",
    "TextureImage": "image",
    "load_image": "image",
    "TextureFeatures": "features",
    "extract_features": "features",
    "radial_profile": "features",
    "TextureMap": "maps.texturemap",
    "texture_map": "maps.texturemap",
    "Drive": "drive",
    "ActuatorLimits": "mapping",
    "Profile": "mapping",
    "preset_names": "mapping",
    "pulse_train": "synthesis",
    "PulseStream": "synthesis",
    "PulseScheduler": "synthesis",
    "PenStream": "synthesis",
    "pen_channels": "synthesis",
    "pen_pulse_trains": "synthesis",
    "phantom_amplitudes": "synthesis",
    "phantom_beta": "synthesis",
    "soa_s": "synthesis",
    "SignalError": "errors",
    "WireError": "errors",
    "WireSpec": "actuators.sma",
    "WireModel": "actuators.sma",
    "SimulationResult": "actuators.sma",
    "CycleResult": "actuators.sma",
    "SafetyEnvelope": "actuators.sma",
    "simulate": "actuators.sma",
    "simulate_drive": "actuators.sma",
    "steady_cycle": "actuators.sma",
    "build_envelope": "actuators.sma",
    "SimulatedOutput": "actuators.simulated",
    "export_wav": "export",
    "export_csv": "export",
    "export_json": "export",
    "export_ahap": "export",
    "export_android": "export",
    "ahap_pattern": "export",
    "android_waveform": "export",
    "DriveTimeline": "export",
    "read_stroke": "export",
    "run_stroke": "export",
    "read_ahap": "export",
    "read_hjif": "export",
    "read_haptic": "export",
    "OutputError": "errors",
    "open_output": "actuators.factory",
    "SerialOutput": "actuators.serial",
    "AudioOutput": "actuators.audio",
    "CatalogError": "errors",
    "CatalogVersionError": "errors",
    "run_batch": "catalog",
    "read_catalog": "catalog",
    "Catalog": "catalog",
    "StrokeTracker": "pen",
    "PenRenderer": "pen",
    "builtin_textures": "data",
    "create_app": "web.app",
}

__all__ = sorted(_EXPORTS) + ["__version__"]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'tactilize' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
