"""Steady drives as files: WAV, sample CSV and the drive document (JSON).

These take a :class:`~tactilize.drive.Drive` (or a list, one per channel), so
a batch over a catalog needs no image.  No SMA envelope is applied here.
"""

from __future__ import annotations

import csv
import io
import json
import wave
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..drive import Drive
from ..errors import SignalError, check_finite, check_output_path
from ..synthesis import DEFAULT_SAMPLE_RATE_HZ, pulse_train

__all__ = ["wav_bytes", "csv_bytes", "drive_document", "export_wav", "export_csv", "export_json", "pcm_wav"]


def _drives(drive: Drive | Sequence[Drive]) -> list[Drive]:
    drives = [drive] if isinstance(drive, Drive) else list(drive)
    if not drives or not all(isinstance(d, Drive) for d in drives):
        raise SignalError("<drive>", "expected a Drive or a list of Drives")
    return drives


def _duration(duration_s: float) -> float:
    return check_finite(duration_s, "<duration>", error=SignalError, above=0.0, unit="s")


def _open_for_write(path: str | Path) -> Path:
    return check_output_path(path, SignalError)


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
    _check_wav_rate(sample_rate_hz)
    return pcm_wav(_signals(drives, duration, sample_rate_hz), sample_rate_hz)


def _check_wav_rate(sample_rate_hz: Any) -> None:
    """A WAV's rate is a whole positive number of Hz (checked before any signal is made)."""
    if not isinstance(sample_rate_hz, int) or isinstance(sample_rate_hz, bool) or sample_rate_hz <= 0:
        raise SignalError("<sample rate>", f"WAV needs a whole positive number of Hz, got {sample_rate_hz!r}")


def pcm_wav(x: np.ndarray, sample_rate_hz: int, *, signed: bool = False) -> bytes:
    """16-bit PCM WAV bytes of samples ``x`` (n, channels) in [0, 1] (1 is full scale, 32767),
    or in [-1, 1] when ``signed`` (an acceleration: :mod:`.wav`).

    Raises
    ------
    SignalError
        ``sample_rate_hz`` is not a whole positive number of Hz.
    """
    _check_wav_rate(sample_rate_hz)
    pcm = np.round(np.clip(x, -1.0 if signed else 0.0, 1.0) * 32767).astype("<i2")
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(int(x.shape[1]))
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
