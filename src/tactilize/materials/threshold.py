"""The vibrotactile detection threshold, in displacement and in acceleration.

A surface is felt through a stylus only where the tip's vibration passes the
skin's detection threshold: a fraction of a micrometre near 250 Hz (the Pacinian
channel), rising on either side (docs/references.md, section 11 (detection
threshold in displacement)).  :func:`threshold_displacement_m` is this project's
fit to that curve, :func:`threshold_acceleration_m_s2` the same converted to
acceleration at each frequency, and :func:`sensation_ratio` says how far above
(> 1) or below (< 1) it a signal is.

Units: SI (m, m/s^2, Hz).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["PACINIAN_BEST_HZ", "PACINIAN_THRESHOLD_M", "FLUTTER_THRESHOLD_M", "LEAST_FELT_PROMINENCE_M",
           "threshold_displacement_m", "threshold_acceleration_m_s2", "sensation_ratio"]

#: The Pacinian channel's most sensitive frequency [Hz] (docs/references.md, section 3
#: (mechanoreceptor bands)).
PACINIAN_BEST_HZ = 250.0
#: Peak displacement detected there [m]: about -20 dB re 1 um (docs/references.md,
#: section 11 (detection threshold in displacement)).
PACINIAN_THRESHOLD_M = 0.1e-6
#: The flutter (non-Pacinian I) channel's threshold at low frequencies [m], about
#: 20 dB re 1 um, where it lies under the Pacinian curve (same section).
FLUTTER_THRESHOLD_M = 10e-6
#: Least bump prominence felt at any speed [m]: twice the least peak displacement
#: felt at any frequency (a bump moves the tip by its whole prominence, a
#: vibration of peak d by 2 d).
LEAST_FELT_PROMINENCE_M = 2.0 * PACINIAN_THRESHOLD_M


def threshold_displacement_m(frequency_hz: Any) -> np.ndarray:
    """Peak displacement [m] just detected at ``frequency_hz`` [Hz].

    The Pacinian U-curve as 12 dB per octave on either side of 250 Hz (a constant
    acceleration below it), bounded below 25 Hz or so by the flutter channel's flat
    threshold: this project's fit, docs/references.md, section 11 (detection
    threshold in displacement).
    """
    f = np.maximum(np.asarray(frequency_hz, dtype=np.float64), 1e-3)
    r = f / PACINIAN_BEST_HZ
    pacinian = PACINIAN_THRESHOLD_M * np.maximum(r, 1.0 / r) ** 2
    return np.minimum(pacinian, np.where(f < PACINIAN_BEST_HZ, FLUTTER_THRESHOLD_M, np.inf))


def threshold_acceleration_m_s2(frequency_hz: Any) -> np.ndarray:
    """Peak acceleration [m/s^2] just detected at ``frequency_hz`` [Hz]: the displacement
    threshold times (2 pi f)^2 (about 0.25 m/s^2 from 25 to 250 Hz)."""
    f = np.asarray(frequency_hz, dtype=np.float64)
    return (2.0 * math.pi * f) ** 2 * threshold_displacement_m(f)


def sensation_ratio(samples_m_s2: Any, sample_rate_hz: float, band_hz: tuple[float, float] = (20.0, 1000.0)) -> float:
    """How far above the detection threshold an acceleration signal is (1: at threshold).

    The signal's spectrum is divided by the threshold at each frequency within
    ``band_hz`` and the peak of the result taken as sqrt(2) times its RMS: a sinusoid
    at the threshold gives 1.  Broadband signals are summed over the band, which
    is this project's simplification (docs/references.md, section 11 (detection
    threshold in displacement)).

    Parameters
    ----------
    samples_m_s2 : array_like
        Acceleration [m/s^2] sampled at ``sample_rate_hz`` [Hz].
    band_hz : (float, float)
        Frequencies counted [Hz].
    """
    x = np.asarray(samples_m_s2, dtype=np.float64)
    if x.size < 2:
        return 0.0
    spec = np.fft.rfft(x)
    f = np.fft.rfftfreq(x.size, 1.0 / float(sample_rate_hz))
    sel = (f >= band_hz[0]) & (f <= band_hz[1])
    weighted = np.zeros_like(spec)
    weighted[sel] = spec[sel] / threshold_acceleration_m_s2(f[sel])
    y = np.fft.irfft(weighted, n=x.size)
    return float(math.sqrt(2.0) * np.sqrt(np.mean(y * y)))
