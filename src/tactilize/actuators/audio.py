"""The audio output: pulse trains played on a sound device.

Voice-coil and LRA actuators on an audio amplifier feel a pulse train played as
sound.  :class:`AudioOutput` opens a two-channel output stream with sounddevice
(PortAudio) and fills every block from one :class:`~tactilize.synthesis.PulseStream`
per channel, so a drive change takes effect at the next pulse start without a
truncated or doubled pulse (the synthesiser's streaming rules).  The pen's
two-channel effects (phantom, apparent movement) are computed upstream, by
:func:`~tactilize.synthesis.pen_channels`, into one drive per channel.

sounddevice is an optional extra (``pip install 'tactilize[audio]'``) and needs
the PortAudio library; both are imported only when an AudioOutput is made, and
their absence is an :class:`~tactilize.errors.OutputError` saying how to
install them.

Frames (:meth:`AudioOutput.play`): a steady rendering's regular train plays as the pulse
train of its Drive (what it always sounded like); other pulse events (the surface rendering,
docs/surfaces.md) play as acceleration wavelets (:mod:`tactilize.synthesis.wavelets`): each bump crossed is the
second derivative of a Gaussian bump, as wide as the local interval, as strong
as the event; the steady pulse train is silent meanwhile.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple, Sequence

import numpy as np

from ..errors import OutputError
from ..drive import Drive
from ..synthesis import PulseScheduler, PulseStream
from ..synthesis.wavelets import FrameWavelet, WaveletPlayer, event_wavelets
from .base import OutputBase

if TYPE_CHECKING:
    from ..surface.rendering import Frame

__all__ = ["AudioOutput", "import_sounddevice"]


class _Scheduled(NamedTuple):
    """What the audio thread is to play of a rendering's events."""

    version: int  # one more with every update, so the audio thread sees each once
    wavelets: tuple[tuple[FrameWavelet, ...], ...] | None  # per channel; None clears them
    fired_before: float  # the frame of the batch's newest sample (:meth:`WaveletPlayer.replace`)


def import_sounddevice() -> Any:
    """The sounddevice module, or an OutputError telling how to get it
    (the extra, or the system's PortAudio: :mod:`tactilize.extras`)."""
    from ..extras import SYSTEM_PACKAGES, require

    try:
        return require("sounddevice", "audio", "audio", error=OutputError)
    except OSError as exc:
        # sounddevice raises OSError("PortAudio library not found") on import.
        raise OutputError("audio", f"{exc}; install {SYSTEM_PACKAGES['audio']}") from None


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
            from .sma import default_envelope

            envelope = default_envelope()
        self.envelope = envelope
        self.device = device
        self.sample_rate_hz = float(sample_rate_hz)
        self.gain = float(gain)
        #: callback blocks PortAudio reported as under- or overflowing
        self.xruns = 0
        self._streams = [PulseStream(self.sample_rate_hz) for _ in range(self.channels)]
        self._wavelets = [WaveletPlayer(self.sample_rate_hz) for _ in range(self.channels)]
        self.block_frames = int(block_frames)
        # Wavelets cross to the audio thread as one tuple, as drives do.
        self._scheduled = _Scheduled(0, None, 0.0)
        self._scheduled_version = 0
        self._offset_frames: float | None = None
        # Drives cross to the audio thread as one (version, drives) tuple:
        # assigning it is atomic, so the callback never sees half an update
        # and never blocks on a lock the caller holds.
        self._wanted: tuple[int, tuple[Drive, ...]] = (0, (Drive.off(),) * self.channels)
        self._playing_version = 0
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
        version, drives = self._wanted
        if version != self._playing_version:
            for stream, d in zip(self._streams, drives):
                stream.set_drive(d)
            self._playing_version = version
        version, wanted, fired_before = self._scheduled
        if version != self._scheduled_version:
            for player, wavelets in zip(self._wavelets, wanted or ((),) * self.channels):
                if wanted is None:
                    player.clear()
                else:
                    player.replace(wavelets, fired_before)
            self._scheduled_version = version
        outdata.fill(0.0)
        for c, stream in enumerate(self._streams):
            stream.render(frames, outdata[:, c])
            self._wavelets[c].render(outdata[:, c])
        if self.gain != 1.0:
            outdata *= self.gain

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Play one drive per channel from the next block on; returns them after the envelope."""
        drives = [d if d.is_off else self.envelope.apply(d) for d in self._check(channels)]
        for d in drives:
            # Refuse here, in the caller's thread, what the synthesiser would
            # refuse in the audio thread (e.g. pulses so wide they touch).
            PulseScheduler(self.sample_rate_hz).set_drive(d)
        self._publish(drives)
        self._scheduled = _Scheduled(self._scheduled.version + 1, None, 0.0)  # a steady drive: no events left to play
        self._offset_frames = None
        return drives

    def play(self, frame: Frame, now_s: float, channels: Sequence[Drive]) -> list[Drive]:
        """Play one rendered frame (the Output interface): a regular train (a steady rendering's)
        as its Drive's pulse train, the synthesiser's exact train; other events as wavelets."""
        if frame.regular:
            return self.apply(channels)
        return self._play_events([frame.events] * self.channels, now_s, channels)

    def _play_events(self, channels: Sequence[Sequence[Any]], now_s: float, equivalent: Sequence[Drive]) -> list[Drive]:
        """Per channel, pulse events (stroke clock [s]) as acceleration wavelets, replacing those
        not yet started; ``now_s`` [s] is the stroke time of the newest pen sample, played one
        block from the frame the device has reached.  Returns ``equivalent`` after the envelope
        (for the page's readouts); the pulse train itself is silent while events play."""
        applied = [d if d.is_off else self.envelope.apply(d) for d in self._check(equivalent)]
        fs = self.sample_rate_hz
        if self._offset_frames is None:
            # The stroke's clock on the device's, fixed for the stroke, one block ahead: a
            # batch arriving late then shifts nothing, and an event re-sent lands where it was.
            self._offset_frames = self._wavelets[0].frame + self.block_frames - now_s * fs
        frame = self._offset_frames + now_s * fs
        # The pen's two-channel split (the phantom sensation by stroke direction) scales each
        # channel as it scales the equivalent drives.
        loudest = max((d.amplitude for d in applied), default=0.0)
        per_channel: list[tuple[FrameWavelet, ...]] = []
        for c, events in enumerate(list(channels)[: self.channels]):
            share = applied[c].amplitude / loudest if loudest > 0 else 1.0
            per_channel.append(tuple(
                FrameWavelet(frame + (w.t_s - now_s) * fs, share * min(1.0, max(0.0, w.amplitude)), w.sigma_s * fs)
                for w in event_wavelets(events)
            ))
        per_channel += [()] * (self.channels - len(per_channel))
        self._publish([Drive.off()] * self.channels)
        self._scheduled = _Scheduled(self._scheduled.version + 1, tuple(per_channel), frame)
        return applied

    def stop(self) -> None:
        """Silence every channel (the stream keeps running, playing zeros)."""
        self._publish([Drive.off()] * self.channels)
        self._scheduled = _Scheduled(self._scheduled.version + 1, None, 0.0)
        self._offset_frames = None

    def _publish(self, drives: Sequence[Drive]) -> None:
        self._wanted = (self._wanted[0] + 1, tuple(drives))

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.stop()
        try:
            self._stream.stop()
        finally:
            self._stream.close()
