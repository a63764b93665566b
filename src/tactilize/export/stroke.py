"""A stroke in, drive over time out: the pen server's path, offline.

A stroke file is CSV (a header ``t_s,x_mm,y_mm[,pressure]``) or JSON (a list of
``{"t_s", "x_mm", "y_mm", "pressure"?}`` objects, or ``{"samples": [...]}``
of those or of ``[t_s, x_mm, y_mm, pressure?]`` rows).  Positions are
millimetres from the picture's top-left corner, y down, as the page records
them.  :func:`read_stroke` refuses an empty stroke, times that do not increase,
values that are not finite and points outside the picture, in one line.

:func:`run_stroke` feeds the samples, a display frame at a time (as the page
sends them), along the one whole-stroke path (:func:`tactilize.surface.playback.play_stroke`)
with a :class:`tactilize.pen.PenRenderer`'s tracker, texture map, profile's rendering, and
output (by default the simulated SMA wire, advanced by the stroke's own clock, not the wall
clock), and records one row per frame: a :class:`~.timeline.DriveTimeline`, whose events are
those the rendering fired.  The renderer is asked
to send every frame's drive (``resend_rel=0``): on the server a drive within
0.5 % of the last is skipped for up to 0.1 s of *wall-clock* time, which an
offline run would make depend on the machine's speed.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Sequence

from ..errors import SignalError
from ..pen import PenRenderer, PenSample
from ..surface.playback import play_stroke
from .timeline import DriveTimeline

if TYPE_CHECKING:  # types only: the export package loads none of them until a stroke runs
    import numpy as np

    from ..actuators.base import Output
    from ..drive import Drive
    from ..features import TextureFeatures
    from ..maps import FeatureLookup
    from ..mapping import Profile
    from ..surface import SurfaceModel

__all__ = ["Stroke", "read_stroke", "parse_stroke", "synthetic_stroke", "run_stroke", "stroke_csv", "stroke_json"]

#: Display frame the page batches samples by [s] (60 Hz).
FRAME_S = 1.0 / 60.0
#: Sample rate of a synthetic stroke [Hz] (a pen tablet's).
SYNTHETIC_RATE_HZ = 240.0
#: Time a synthetic stroke is already moving before the export starts [s], so
#: the tracker knows its speed at t = 0 (the fit window is 30 ms).
PREROLL_S = 0.1
#: Longest stroke accepted [s].
MAX_STROKE_S = 600.0


class StrokeError(SignalError):
    """A stroke file that cannot be exported (empty, unsorted, not finite, outside the picture)."""


@dataclass(frozen=True)
class Stroke:
    """Pen samples in SI: times [s], positions [m] (y down), pressure in [0, 1] or None."""

    t_s: tuple[float, ...]
    x_m: tuple[float, ...]
    y_m: tuple[float, ...]
    pressure: tuple[float | None, ...]
    source: str = "<stroke>"

    def __len__(self) -> int:
        return len(self.t_s)

    def samples(self) -> list[PenSample]:
        return [PenSample(t, x, y, p) for t, x, y, p in zip(self.t_s, self.x_m, self.y_m, self.pressure)]


def _number(v: Any, source: str, i: int, name: str) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise StrokeError(source, f"sample {i + 1}: {name} is not a number ({v!r})") from None
    if not math.isfinite(x):
        raise StrokeError(source, f"sample {i + 1}: {name} is not a finite number ({v!r})")
    return x


def parse_stroke(rows: Sequence[Any], source: str, width_m: float | None = None, height_m: float | None = None) -> Stroke:
    """A :class:`Stroke` from rows ``[t_s, x_mm, y_mm, pressure?]`` or dicts, checked.

    Raises
    ------
    StrokeError
        Empty, a value that is not a finite number, times that do not increase,
        pressure outside [0, 1], a point outside ``width_m`` x ``height_m``.
    """
    if not rows:
        raise StrokeError(source, "the stroke is empty (no samples)")
    ts: list[float] = []
    xs: list[float] = []
    ys: list[float] = []
    ps: list[float | None] = []
    for i, row in enumerate(rows):
        if isinstance(row, dict):
            missing = [k for k in ("t_s", "x_mm", "y_mm") if k not in row]
            if missing:
                raise StrokeError(source, f"sample {i + 1}: missing {', '.join(missing)}")
            vals = [row["t_s"], row["x_mm"], row["y_mm"], row.get("pressure")]
        elif isinstance(row, (list, tuple)) and 3 <= len(row) <= 4:
            vals = list(row) + [None] * (4 - len(row))
        else:
            raise StrokeError(source, f"sample {i + 1}: expected t_s, x_mm, y_mm[, pressure]")
        t = _number(vals[0], source, i, "t_s")
        x = _number(vals[1], source, i, "x_mm") * 1e-3
        y = _number(vals[2], source, i, "y_mm") * 1e-3
        p = None if vals[3] in (None, "") else _number(vals[3], source, i, "pressure")
        if p is not None and not 0.0 <= p <= 1.0:
            raise StrokeError(source, f"sample {i + 1}: pressure must be in [0, 1], got {p:g}")
        if ts and t <= ts[-1]:
            raise StrokeError(source, f"sample {i + 1}: times must increase (t_s {t:g} after {ts[-1]:g})")
        if width_m is not None and height_m is not None and not (0.0 <= x < width_m and 0.0 <= y < height_m):
            raise StrokeError(
                source,
                f"sample {i + 1} at ({x * 1e3:g}, {y * 1e3:g}) mm is outside the picture "
                f"({width_m * 1e3:.1f} x {height_m * 1e3:.1f} mm)",
            )
        ts.append(t)
        xs.append(x)
        ys.append(y)
        ps.append(p)
    if ts[-1] - ts[0] > MAX_STROKE_S:
        raise StrokeError(source, f"the stroke lasts {ts[-1] - ts[0]:g} s (limit {MAX_STROKE_S:g} s)")
    return Stroke(tuple(ts), tuple(xs), tuple(ys), tuple(ps), source)


def read_stroke(path_or_text: str | Path | bytes, width_m: float | None = None, height_m: float | None = None,
                *, source: str | None = None) -> Stroke:
    """Read a stroke file (CSV or JSON, told apart by content), checked against the picture.

    Parameters
    ----------
    path_or_text : str, Path or bytes
        A file path, or the file's bytes.
    width_m, height_m : float, optional
        The picture's displayed size [m]; every point must lie on it.
    source : str, optional
        How errors name the input (default: the path, or ``<stroke>``).
    """
    if isinstance(path_or_text, (bytes, bytearray)):
        data, src = bytes(path_or_text), source or "<stroke>"
    else:
        src = source or str(path_or_text)
        try:
            data = Path(path_or_text).read_bytes()
        except OSError as exc:
            raise StrokeError(src, f"cannot read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise StrokeError(src, "not a text file (expected CSV or JSON)") from None
    stripped = text.strip()
    if not stripped:
        raise StrokeError(src, "the stroke is empty (no samples)")
    if stripped[0] in "[{":
        try:
            doc = json.loads(stripped)
        except ValueError as exc:
            raise StrokeError(src, f"not valid JSON ({exc})") from None
        rows = doc.get("samples") if isinstance(doc, dict) else doc
        if not isinstance(rows, list):
            raise StrokeError(src, "JSON must be a list of samples or {\"samples\": [...]}")
        return parse_stroke(rows, src, width_m, height_m)
    reader = csv.reader(io.StringIO(stripped))
    header = [h.strip().lower() for h in next(reader)]
    if header[:3] != ["t_s", "x_mm", "y_mm"] or len(header) > 4 or (len(header) == 4 and header[3] != "pressure"):
        raise StrokeError(src, f"CSV header must be t_s,x_mm,y_mm[,pressure], got {','.join(header)}")
    rows = [r for r in reader if r and any(c.strip() for c in r)]
    rows = [dict(zip(header, (c.strip() for c in r))) if len(r) == len(header) else r for r in rows]
    return parse_stroke(rows, src, width_m, height_m)


def stroke_csv(stroke: Stroke) -> bytes:
    """The stroke as the CSV file :func:`read_stroke` reads."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(["t_s", "x_mm", "y_mm", "pressure"])
    for t, x, y, p in zip(stroke.t_s, stroke.x_m, stroke.y_m, stroke.pressure):
        w.writerow([f"{t:.6f}", f"{x * 1e3:.4f}", f"{y * 1e3:.4f}", "" if p is None else f"{p:.4f}"])
    return buf.getvalue().encode("utf-8")


