"""Pulse trains: one-shot arrays, a streaming phase-continuous synthesiser, two channels.

================  ==================================================================
``trains``        :func:`pulse_train`, :class:`PulseScheduler`, :class:`PulseStream`,
                  the jitter of irregular textures
``pen``           the pen's two actuators: phantom sensation, apparent movement
``acceleration``  the tip's vertical acceleration along a stroke (voice coils, WAV);
                  imported by name (it loads scipy on first use)
``wavelets``      pulse events as acceleration wavelets (the sound card, the page)
================  ==================================================================
"""

from .pen import PenStream, pen_channels, pen_pulse_trains, phantom_amplitudes, phantom_beta, soa_s
from .trains import (
    DEFAULT_SAMPLE_RATE_HZ,
    JITTER_MAX_PERIODS,
    PulseScheduler,
    PulseStream,
    jitter_periods,
    pulse_train,
)

__all__ = [
    "pulse_train",
    "PulseScheduler",
    "PulseStream",
    "PenStream",
    "pen_channels",
    "pen_pulse_trains",
    "phantom_amplitudes",
    "phantom_beta",
    "soa_s",
    "jitter_periods",
    "JITTER_MAX_PERIODS",
    "DEFAULT_SAMPLE_RATE_HZ",
]
