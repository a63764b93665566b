"""The payloads of the serial byte format up to version 3: SET, STATUS, HOLD, PAIR, SENSE.

Wire units are integers (millihertz, nanoseconds) because the firmware works in
integers; the encoders convert from SI.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import NamedTuple

from ._framing import FLAG_SENSE_FAULT, FLAG_WATCHDOG_TRIPPED

#: the u16 amplitude that means 1.0 (the paper's full pulse height H)
AMPLITUDE_FULL_SCALE = 0xFFFF

_SET_FORMAT = ">BIIH"
_SET_IRREGULAR_FORMAT = ">BIIHH"
#: regularity u16 of an even train (also what a SET without the field means)
REGULARITY_EVEN = 0xFFFF


class SetChannel(NamedTuple):
    """A SET payload in wire units."""

    channel: int
    frequency_mhz: int
    pulse_width_ns: int
    amplitude_q16: int
    regularity_q16: int = REGULARITY_EVEN

    @property
    def frequency_hz(self) -> float:
        return self.frequency_mhz / 1e3

    @property
    def pulse_width_s(self) -> float:
        return self.pulse_width_ns / 1e9

    @property
    def amplitude(self) -> float:
        return self.amplitude_q16 / AMPLITUDE_FULL_SCALE


def _u32(value: float, name: str) -> int:
    n = int(round(value))
    if not 0 <= n <= 0xFFFFFFFF:
        raise ValueError(f"{name} {value} does not fit the wire format")
    return n


def encode_set_channel(
    channel: int, frequency_hz: float, pulse_width_s: float, amplitude: float, regularity: float | None = None
) -> bytes:
    """SET payload from SI values.

    Parameters
    ----------
    channel : int
        Channel index, 0 or 1 on the pen's controller.
    frequency_hz : float
        Pulse frequency [Hz], sent in millihertz.
    pulse_width_s : float
        Pulse width [s], sent in nanoseconds.
    amplitude : float
        Fraction of full pulse height in [0, 1], sent as u16.
    regularity : float, optional
        The drive's regularity in [0, 1]; None or 1 sends the short frame (an
        even train), which every controller understands.
    """
    if not 0 <= channel <= 0xFF:
        raise ValueError(f"channel {channel} is not a byte")
    if not 0.0 <= amplitude <= 1.0:
        raise ValueError(f"amplitude {amplitude} outside [0, 1]")
    head = struct.pack(
        _SET_FORMAT,
        channel,
        _u32(frequency_hz * 1e3, "frequency_hz"),
        _u32(pulse_width_s * 1e9, "pulse_width_s"),
        int(round(amplitude * AMPLITUDE_FULL_SCALE)),
    )
    if regularity is None or regularity >= 1.0:
        return head
    if not 0.0 <= regularity < 1.0:
        raise ValueError(f"regularity {regularity} outside [0, 1]")
    return head + struct.pack(">H", min(REGULARITY_EVEN - 1, int(round(regularity * REGULARITY_EVEN))))


def decode_set_channel(payload: bytes) -> SetChannel:
    """Inverse of :func:`encode_set_channel` (wire units)."""
    if len(payload) == struct.calcsize(_SET_IRREGULAR_FORMAT):
        return SetChannel(*struct.unpack(_SET_IRREGULAR_FORMAT, payload))
    return SetChannel(*struct.unpack(_SET_FORMAT, payload))


#: STATUS_REPLY payload: version, flags, uptime [ms], frames accepted, frames
#: rejected; per channel (two) on, frequency [mHz], width [ns], amplitude u16;
#: hard limits: min and max frequency [mHz], min and max width [ns], max duty
#: [parts per million]; watchdog timeout [ms]
STATUS_FORMAT = ">BBIII" + "BIIH" * 2 + "IIIIIH"


@dataclass(frozen=True)
class ChannelStatus:
    """What one channel of the controller is doing (SI units)."""

    on: bool
    frequency_hz: float
    pulse_width_s: float
    amplitude: float


@dataclass(frozen=True)
class ControllerStatus:
    """A STATUS_REPLY, in SI units.

    Attributes
    ----------
    version : int
        Firmware protocol version.
    watchdog_tripped : bool
        Every output is off because no valid frame came for ``watchdog_s``.
    uptime_s : float
        Time since the controller started [s].
    frames_ok, frames_bad : int
        Valid frames handled, and frames rejected for checksum (mod 2**32).
    channels : tuple of ChannelStatus
    min_frequency_hz, max_frequency_hz : float
        The controller's own hard frequency limits [Hz] (0 Hz, off, is always allowed).
    min_pulse_width_s, max_pulse_width_s : float
        Hard width limits [s].
    max_duty_ratio : float
        Hard duty-ratio limit (frequency times width).
    watchdog_s : float
        Silence after which the controller turns everything off [s].
    """

    version: int
    watchdog_tripped: bool
    uptime_s: float
    frames_ok: int
    frames_bad: int
    channels: tuple[ChannelStatus, ...]
    min_frequency_hz: float
    max_frequency_hz: float
    min_pulse_width_s: float
    max_pulse_width_s: float
    max_duty_ratio: float
    watchdog_s: float
    sense_fault: bool = False


def decode_status(payload: bytes) -> ControllerStatus:
    """A :class:`ControllerStatus` from a STATUS_REPLY payload."""
    v = struct.unpack(STATUS_FORMAT, payload)
    chans = tuple(
        ChannelStatus(bool(v[5 + 4 * i]), v[6 + 4 * i] / 1e3, v[7 + 4 * i] / 1e9, v[8 + 4 * i] / AMPLITUDE_FULL_SCALE)
        for i in range(2)
    )
    return ControllerStatus(
        version=v[0],
        watchdog_tripped=bool(v[1] & FLAG_WATCHDOG_TRIPPED),
        uptime_s=v[2] / 1e3,
        frames_ok=v[3],
        frames_bad=v[4],
        channels=chans,
        min_frequency_hz=v[13] / 1e3,
        max_frequency_hz=v[14] / 1e3,
        min_pulse_width_s=v[15] / 1e9,
        max_pulse_width_s=v[16] / 1e9,
        max_duty_ratio=v[17] / 1e6,
        watchdog_s=v[18] / 1e3,
        sense_fault=bool(v[1] & FLAG_SENSE_FAULT),
    )


def encode_status(status: ControllerStatus) -> bytes:
    """Inverse of :func:`decode_status` (for tests and host-side fakes)."""
    fields: list[int] = [
        status.version,
        (FLAG_WATCHDOG_TRIPPED if status.watchdog_tripped else 0) | (FLAG_SENSE_FAULT if status.sense_fault else 0),
        _u32(status.uptime_s * 1e3, "uptime_s"),
        status.frames_ok & 0xFFFFFFFF,
        status.frames_bad & 0xFFFFFFFF,
    ]
    for ch in status.channels:
        fields += [
            int(ch.on),
            _u32(ch.frequency_hz * 1e3, "frequency_hz"),
            _u32(ch.pulse_width_s * 1e9, "pulse_width_s"),
            int(round(ch.amplitude * AMPLITUDE_FULL_SCALE)),
        ]
    fields += [
        _u32(status.min_frequency_hz * 1e3, "min_frequency_hz"),
        _u32(status.max_frequency_hz * 1e3, "max_frequency_hz"),
        _u32(status.min_pulse_width_s * 1e9, "min_pulse_width_s"),
        _u32(status.max_pulse_width_s * 1e9, "max_pulse_width_s"),
        _u32(status.max_duty_ratio * 1e6, "max_duty_ratio"),
        int(round(status.watchdog_s * 1e3)),
    ]
    return struct.pack(STATUS_FORMAT, *fields)


# ------------------------------------------------------------ self-sensing and the board's hold

_HOLD_FORMAT = ">BIII"
_PAIR_FORMAT = ">I" + "IIH" * 2
#: SENSE_REPLY payload of a version 2 board: rail [mV] u16, then per channel
#: resistance [uohm] u32, current [uA] u32, bias level u16 (65536 = 1), pulse
#: width [ns] u32, count u16
SENSE_FORMAT_V2 = ">H" + "IIHIH" * 2
#: version 3: the same, then the faulty channels u8 (bit i: channel i)
SENSE_FORMAT = SENSE_FORMAT_V2 + "B"


def encode_hold(channel: int, pulse_energy_j: float, bias_w: float, target_ohm: float) -> bytes:
    """HOLD payload: heat per pulse [J], bias heat [W] and target resistance [ohm]."""
    return struct.pack(
        _HOLD_FORMAT, channel, _u32(pulse_energy_j * 1e9, "pulse_energy_j"), _u32(bias_w * 1e6, "bias_w"),
        _u32(target_ohm * 1e6, "target_ohm"),
    )


def encode_pair(onset_s: float, first: tuple[float, float, float], second: tuple[float, float, float]) -> bytes:
    """PAIR payload: channel 1 starts ``onset_s`` [s] after channel 0; each drive is
    (frequency [Hz], width [s], amplitude)."""
    fields: list[int] = [_u32(onset_s * 1e6, "onset_s")]
    for f, w, a in (first, second):
        fields += [_u32(f * 1e3, "frequency_hz"), _u32(w * 1e9, "pulse_width_s"), int(round(a * AMPLITUDE_FULL_SCALE))]
    return struct.pack(_PAIR_FORMAT, *fields)


@dataclass(frozen=True)
class ChannelSense:
    """One channel's latest self-sensing measurement (SI units; 0 when none yet)."""

    resistance_ohm: float
    current_a: float
    bias_level: float
    pulse_width_s: float
    count: int


@dataclass(frozen=True)
class SenseReport:
    """A SENSE_REPLY: the supply rail [V], each channel's measurement, and which
    channels' sense paths are faulty (None from a version 2 board, which cannot say)."""

    rail_v: float
    channels: tuple[ChannelSense, ...]
    faults: tuple[bool, ...] | None = None


def decode_sense(payload: bytes) -> SenseReport:
    """A :class:`SenseReport` from a SENSE_REPLY payload of either version."""
    v2 = struct.calcsize(SENSE_FORMAT_V2)
    v = struct.unpack(SENSE_FORMAT_V2, payload[:v2]) if len(payload) == v2 else struct.unpack(SENSE_FORMAT, payload)
    chans = tuple(
        ChannelSense(v[1 + 5 * i] / 1e6, v[2 + 5 * i] / 1e6, v[3 + 5 * i] / 65536, v[4 + 5 * i] / 1e9, v[5 + 5 * i])
        for i in range(2)
    )
    faults = None if len(v) == 11 else tuple(bool(v[11] >> i & 1) for i in range(2))
    return SenseReport(v[0] / 1e3, chans, faults)
