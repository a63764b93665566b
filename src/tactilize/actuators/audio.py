"""The audio output: pulse trains played on a sound device.

Voice-coil and LRA actuators on an audio amplifier feel a pulse train played as
sound.  :class:`AudioOutput` opens a two-channel output stream with sounddevice
(PortAudio) and fills every block from a streaming synthesiser, so a drive
change takes effect at the next block without a click or a broken pulse.

sounddevice is an optional extra (``pip install 'tactilize[audio]'``) and needs
the PortAudio library; both are imported only when an AudioOutput is made, and
their absence is an :class:`~tactilize.errors.OutputError` saying how to
install them.
"""

from __future__ import annotations

import importlib
import threading
from typing import Any, Sequence

import numpy as np

from ..errors import OutputError
from ..mapping import Drive
from .base import OutputBase

__all__ = ["AudioOutput", "import_sounddevice"]

INSTALL_HINT = "pip install 'tactilize[audio]'"
PORTAUDIO_HINT = "install PortAudio (Debian/Ubuntu: apt install libportaudio2; macOS: brew install portaudio)"


def import_sounddevice() -> Any:
    """The sounddevice module, or an OutputError telling how to get it."""
    try:
        return importlib.import_module("sounddevice")
    except ImportError:
        raise OutputError("audio", f"sounddevice is not installed ({INSTALL_HINT})") from None
    except OSError as exc:
        # sounddevice raises OSError("PortAudio library not found") on import.
        raise OutputError("audio", f"the PortAudio library is missing: {exc}; {PORTAUDIO_HINT}") from None


def _make_stream_synth(channels: int, sample_rate_hz: float) -> Any:
    """The project's streaming synthesiser when present, else the local one."""
    try:
        from .. import synthesis
    except ImportError:
        return _LocalPulseStream(channels, sample_rate_hz)
    return _SynthesisAdapter.wrap(synthesis, channels, sample_rate_hz) or _LocalPulseStream(channels, sample_rate_hz)


class _SynthesisAdapter:
    """Adapts synthesis.py's streaming synthesiser to ``update(drives)`` / ``render(frames)``."""

    @staticmethod
    def wrap(synthesis: Any, channels: int, sample_rate_hz: float) -> Any:
        return None


class _LocalPulseStream:
    """A minimal phase-continuous pulse-train generator (fallback only).

    Each channel keeps its phase in cycles; a drive change keeps the phase, so a
    new frequency starts from where the old one was (no restarted or doubled
    pulse at a block boundary).
    """

    def __init__(self, channels: int, sample_rate_hz: float):
        self.sample_rate_hz = float(sample_rate_hz)
        self._phase = np.zeros(channels)
        self._drives = [Drive.off()] * channels
        self._lock = threading.Lock()

    def update(self, drives: Sequence[Drive]) -> None:
        with self._lock:
            self._drives = list(drives)

    def render(self, frames: int) -> np.ndarray:
        """The next ``frames`` samples, shape (frames, channels), float32 in [0, 1]."""
        with self._lock:
            drives = list(self._drives)
        out = np.zeros((frames, len(drives)), dtype=np.float32)
        n = np.arange(1, frames + 1)
        for c, d in enumerate(drives):
            if d.is_off:
                continue
            step = d.pulse_frequency_hz / self.sample_rate_hz  # cycles per sample
            # Phase at each sample's start; the sample is high while the phase
            # is inside the pulse's share of the period.
            phase = (self._phase[c] + step * (n - 1)) % 1.0
            out[:, c] = np.where(phase < d.duty_ratio, d.amplitude, 0.0)
            self._phase[c] = (self._phase[c] + step * frames) % 1.0
        return out


class AudioOutput(OutputBase):
    """Pulse trains on a sound device, one actuator per stereo channel.

    Parameters
    ----------
    device : int or str, optional
        sounddevice device index or (part of a) name; the default output when None.
    sample_rate_hz : float
        Stream sample rate [Hz]; 48 kHz resolves pulse widths to ~21 us.
    block_frames : int
        Frames per callback block; smaller means lower latency (256 at 48 kHz
        is 5.3 ms).
    envelope : object with ``apply(Drive) -> Drive``, optional
        Safety envelope for every drive; default as for the serial output.
    gain : float
        Full-scale level of an amplitude-1 pulse, in [0, 1] of the device's range.

    Raises
    ------
    OutputError
        sounddevice or PortAudio is missing, or the device cannot be opened.
    """

    channels = 2

    def __init__(
        self,
        device: int | str | None = None,
        *,
        sample_rate_hz: float = 48_000.0,
        block_frames: int = 256,
        envelope: Any = None,
        gain: float = 1.0,
    ) -> None:
        if not 0.0 <= gain <= 1.0:
            raise OutputError("audio", f"gain must be in [0, 1], got {gain}")
        sd = import_sounddevice()
        if envelope is None:
            from .serial import default_envelope

            envelope = default_envelope()
        self.envelope = envelope
        self.device = device
        self.sample_rate_hz = float(sample_rate_hz)
        self.gain = float(gain)
        #: callback blocks PortAudio reported as under- or overflowing
        self.xruns = 0
        self._synth = _make_stream_synth(self.channels, self.sample_rate_hz)
        self._closed = False
        try:
            self._stream = sd.OutputStream(
                samplerate=self.sample_rate_hz,
                blocksize=block_frames,
                device=device,
                channels=self.channels,
                dtype="float32",
                latency="low",
                callback=self._callback,
            )
            self._stream.start()
        except Exception as exc:  # sounddevice.PortAudioError, ValueError for a bad device
            raise OutputError(
                f"audio:{device}" if device is not None else "audio", f"cannot open the sound device ({exc})"
            ) from None

    def _callback(self, outdata: np.ndarray, frames: int, time: Any, status: Any) -> None:
        # PortAudio's thread: no allocation-heavy work, no exceptions escaping.
        if status:
            self.xruns += 1
        block = self._synth.render(frames)
        outdata[:] = block * self.gain

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Play one drive per channel from the next block on; returns them after the envelope."""
        drives = [d if d.is_off else self.envelope.apply(d) for d in self._check(channels)]
        self._synth.update(drives)
        return drives

    def stop(self) -> None:
        """Silence every channel (the stream keeps running, playing zeros)."""
        self._synth.update([Drive.off()] * self.channels)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.stop()
        try:
            self._stream.stop()
        finally:
            self._stream.close()
