"""Write a drive to files other rigs and phones play: WAV, CSV, JSON, Apple AHAP, Android waveform.

Every function takes a :class:`~tactilize.mapping.Drive` (or, for WAV and CSV, a
list of drives, one per channel), so a batch over a catalog needs no image, and
returns the path written.  :func:`export` picks the writer by format name.

No SMA envelope is applied here: these files are for other actuators (voice
coils, LRAs, phone motors).  Pass ``drive = envelope.apply(drive)`` first to
export what the simulated wire would get.

Phone formats cannot carry a pulse train at full resolution, so they carry what
such actuators can render [1]_:

* AHAP: at 65 Hz and above, continuous events whose sharpness maps the pulse
  frequency linearly onto 0..1 over 65..300 Hz and whose intensity is the
  pulse train's fundamental, ``amplitude * sin(pi D) / sin(pi D_full)`` (``D``
  the duty ratio, ``D_full`` = 0.1, the paper profile's largest duty, capped at
  1); below 65 Hz, where a phone cannot vibrate continuously, one transient per
  pulse (the taps of a rough texture).
* Android: ``VibrationEffect.createWaveform(timings_ms, amplitudes, repeat)``:
  below 65 Hz each pulse and gap in whole milliseconds (edges rounded from the
  exact times, so the pattern does not drift); above, one constant amplitude
  for the duration (the motor supplies the frequency).  An ``envelope`` list of
  ``(amplitude 0..1, frequency_hz, duration_ms)`` control points for the
  API 36 envelope builder carries the frequency too.

References
----------
.. [1] docs/references.md, section 6 (haptic file formats).
"""

from __future__ import annotations

import csv
import io
import json
import math
import wave
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from .drive import Drive
from .errors import SignalError, check_finite
from .synthesis import DEFAULT_SAMPLE_RATE_HZ, pulse_train

__all__ = [
    "FORMATS",
    "export",
    "export_wav",
    "export_csv",
    "export_json",
    "export_ahap",
    "ExportFormat",
    "export_format",
    "render",
    "wav_bytes",
    "csv_bytes",
    "drive_document",
    "export_android",
    "ahap_pattern",
    "android_waveform",
    "sharpness_from_frequency",
    "intensity_from_drive",
]

#: AHAP sharpness 0..1 is commonly mapped to 65..300 Hz:
#: docs/references.md, section 6 (AHAP sharpness and frequency).
SHARPNESS_LOW_HZ = 65.0
SHARPNESS_HIGH_HZ = 300.0
#: Duty ratio rendered at full intensity (the paper profile's max_duty_ratio).
FULL_INTENSITY_DUTY = 0.10
#: Core Haptics limits one continuous event to 30 s.
AHAP_MAX_EVENT_S = 30.0


def _drives(drive: Drive | Sequence[Drive]) -> list[Drive]:
    drives = [drive] if isinstance(drive, Drive) else list(drive)
    if not drives or not all(isinstance(d, Drive) for d in drives):
        raise SignalError("<drive>", "expected a Drive or a list of Drives")
    return drives


def _duration(duration_s: float) -> float:
    return check_finite(duration_s, "<duration>", error=SignalError, above=0.0, unit="s")


def _open_for_write(path: str | Path) -> Path:
    p = Path(path)
    if p.is_dir():
        raise SignalError(str(path), "is a directory")
    if not p.parent.exists():
        raise SignalError(str(path), "its directory does not exist")
    return p


def _signals(drives: list[Drive], duration_s: float, sample_rate_hz: float) -> np.ndarray:
    return np.stack([pulse_train(d, duration_s, sample_rate_hz) for d in drives], axis=1)