def stroke_json(stroke: Stroke) -> bytes:
    """The stroke as the JSON file :func:`read_stroke` reads."""
    rows = [
        {"t_s": t, "x_mm": x * 1e3, "y_mm": y * 1e3, "pressure": p}
        for t, x, y, p in zip(stroke.t_s, stroke.x_m, stroke.y_m, stroke.pressure)
    ]
    return (json.dumps({"samples": rows}, indent=1) + "\n").encode("utf-8")


def synthetic_stroke(width_m: float, height_m: float, speed_m_s: float, duration_s: float,
                     direction_deg: float = 0.0, rate_hz: float = SYNTHETIC_RATE_HZ) -> Stroke:
    """A steady straight stroke from the picture's centre, as a :class:`Stroke`.

    The samples are :func:`tactilize.surface.straight.straight_stroke`'s (its
    rule at the edges: the line runs on past them and the picture is read
    mirrored, which :func:`run_stroke` does with ``mirror=True``).  It starts
    :data:`PREROLL_S` early (negative times; :func:`run_stroke` drops them).

    Parameters
    ----------
    width_m, height_m : float
        The picture's size where shown [m].
    speed_m_s : float
        Speed [m/s].
    duration_s : float
        Length after time 0 [s].
    direction_deg : float
        Direction [deg] counter-clockwise from +x with y up, as everywhere in tactilize.
    rate_hz : float
        Sample rate [Hz].
    """
    from ..surface.straight import straight_stroke

    t, x, y = straight_stroke(width_m, height_m, speed_m_s, math.radians(direction_deg), duration_s, rate_hz,
                              preroll_s=PREROLL_S)
    return Stroke(tuple(t.tolist()), tuple(x.tolist()), tuple(y.tolist()), (None,) * len(t), "<synthetic stroke>")


