"""The operating limits of an actuator, applied to every drive with a record of what acted.

Units: SI (Hz, s).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from ..drive import Drive
from ..errors import ProfileError, check_finite

__all__ = ["ActuatorLimits"]


@dataclass(frozen=True)
class ActuatorLimits:
    """The operating limits of an actuator, applied to every drive with a record.

    Parameters
    ----------
    name : str
        Which actuator these limits describe.
    min_frequency_hz, max_frequency_hz : float
        Pulse frequency band [Hz].  A positive request below the band is raised
        to ``min_frequency_hz``; 0 stays 0 (off).
    min_pulse_width_s, max_pulse_width_s : float
        Pulse-width range [s].
    max_duty_ratio : float
        Largest f_p * p_w; above it the width is shortened.
    """

    name: str = "sma-75um-pen"
    min_frequency_hz: float = 1.0
    # The paper: "vibration up to 300 Hz is generated" by the pin actuator.
    max_frequency_hz: float = 300.0
    # Shorter pulses than a few tens of microseconds do not heat a 75 um wire
    # measurably (docs/references.md, section 2 (operating point): 1 ms at 0.42 A gives ~1.7 K).
    min_pulse_width_s: float = 20e-6
    max_pulse_width_s: float = 2e-3
    # docs/references.md, section 2 (duty ratio in practice): SMA micro-vibration is driven at duty ratios of a few
    # per cent; above ~10 % the mean temperature leaves the transformation band.
    max_duty_ratio: float = 0.10

    def __post_init__(self) -> None:
        for key, value in dataclasses.asdict(self).items():
            if key != "name":
                check_finite(value, f"<actuator {self.name}>", what=key, error=ProfileError, minimum=0.0)
        if self.min_frequency_hz > self.max_frequency_hz:
            raise ProfileError(f"<actuator {self.name}>", "min_frequency_hz exceeds max_frequency_hz")
        if self.min_pulse_width_s > self.max_pulse_width_s:
            raise ProfileError(f"<actuator {self.name}>", "min_pulse_width_s exceeds max_pulse_width_s")
        if not 0 < self.max_duty_ratio <= 1:
            raise ProfileError(f"<actuator {self.name}>", "max_duty_ratio must be in (0, 1]")

    def apply(self, drive: Drive) -> Drive:
        """Clamp a drive into these limits, naming each limit that changed it."""
        if drive.is_off:
            return drive
        f, w, clamped = drive.pulse_frequency_hz, drive.pulse_width_s, drive.clamped
        names: list[str] = []
        if f > self.max_frequency_hz:
            f = self.max_frequency_hz
            names.append("max_frequency_hz")
        elif f < self.min_frequency_hz:
            f = self.min_frequency_hz
            names.append("min_frequency_hz")
        if w > self.max_pulse_width_s:
            w = self.max_pulse_width_s
            names.append("max_pulse_width_s")
        elif w < self.min_pulse_width_s:
            w = self.min_pulse_width_s
            names.append("min_pulse_width_s")
        # Relative tolerance: a width computed as max_duty / f must not re-trigger.
        if f * w > self.max_duty_ratio * (1 + 1e-12):
            w = self.max_duty_ratio / f
            names.append("max_duty_ratio")
        if not names:
            return drive
        clamped = clamped + tuple(n for n in names if n not in clamped)
        return drive.replace(pulse_frequency_hz=f, pulse_width_s=w, clamped=clamped)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
