"""The pulse drive of one actuator: the value every stage after the laws passes on.

A :class:`Drive` is a small frozen value, checked when made, with no knowledge
of profiles, laws or wires: the wire physics, the outputs and the exports all
take one without importing the profile machinery.

Units: SI (Hz, s); ``amplitude`` and ``strength`` are fractions in [0, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from .errors import DriveError, check_finite

__all__ = ["Drive", "JITTER_MAX_PERIODS", "jitter_periods", "jitter_offset", "interval_cv"]


@dataclass(frozen=True)
class Drive:
    """One actuator's pulse drive.

    Parameters
    ----------
    pulse_frequency_hz : float
        Pulse repetition frequency [Hz].  0 means the actuator is off.
    pulse_width_s : float
        Width of each pulse [s].
    amplitude : float
        Pulse height in [0, 1] (the paper's H; it keeps H fixed, so 1.0).  On a
        voice coil or LRA it is the felt intensity.  On an SMA output it is what
        the circuit can do: the fraction of each pulse its switch conducts,
        chopped at tens of kHz (docs/signals-and-wire.md, "The circuit").
    clamped : tuple of str
        Names of the limits that changed this drive on its way here
        (e.g. ``"max_frequency_hz"``, ``"max_duty_ratio"``, ``"envelope"``);
        empty when the laws' result went through untouched.
    strength : float or None
        Where the profile's width law puts this texture between its weakest and
        strongest, in [0, 1] (:meth:`Profile.drive` sets it).  An actuator with a
        narrow felt band (the SMA wire) plays this position inside its band
        rather than the absolute width, which could fall outside it.  None: a
        hand-made drive; such outputs then place it by its own heat.
    regularity : float or None
        How evenly the pulses follow each other, in [0, 1]: 1 (or None) an even
        train, a grating; lower for irregular, noisy surfaces, whose pulses then
        jitter around the same mean frequency (tactilize.synthesis, "Irregular
        textures").

    Notes
    -----
    ``duty_ratio`` (the paper's W/L) is derived, never stored, so it cannot
    disagree with frequency and width.
    """

    pulse_frequency_hz: float
    pulse_width_s: float
    amplitude: float = 1.0
    clamped: tuple[str, ...] = ()
    strength: float | None = None
    regularity: float | None = None

    def __post_init__(self) -> None:
        f, w, a, s, r = self.pulse_frequency_hz, self.pulse_width_s, self.amplitude, self.strength, self.regularity
        # Every pen batch makes a few Drives: plain floats within range pass in one chain of
        # comparisons (NaN fails every one); anything else goes through check_finite, which
        # accepts or refuses exactly as for these.
        if (
            type(f) is float and type(w) is float and type(a) is float
            and 0.0 <= f < math.inf and 0.0 <= w < math.inf and 0.0 <= a <= 1.0
            and (s is None or (type(s) is float and 0.0 <= s <= 1.0))
            and (r is None or (type(r) is float and 0.0 <= r <= 1.0))
        ):
            if type(self.clamped) is not tuple:
                object.__setattr__(self, "clamped", tuple(self.clamped))
            return
        for name in ("pulse_frequency_hz", "pulse_width_s"):
            check_finite(getattr(self, name), "<drive>", what=name, error=DriveError, minimum=0.0)
        check_finite(self.amplitude, "<drive>", what="amplitude", error=DriveError, minimum=0.0, maximum=1.0)
        for name in ("strength", "regularity"):
            value = getattr(self, name)
            if value is not None:
                check_finite(value, "<drive>", what=name, error=DriveError, minimum=0.0, maximum=1.0)
        if type(self.clamped) is not tuple:
            # Accept any iterable of names but store an immutable tuple (hashable, comparable).
            object.__setattr__(self, "clamped", tuple(self.clamped))

    @classmethod
    def off(cls, clamped: tuple[str, ...] = ()) -> "Drive":
        """A drive that keeps the actuator off."""
        return cls(0.0, 0.0, 0.0, clamped)

    @property
    def is_off(self) -> bool:
        """True when the drive produces no pulses."""
        return self.pulse_frequency_hz <= 0 or self.pulse_width_s <= 0 or self.amplitude <= 0

    @property
    def duty_ratio(self) -> float:
        """Fraction of time the current is on, W/L = f_p * p_w (dimensionless)."""
        return self.pulse_frequency_hz * self.pulse_width_s

    @property
    def period_s(self) -> float:
        """Pulse period [s]; ``inf`` when off."""
        return 1.0 / self.pulse_frequency_hz if self.pulse_frequency_hz > 0 else math.inf

    def replace(self, **changes: Any) -> "Drive":
        """A copy with some fields changed (validated like any new Drive)."""
        # As dataclasses.replace (an unknown name is a TypeError from __init__, every field is
        # checked again), without its walk over the fields' metadata.
        return type(self)(**{**self.__dict__, **changes})

    def with_clamp(self, name: str, **changes: Any) -> "Drive":
        """A copy with fields changed and ``name`` appended to :attr:`clamped`."""
        clamped = self.clamped if name in self.clamped else self.clamped + (name,)
        return self.replace(clamped=clamped, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready mapping (SI units, plus ``pulse_width_ms`` for display)."""
        return {
            "pulse_frequency_hz": self.pulse_frequency_hz,
            "pulse_width_s": self.pulse_width_s,
            "pulse_width_ms": self.pulse_width_s * 1e3,
            "duty_ratio": self.duty_ratio,
            "amplitude": self.amplitude,
            "clamped": list(self.clamped),
            "strength": self.strength,
            "regularity": self.regularity,
        }


#: Largest pulse-position jitter [periods], at regularity 0: each pulse moves up to
#: 0.3 of a period either way, so the intervals' coefficient of variation is
#: 0.6 / sqrt(6) = 0.245, above the fingertip's frequency Weber fraction (about 0.2,
#: docs/references.md, section 3 (frequency discrimination)): successive intervals
#: differ by more than a frequency JND.  No interval is shorter than 0.4 of a
#: period, so the SMA wire still relaxes between pulses and follows every one
#: (at 0.8 it missed some on the finest built-in textures at 160 mm/s).
#: One rule for every train of a Drive: the synthesiser's (:mod:`tactilize.synthesis.trains`)
#: and a steady rendering's events (:func:`tactilize.surface.rendering.train_events`).
JITTER_MAX_PERIODS = 0.6
JITTER_TABLE = 4096  # pulses before the pattern repeats: 13 s at 300 Hz


@lru_cache(maxsize=16)
def jitter_table(seed: int) -> Any:
    """The seeded offsets u_k in [-1/2, 1/2) (a read-only numpy array)."""
    import numpy as np

    t = np.random.default_rng(seed).uniform(-0.5, 0.5, JITTER_TABLE)
    t.flags.writeable = False
    return t


def jitter_offset(k: int, seed: int = 0) -> float:
    """Pulse ``k``'s offset u_k in [-1/2, 1/2) (the same table as every train of that seed)."""
    return float(jitter_table(seed)[k % JITTER_TABLE])


def jitter_periods(drive: Drive, period_samples: float, width_samples: int) -> float:
    """Depth ``j`` of a drive's pulse-position jitter [periods] (0 for a regular drive).

    Two neighbours may move toward each other by ``j`` periods; ``j`` is capped so
    that they still leave one sample between them.
    """
    regularity = drive.regularity
    if regularity is None or regularity >= 1.0:
        return 0.0
    room = 1.0 - (width_samples + 1) / period_samples
    return max(0.0, min(JITTER_MAX_PERIODS * (1.0 - regularity), room))


def interval_cv(drive: Drive) -> float:
    """Coefficient of variation of a drive's inter-pulse intervals (0 for an even train or an off drive).

    Each pulse moves by ``j u_k`` periods (``u_k`` uniform on [-1/2, 1/2), ``j`` of
    :func:`jitter_periods`), so an interval varies by ``j (u_{k+1} - u_k)``, whose standard
    deviation is ``j / sqrt(6)`` periods.
    """
    if drive.is_off:
        return 0.0
    # At 1 MHz (the wire's schedule) the one-sample margin of jitter_periods is negligible.
    fs = 1e6
    return jitter_periods(drive, fs / drive.pulse_frequency_hz, max(1, round(drive.pulse_width_s * fs))) / math.sqrt(6)