def wav_bytes(
    drive: Drive | Sequence[Drive],
    duration_s: float = 2.0,
    sample_rate_hz: int = DEFAULT_SAMPLE_RATE_HZ,
) -> bytes:
    """A 16-bit PCM WAV of the pulse train (one channel per drive), as bytes.

    Parameters
    ----------
    drive : Drive or list of Drive
        One drive per channel; amplitude 1 is full scale (32767).
    duration_s : float
        Length [s].
    sample_rate_hz : int
        Sample rate [Hz]; 48 kHz by default.
    """
    drives = _drives(drive)
    duration = _duration(duration_s)
    if not isinstance(sample_rate_hz, int) or isinstance(sample_rate_hz, bool) or sample_rate_hz <= 0:
        raise SignalError("<sample rate>", f"WAV needs a whole positive number of Hz, got {sample_rate_hz!r}")
    x = _signals(drives, duration, sample_rate_hz)
    pcm = np.round(np.clip(x, 0.0, 1.0) * 32767).astype("<i2")
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(len(drives))
        w.setsampwidth(2)
        w.setframerate(sample_rate_hz)
        w.writeframes(pcm.tobytes())
    return buf.getvalue()


def csv_bytes(
    drive: Drive | Sequence[Drive],
    duration_s: float = 2.0,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
) -> bytes:
    """The samples as CSV: ``time_s`` then one column per channel (``channel_0``...)."""
    drives = _drives(drive)
    duration = _duration(duration_s)
    x = _signals(drives, duration, sample_rate_hz)
    t = np.arange(x.shape[0]) / float(sample_rate_hz)
    buf = io.StringIO(newline="")
    wr = csv.writer(buf)
    wr.writerow(["time_s"] + [f"channel_{i}" for i in range(len(drives))])
    # repr-exact times, compact sample values
    wr.writerows([f"{ti:.9g}"] + [f"{v:.6g}" for v in row] for ti, row in zip(t, x.tolist()))
    return buf.getvalue().encode("utf-8")


def export_wav(
    drive: Drive | Sequence[Drive],
    path: str | Path,
    duration_s: float = 2.0,
    sample_rate_hz: int = DEFAULT_SAMPLE_RATE_HZ,
) -> Path:
    """Write :func:`wav_bytes` to ``path``."""
    return _write(path, wav_bytes(drive, duration_s, sample_rate_hz))


def export_csv(
    drive: Drive | Sequence[Drive],
    path: str | Path,
    duration_s: float = 2.0,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
) -> Path:
    """Write :func:`csv_bytes` to ``path``."""
    return _write(path, csv_bytes(drive, duration_s, sample_rate_hz))


def _write(path: str | Path, data: bytes) -> Path:
    p = _open_for_write(path)
    try:
        p.write_bytes(data)
    except OSError as exc:
        raise SignalError(str(path), f"cannot write ({exc.strerror or exc})") from None
    return p


def drive_document(drive: Drive | Sequence[Drive], duration_s: float = 2.0, **extra: Any) -> dict[str, Any]:
    """The drive parameters as a JSON-ready document (SI units), plus anything in ``extra``."""
    drives = _drives(drive)
    return {
        "format": "tactilize-drive",
        "version": 1,
        "duration_s": _duration(duration_s),
        "channels": [d.to_dict() for d in drives],
        **extra,
    }


def export_json(drive: Drive | Sequence[Drive], path: str | Path, duration_s: float = 2.0, **extra: Any) -> Path:
    """Write :func:`drive_document` as JSON."""
    return _write(path, _json_bytes(drive_document(drive, duration_s, **extra), path))


def _json_bytes(doc: Any, source: Any) -> bytes:
    try:
        return (json.dumps(doc, indent=2, allow_nan=False) + "\n").encode("utf-8")
    except ValueError:
        raise SignalError(str(source), "a value is not finite (JSON has no NaN)") from None


# --------------------------------------------------------------------------- phones


def sharpness_from_frequency(frequency_hz: float) -> float:
    """AHAP sharpness in [0, 1] for a vibration frequency [Hz]: linear over 65..300 Hz, clipped."""
    s = (frequency_hz - SHARPNESS_LOW_HZ) / (SHARPNESS_HIGH_HZ - SHARPNESS_LOW_HZ)
    return min(1.0, max(0.0, s))


def intensity_from_drive(drive: Drive) -> float:
    """Intensity in [0, 1]: the fundamental of the pulse train relative to ``FULL_INTENSITY_DUTY``.

    A rectangular train of duty D and height A has a fundamental of amplitude
    (2 A / pi) sin(pi D); an LRA or phone motor passes mostly that.
    """
    if drive.is_off:
        return 0.0
    d = min(drive.duty_ratio, 0.5)
    return min(1.0, drive.amplitude * math.sin(math.pi * d) / math.sin(math.pi * FULL_INTENSITY_DUTY))