class _Mirrored:
    """A texture map continued beyond its edges by mirror images of itself."""

    def __init__(self, tmap: FeatureLookup) -> None:
        from ..surface.straight import MirroredSurface

        self.tmap = tmap
        self.w, self.h = MirroredSurface.folded_size(tmap.width_m, tmap.height_m)

    def lookup(self, x_m: float, y_m: float) -> TextureFeatures | None:
        from ..surface.straight import fold_into

        return self.tmap.lookup(float(fold_into(x_m, self.w)), float(fold_into(y_m, self.h)))


def _same_drive(drive: Drive, n: int, state: Any) -> list[Drive]:
    return [drive] * n


def run_stroke(stroke: Stroke, texture_map: FeatureLookup, profile: Profile,
               output: Output | Literal["simulated"] | None = "simulated", *,
               frame_s: float = FRAME_S, start_s: float | None = None, end_s: float | None = None,
               meta: dict[str, Any] | None = None, mirror: bool = False,
               surface: SurfaceModel | None = None) -> DriveTimeline:
    """Render ``stroke`` on ``texture_map`` as the pen server does; the drive per frame.

    Parameters
    ----------
    stroke : Stroke
    texture_map : TextureMap
        The picture at its displayed size.
    profile : Profile
    output : Output, "simulated" or None
        Where drives go: by default a fresh simulated SMA wire (two channels,
        advanced by the stroke's clock); None records the profile's drive only.
    frame_s : float
        Samples are fed in batches of one display frame [s].
    start_s : float, optional
        Rows before this time are dropped (a synthetic stroke's run-up); by
        default the stroke's first sample.
    end_s : float, optional
        Length of the result [s] from ``start_s``; by default one frame after
        the last sample.
    meta : dict, optional
        Kept in the result (image, profile...) for the documents.
    mirror : bool
        Continue the picture beyond its edges with mirror images (for a
        synthetic stroke longer than the picture).
    surface : SurfaceModel, optional
        The picture as a surface, for a profile whose rendering is ``surface``
        (docs/surfaces.md): the simulated wire plays its pulse events, the
        rows hold the equivalent drive of each frame's window, and the result's
        ``events`` the events the rendering fired (:func:`.events.bump_events`), which the
        parametric formats play.
    """
    from ..actuators.recording import RecordingOutput

    owned = False
    out: Output
    if output == "simulated":
        from ..actuators.simulated import SimulatedOutput

        out, owned = SimulatedOutput(start=False, trace_seconds=0.5, trace_rate_hz=1000.0), True
    elif output is None:
        out = RecordingOutput()
    elif isinstance(output, str):
        raise ValueError(f"output must be an Output, 'simulated' or None, got {output!r}")
    else:
        out = output
    # Both channels get the profile's drive, as on the SMA wire (the phantom
    # split of audio outputs would leave one channel of a phone file silent).
    from ..surface.straight import MirroredSurface

    felt: SurfaceModel | MirroredSurface | None = surface
    if surface is not None and mirror:
        felt = MirroredSurface(surface)
    renderer = PenRenderer(_Mirrored(texture_map) if mirror else texture_map, profile, out, resend_rel=0.0,
                           splitter=_same_drive, surface=felt)
    samples = stroke.samples()
    origin = samples[0].t_s if start_s is None else start_s
    rows: list[tuple[float, tuple, tuple, float, float, float]] = []
    advance = getattr(out, "advance", None)
    clock = [samples[0].t_s]
    irregular = [False]  # a frame's events were not its drive's regular train

    def show(batch: list[Any], state: Any, features: Any, frame: Any, arrival_s: float) -> None:
        # The output's clock follows the stroke's, batch by batch (the wire plays what is due).
        t = batch[-1].t_s
        if advance is not None and t > clock[0]:
            advance(t - clock[0])
        clock[0] = t
        irregular[0] = irregular[0] or (frame is not None and not frame.regular)
        res = renderer.show(state, features, frame)
        st = res.state
        rows.append((t - origin, tuple(res.requested), tuple(res.applied),
                     st.speed_m_s if st else 0.0, st.x_m if st else math.nan, st.y_m if st else math.nan))

    try:
        # The one whole-stroke path, with the renderer's rendering, tracker and picture: the
        # events it fired are the ones the wire column played.
        played = play_stroke(renderer.rendering, samples, renderer.texture_map, batch_s=frame_s, transport_s=0.0,
                             tracker=renderer.tracker, on_frame=show)
        renderer.lift()
    finally:
        if owned:
            out.close()
    end = samples[-1].t_s - origin + frame_s if end_s is None else float(end_s)
    kept = [r for r in rows if 0.0 <= r[0] < end]
    if not kept or kept[0][0] > 0.0:
        # the row in force at the origin starts the timeline
        before = [r for r in rows if r[0] < 0.0]
        if before:
            kept.insert(0, (0.0, *before[-1][1:]))
        else:
            kept[0] = (0.0, *kept[0][1:])
    # rows of the same time (a frame's last sample repeated) keep the last
    dedup: dict[float, tuple] = {}
    for r in kept:
        dedup[r[0]] = r
    kept = sorted(dedup.values(), key=lambda r: r[0])
    events = None
    if irregular[0]:
        from .events import bump_events

        # The events the stroke's rendering fired, when they are not its drives' regular trains
        # (those the formats read from the rows, DriveTimeline.pulses).
        events = bump_events(played.events, stroke, felt, origin_s=origin, end_s=end)
    return DriveTimeline(
        tuple(r[0] for r in kept), end,
        tuple(r[1] for r in kept), tuple(r[2] for r in kept),
        tuple(r[3] for r in kept), tuple(r[4] for r in kept), tuple(r[5] for r in kept),
        {"samples": len(stroke), "source": stroke.source, **(meta or {})},
        events,
    )
