"""The one registry of export formats: name, suffix, media type, and how to make the bytes.

Every format renders a *source*: a :class:`~tactilize.drive.Drive` (or a list,
one per channel) held for a duration, or a :class:`~.timeline.DriveTimeline`
made from a stroke (:func:`~.stroke.run_stroke`).  AHAP, Android, ``.hjif``
and ``.haptic`` documents pass their validator (:mod:`.conformance`) or are
refused with a :class:`~.conformance.ConformanceError`.  The CLI, :func:`export`,
the catalog's HTTP API and the pen page's stroke export all read
:data:`FORMATS`.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

from ..drive import Drive
from ..errors import SignalError
from ..synthesis import DEFAULT_SAMPLE_RATE_HZ
from .ahap import ahap_document
from .android import android_document
from .conformance import validate
from .haptic import haptic_document
from .hjif import hjif_document
from .steady import _drives, _json_bytes, _write, csv_bytes, drive_document, pcm_wav, wav_bytes
from .timeline import DriveTimeline
from .wav import StrokeAcceleration

__all__ = ["ExportFormat", "FORMATS", "export_format", "render", "export", "drive_log_csv", "drive_log_document"]

Source = Any  # Drive | Sequence[Drive] | DriveTimeline


def _timeline(src: Source, duration_s: float) -> DriveTimeline:
    return src if isinstance(src, DriveTimeline) else DriveTimeline.steady(_drives(src), duration_s)


def _one(src: Source, duration_s: float) -> DriveTimeline:
    """Phone formats play one actuator: a single drive, the first of a list, or channel 0 of a timeline."""
    if isinstance(src, DriveTimeline):
        return src
    return DriveTimeline.steady(_drives(src)[0], duration_s)


def drive_log_document(tl: DriveTimeline, kind: str = "profile", **extra: Any) -> dict[str, Any]:
    """The drive log as a JSON-ready document: one row per drive change (SI units)."""
    return {
        "format": "tactilize-drive-log",
        "version": 1,
        "duration_s": tl.end_s,
        "drive": kind,
        "channels": tl.channels,
        "rows": tl.log_rows(kind),
        **extra,
    }


def drive_log_csv(tl: DriveTimeline, kind: str = "profile") -> bytes:
    """The drive log as CSV: one row per drive change, ``t_s, speed_m_s, x_m, y_m`` then per channel."""
    rows = tl.log_rows(kind)
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(list(rows[0]))
    for r in rows:
        w.writerow(["" if v is None else v if isinstance(v, str) else f"{v:.9g}" for v in r.values()])
    return buf.getvalue().encode("utf-8")


def _samples_csv(tl: DriveTimeline, fs: int, kind: str) -> bytes:
    x = tl.samples(fs, kind)
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(["time_s"] + [f"channel_{i}" for i in range(x.shape[1])])
    w.writerows([f"{i / fs:.9g}"] + [f"{v:.6g}" for v in row] for i, row in enumerate(x.tolist()))
    return buf.getvalue().encode("utf-8")


def _wav(src: Source, t: float, fs: int, kind: str, x: dict[str, Any]) -> bytes:
    if isinstance(src, StrokeAcceleration):  # a stroke on a surface: the tip's acceleration
        return pcm_wav(src.samples(fs)[0], fs, signed=True)
    if isinstance(src, DriveTimeline):
        return pcm_wav(src.samples(fs, kind), fs)
    return wav_bytes(src, t, fs)


def _csv(src: Source, t: float, fs: int, kind: str, x: dict[str, Any]) -> bytes:
    return _samples_csv(src, fs, kind) if isinstance(src, DriveTimeline) else csv_bytes(src, t, fs)


def _json(src: Source, t: float, fs: int, kind: str, x: dict[str, Any]) -> bytes:
    if isinstance(src, DriveTimeline):
        return _json_bytes(drive_log_document(src, kind, **x), "<json>")
    return _json_bytes(drive_document(src, t, **x), "<json>")


def _doc(fn: Callable[..., dict[str, Any]], name: str, one: bool = True) -> Callable[..., bytes]:
    # Every document is held to its format's rules before it is written: a
    # drive the format cannot carry is refused here, not by a player later.
    def render_doc(src: Source, t: float, fs: int, kind: str, x: dict[str, Any]) -> bytes:
        tl = _one(src, t) if one else _timeline(src, t)
        return _json_bytes(validate(fn(tl, kind), name), f"<{name}>")

    return render_doc


@dataclass(frozen=True)
class ExportFormat:
    """One file format: its name, file suffix, media type and how to make its bytes.

    ``render(source, duration_s, sample_rate_hz, drive_kind, extra) -> bytes``.
    """

    name: str
    suffix: str
    media_type: str
    render: Callable[[Any, float, int, str, dict[str, Any]], bytes]
    description: str
    carries_frequency: bool = False
    #: How a file name made for this format ends (``stroke-corduroy`` + it): the
    #: suffix, marked where two formats share one, so that downloads of one stroke
    #: in every format never overwrite each other (nor the stroke's own CSV).
    name_tail: str = ""

    @property
    def file_tail(self) -> str:
        """The end of a file name made for this format: :attr:`name_tail` or the suffix."""
        return self.name_tail or self.suffix


#: Every export format, by name.
FORMATS: dict[str, ExportFormat] = {
    f.name: f
    for f in (
        ExportFormat("wav", ".wav", "audio/wav", _wav, "16-bit PCM, 48 kHz, one channel per actuator: the pulse train, or on a "
                     "surface the tip's acceleration"),
        ExportFormat("csv", ".csv", "text/csv", _csv, "the samples: time_s, channel_0, ...", name_tail="-signal.csv"),
        ExportFormat("json", ".json", "application/json", _json,
                     "the drive in SI units (a stroke: the drive log, one row per change)"),
        ExportFormat("log", ".csv", "text/csv",
                     lambda s, t, fs, k, x: drive_log_csv(_timeline(s, t), k),
                     "the drive log as CSV, one row per drive change", name_tail="-log.csv"),
        ExportFormat("ahap", ".ahap", "application/json", _doc(ahap_document, "ahap"),
                     "Apple Core Haptics pattern", True),
        ExportFormat("android", ".json", "application/json", _doc(android_document, "android"),
                     "Android API 36 envelopes and the createWaveform fallback", True, name_tail=".android.json"),
        ExportFormat("hjif", ".hjif", "application/json", _doc(hjif_document, "hjif", one=False),
                     "MPEG-I Haptics (ISO/IEC 23090-31), JSON form", True),
        ExportFormat("haptic", ".haptic", "application/json", _doc(haptic_document, "haptic"),
                     "Meta Haptics amplitude and frequency envelopes", True),
    )
}


def export_format(fmt: str) -> ExportFormat:
    """The :class:`ExportFormat` named ``fmt`` (any case)."""
    key = str(fmt).strip().lower()
    if key not in FORMATS:
        raise SignalError(str(fmt), f"unknown export format (use one of: {', '.join(FORMATS)})")
    return FORMATS[key]


def render(
    source: Drive | Sequence[Drive] | DriveTimeline,
    fmt: str,
    duration_s: float = 2.0,
    *,
    sample_rate_hz: int = DEFAULT_SAMPLE_RATE_HZ,
    drive: str = "profile",
    **extra: Any,
) -> bytes:
    """The bytes of ``source`` in format ``fmt`` (see :data:`FORMATS`).

    Parameters
    ----------
    source : Drive, list of Drive, or DriveTimeline
        A steady drive (held ``duration_s`` [s]) or drive over time.
    fmt : str
    duration_s : float
        Length of a steady export [s]; a timeline has its own.
    sample_rate_hz : int
        For WAV and CSV [Hz].
    drive : {"profile", "wire"}
        Which drive of a timeline (:mod:`.timeline`); steady drives have one.
    extra
        Goes into the JSON documents.
    """
    if drive not in ("profile", "wire"):
        raise SignalError(str(drive), "unknown drive (use 'profile' or 'wire')")
    return export_format(fmt).render(source, duration_s, sample_rate_hz, drive, extra)


def export(source: Any, path: str | Path, fmt: str, duration_s: float = 2.0, **extra: Any) -> Path:
    """Write ``source`` in format ``fmt`` (one of :data:`FORMATS`) to ``path``."""
    data = render(source, fmt, duration_s, **extra)
    return _write(path, data)