def _pulse_edges_ms(drive: Drive, duration_s: float) -> list[tuple[float, float]]:
    """(start, end) of every pulse starting within the duration [ms], exact."""
    out = []
    k = 0
    while True:
        t = k * drive.period_s
        if t >= duration_s - 1e-12:
            return out
        out.append((t * 1e3, min(t + drive.pulse_width_s, duration_s) * 1e3))
        k += 1


def ahap_pattern(drive: Drive, duration_s: float = 2.0) -> dict[str, Any]:
    """The AHAP document (a dict) for a steady drive (see the module docstring)."""
    duration = _duration(duration_s)
    events: list[dict[str, Any]] = []
    curves: list[dict[str, Any]] = []
    intensity = intensity_from_drive(drive)
    sharpness = sharpness_from_frequency(drive.pulse_frequency_hz)
    if drive.is_off:
        pass
    elif drive.pulse_frequency_hz < SHARPNESS_LOW_HZ:
        # One tap per pulse: its intensity is the pulse height (the duty does not
        # reduce a single tap); sharpness from the pulse's own bandwidth, 1 / width.
        tap_sharpness = sharpness_from_frequency(1.0 / max(drive.pulse_width_s, 1e-6))
        for start_ms, _ in _pulse_edges_ms(drive, duration):
            events.append(
                {
                    "Event": {
                        "Time": round(start_ms / 1e3, 6),
                        "EventType": "HapticTransient",
                        "EventParameters": [
                            {"ParameterID": "HapticIntensity", "ParameterValue": round(drive.amplitude, 4)},
                            {"ParameterID": "HapticSharpness", "ParameterValue": round(tap_sharpness, 4)},
                        ],
                    }
                }
            )
    else:
        t = 0.0
        while t < duration - 1e-9:
            d = min(AHAP_MAX_EVENT_S, duration - t)
            events.append(
                {
                    "Event": {
                        "Time": round(t, 6),
                        "EventType": "HapticContinuous",
                        "EventDuration": round(d, 6),
                        "EventParameters": [
                            {"ParameterID": "HapticIntensity", "ParameterValue": round(intensity, 4)},
                            {"ParameterID": "HapticSharpness", "ParameterValue": round(sharpness, 4)},
                        ],
                    }
                }
            )
            t += d
        # Control curves at full scale: hosts that scale a pattern (e.g. with the
        # stroke speed) edit these points instead of the events.
        curves = [
            {
                "ParameterCurve": {
                    "ParameterID": pid,
                    "Time": 0.0,
                    "ParameterCurveControlPoints": [
                        {"Time": 0.0, "ParameterValue": 1.0},
                        {"Time": round(duration, 6), "ParameterValue": 1.0},
                    ],
                }
            }
            for pid in ("HapticIntensityControl", "HapticSharpnessControl")
        ]
    return {
        "Version": 1.0,
        "Metadata": {
            "Project": "tactilize",
            "Description": (
                f"pulse train {drive.pulse_frequency_hz:g} Hz, width {drive.pulse_width_s * 1e3:g} ms, "
                f"amplitude {drive.amplitude:g}, {duration:g} s"
            ),
        },
        "Pattern": events + curves,
    }


def export_ahap(drive: Drive, path: str | Path, duration_s: float = 2.0) -> Path:
    """Write :func:`ahap_pattern` as an ``.ahap`` (JSON) file."""
    return _write(path, render(drive, "ahap", duration_s))


