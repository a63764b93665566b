"""Write drives to files other rigs, phones and players play; read some of them back.

A drive is exported steady (one :class:`~tactilize.drive.Drive` per channel,
held for a duration: what a catalog needs, no image) or over time, from a
stroke run through the pen server's path (:func:`run_stroke`).  One module
per concern:

:mod:`.registry`   the one registry of formats (:data:`FORMATS`, :func:`render`, :func:`export`)
:mod:`.timeline`   :class:`DriveTimeline`, the control grid, intensity and sharpness
:mod:`.events`     a surface stroke's bumps: a transient each, or a continuous stretch where they come too fast
:mod:`.stroke`     stroke files (CSV/JSON), synthetic strokes, :func:`run_stroke`
:mod:`.steady`     WAV, sample CSV and the drive document of steady drives
:mod:`.ahap`       Apple Core Haptics
:mod:`.android`    Android API 36 envelopes and ``createWaveform``; :mod:`.android_events` the compositions of bumps
:mod:`.hjif`       MPEG-I Haptics (ISO/IEC 23090-31), ``.hjif``
:mod:`.haptic`     Meta Haptics ``.haptic``
:mod:`.readers`    AHAP, ``.hjif`` and ``.haptic`` back to drive over time
:mod:`.conformance` the rules of AHAP, Android, ``.hjif`` and ``.haptic`` (``check``, ``validate``)

No SMA envelope is applied to a steady drive: these files are for other
actuators (voice coils, LRAs, phone motors).  A stroke's timeline holds both
the profile's drive and what the simulated wire applied (:mod:`.timeline`).

References
----------
.. [1] docs/references.md, section 6 (haptic file formats).
"""

from __future__ import annotations

from pathlib import Path

from ..drive import Drive
from .ahap import AHAP_MAX_CURVE_POINTS, AHAP_MAX_EVENT_S, ahap_document, ahap_pattern
from .android import ANDROID_LIMITS, android_document, android_waveform
from .events import BumpEvent, EventPlan, bump_events, plan_events
from .haptic import haptic_document
from .hjif import hjif_document
from .readers import HapticTrack, read_ahap, read_haptic, read_hjif
from .registry import FORMATS, ExportFormat, drive_log_csv, drive_log_document, export, export_format, render
from .steady import csv_bytes, drive_document, export_csv, export_json, export_wav, wav_bytes
from .stroke import Stroke, StrokeError, parse_stroke, read_stroke, run_stroke, stroke_csv, stroke_json, synthetic_stroke
from .timeline import (
    FULL_INTENSITY_DUTY,
    SHARPNESS_HIGH_HZ,
    SHARPNESS_LOW_HZ,
    ControlPoint,
    DriveTimeline,
    control_points,
    intensity_from_drive,
    sharpness_from_frequency,
)

__all__ = [
    "FORMATS", "ExportFormat", "export_format", "render", "export",
    "export_wav", "export_csv", "export_json", "export_ahap", "export_android",
    "wav_bytes", "csv_bytes", "drive_document", "drive_log_csv", "drive_log_document",
    "ahap_pattern", "ahap_document", "android_waveform", "android_document", "hjif_document", "haptic_document",
    "read_ahap", "read_hjif", "read_haptic", "HapticTrack",
    "DriveTimeline", "ControlPoint", "control_points",
    "BumpEvent", "EventPlan", "plan_events", "bump_events",
    "Stroke", "StrokeError", "read_stroke", "parse_stroke", "synthetic_stroke", "run_stroke", "stroke_csv", "stroke_json",
    "sharpness_from_frequency", "intensity_from_drive",
    "SHARPNESS_LOW_HZ", "SHARPNESS_HIGH_HZ", "FULL_INTENSITY_DUTY", "AHAP_MAX_EVENT_S", "AHAP_MAX_CURVE_POINTS",
    "ANDROID_LIMITS",
]


def export_ahap(drive: Drive, path: str | Path, duration_s: float = 2.0) -> Path:
    """Write the AHAP of a steady drive to ``path``."""
    return export(drive, path, "ahap", duration_s)


def export_android(drive: Drive, path: str | Path, duration_s: float = 2.0) -> Path:
    """Write the Android document of a steady drive to ``path``."""
    return export(drive, path, "android", duration_s)