def android_waveform(drive: Drive, duration_s: float = 2.0) -> dict[str, Any]:
    """Arguments for Android's ``VibrationEffect.createWaveform`` (see the module docstring).

    Returns
    -------
    dict
        ``timings_ms`` (whole ms), ``amplitudes`` (0..255, one per timing),
        ``repeat`` (-1: play once), ``envelope`` (API 36 control points), and
        the drive for reference.
    """
    duration = _duration(duration_s)
    total_ms = int(round(duration * 1e3))
    timings: list[int] = []
    amps: list[int] = []
    if drive.is_off:
        timings, amps = [total_ms], [0]
    elif drive.pulse_frequency_hz < SHARPNESS_LOW_HZ:
        level = max(1, int(round(255 * drive.amplitude)))
        cursor = 0
        for start_ms, end_ms in _pulse_edges_ms(drive, duration):
            s = int(round(start_ms))
            # A pulse shorter than 1 ms still plays for 1 ms: the finest Android allows.
            e = max(s + 1, int(round(end_ms)))
            if s > cursor:
                timings.append(s - cursor)
                amps.append(0)
            if e > s and s >= cursor:
                timings.append(e - s)
                amps.append(level)
                cursor = e
        if total_ms > cursor:
            timings.append(total_ms - cursor)
            amps.append(0)
    else:
        level = int(round(255 * intensity_from_drive(drive)))
        timings, amps = [total_ms], [level]
    envelope = [] if drive.is_off else [
        {
            "amplitude": round(intensity_from_drive(drive), 4),
            "frequency_hz": round(drive.pulse_frequency_hz, 3),
            "duration_ms": total_ms,
        }
    ]
    return {
        "timings_ms": timings,
        "amplitudes": amps,
        "repeat": -1,
        "envelope": envelope,
        "drive": drive.to_dict(),
    }


def export_android(drive: Drive, path: str | Path, duration_s: float = 2.0) -> Path:
    """Write :func:`android_waveform` as JSON."""
    return _write(path, render(drive, "android", duration_s))


def _one(drive: Drive | Sequence[Drive]) -> Drive:
    """Phone formats play one actuator: a single drive, or the first of a list."""
    if isinstance(drive, Drive):
        return drive
    drives = _drives(drive)
    return drives[0]


@dataclass(frozen=True)
class ExportFormat:
    """One file format: its name, file suffix, media type and how to make its bytes.

    ``render(drive, duration_s, sample_rate_hz, extra) -> bytes``.
    """

    name: str
    suffix: str
    media_type: str
    render: Callable[[Any, float, int, dict[str, Any]], bytes]
    description: str


#: Every export format, by name: the CLI, :func:`export` and the catalog's HTTP API read this.
FORMATS: dict[str, ExportFormat] = {
    f.name: f
    for f in (
        ExportFormat("wav", ".wav", "audio/wav", lambda d, t, fs, x: wav_bytes(d, t, fs),
                     "16-bit PCM pulse train, one channel per drive"),
        ExportFormat("csv", ".csv", "text/csv", lambda d, t, fs, x: csv_bytes(d, t, fs),
                     "the samples: time_s, channel_0, ..."),
        ExportFormat("json", ".json", "application/json",
                     lambda d, t, fs, x: _json_bytes(drive_document(d, t, **x), "<json>"),
                     "the drive parameters in SI units"),
        ExportFormat("ahap", ".ahap", "application/json",
                     lambda d, t, fs, x: _json_bytes(ahap_pattern(_one(d), t), "<ahap>"),
                     "Apple Core Haptics pattern"),
        ExportFormat("android", ".json", "application/json",
                     lambda d, t, fs, x: _json_bytes(android_waveform(_one(d), t), "<android>"),
                     "Android VibrationEffect waveform and API 36 envelope"),
    )
}


def export_format(fmt: str) -> ExportFormat:
    """The :class:`ExportFormat` named ``fmt`` (any case)."""
    key = str(fmt).strip().lower()
    if key not in FORMATS:
        raise SignalError(str(fmt), f"unknown export format (use one of: {', '.join(FORMATS)})")
    return FORMATS[key]


def render(
    drive: Drive | Sequence[Drive],
    fmt: str,
    duration_s: float = 2.0,
    *,
    sample_rate_hz: int = DEFAULT_SAMPLE_RATE_HZ,
    **extra: Any,
) -> bytes:
    """The bytes of ``drive`` in format ``fmt`` (see :data:`FORMATS`); ``extra`` goes into JSON."""
    return export_format(fmt).render(drive, duration_s, sample_rate_hz, extra)


def export(drive: Drive | Sequence[Drive], path: str | Path, fmt: str, duration_s: float = 2.0, **extra: Any) -> Path:
    """Write ``drive`` in format ``fmt`` (one of :data:`FORMATS`); ``extra`` goes into JSON."""
    data = render(drive, fmt, duration_s, **extra)
    return _write(path, data)
