"""What reaches the board's pin over the serial link: ``tactilize profile report --serial``.

For each texture and speed, :func:`board_stroke` renders the profile's steady
straight stroke (:mod:`tactilize.surface.straight`, the stroke the rest of the
report measures) and plays it to the controller firmware on the virtual-time
board (:mod:`tactilize.boardhost.virtual_board`), along the host's own path:

- a ``surface`` profile: the stroke's pulse events handed over as the pen page's
  batches come (every :data:`BATCH_S`, each event once it is within the surface's
  look-ahead, :data:`~tactilize.surface.stroke.LOOKAHEAD_S`), each frame landing
  :data:`TRANSPORT_S` after its batch; the board's clock kept by PING/PONG
  (:class:`~tactilize.actuators.clock_sync.ClockSync`), every pulse planned by
  :func:`~tactilize.actuators.serial_events.plan_pulses` through the felt band,
  the safety envelope and the board's own limits, as
  :meth:`SerialOutput.play <tactilize.actuators.serial.SerialOutput.play>`
  does on a version 4 board;
- a steady profile: its drive through the same envelope, sent with SET (and
  heartbeats), as :meth:`SerialOutput.apply <tactilize.actuators.serial.SerialOutput.apply>` does.

Then it reads the pin: pulses per second that reached it, p50/p95 of
|pulse on the pin - rendered event| (and - true crossing, when the bumps are
known), and the board's counters (pulses fired, shortened or skipped by its
running heat estimate, late).  Simulated time: nothing waits on the wall clock,
every run gives the same figures, and the figures are the method's (host
planning, clock sync, the firmware's scheduling and heat gate), not the
machine's load; the real-time link over a pseudo-terminal is measured by
``bench/bench_surfaces.py --only serial``.

Units: SI (s, m, Hz); the board's microseconds where named ``_us``.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any, Sequence, cast

import numpy as np

from .drive import Drive

__all__ = ["board_stroke", "serial_report", "BATCH_S", "TRANSPORT_S"]

#: The pen page's batch period [s] (its samples reach the host in batches this long).
BATCH_S = 0.004
#: Host to board, each frame [s] (USB full speed, a frame or two).
TRANSPORT_S = 0.001
#: Board time [s] of stroke time 0 (after the handshake).
_ORIGIN_S = 0.1
#: A heartbeat this often while a steady drive plays [s] (the host's, well inside the board's 200 ms watchdog).
_HEARTBEAT_S = 0.05


def _host(board: Any, circuit: str) -> Any:
    """What SerialOutput knows of the board (envelope, planner, STATUS) and its make-safe rule."""
    from .actuators import frames as P
    from .actuators.serial import SerialOutput
    from .actuators.sma import Circuit, SafetyEnvelope, WireController, WireSpec

    board.send(P.Command.STATUS)
    status = P.decode_status([f for f in board.replies() if f.command == P.Command.STATUS_REPLY][-1].payload)
    spec = WireSpec.resolve(None)
    envelope = SafetyEnvelope(spec, Circuit.resolve(circuit, spec))
    host = SimpleNamespace(envelope=envelope, controller_status=status,
                           _planner=WireController(spec, envelope.circuit, envelope, closed_loop=False))
    # SerialOutput's own rule (felt band, envelope, the board's limits), not a copy of it.
    host.make_safe = lambda d: SerialOutput._make_safe(cast(Any, host), d)
    return host


def _pong(board: Any) -> Any:
    from .actuators import frames as P

    board.send(P.Command.PING, P.encode_ping(board.seq))
    return P.decode_pong([f for f in board.replies() if f.command == P.Command.PONG][-1].payload)


def _errors_ms(pulses_s: np.ndarray, targets_s: np.ndarray) -> dict[str, float | None]:
    """p50/p95 [ms] of |each pulse - the nearest target| (None without both)."""
    if pulses_s.size == 0 or targets_s.size == 0:
        return {"p50_ms": None, "p95_ms": None}
    e = np.min(np.abs(pulses_s[:, None] - targets_s[None, :]), axis=1) * 1e3
    return {"p50_ms": float(np.percentile(e, 50)), "p95_ms": float(np.percentile(e, 95))}


def board_stroke(profile: Any, speed_m_s: float, *, surface: Any = None, features: Any = None,
                 bumps: Any = None, circuit: str = "aa-resistor", duration_s: float | None = None) -> dict[str, Any]:
    """One steady straight stroke of ``profile`` played to the virtual board (module docstring).

    Parameters
    ----------
    profile : Profile
    speed_m_s : float
        Stroking speed [m/s].
    surface : SurfaceModel
        The picture's surface (a ``surface`` profile's stroke crosses it).
    features : object
        The picture's features (a steady profile's laws read them).
    bumps : BumpField, optional
        The surface's known bumps: errors against the true crossings too.
    circuit : str
        The circuit the board is configured for (its stored limits and the envelope).
    duration_s : float, optional
        The stroke's length [s]; :data:`~tactilize.surface.straight.STROKE_S` by default.

    Returns
    -------
    dict
        ``rendering``, ``rendered`` (events, or the drive's pulses over the stroke),
        ``rendered_per_s``, ``pulses`` (on channel 0's pin), ``pulses_per_s``,
        ``frequency_hz`` (a steady drive's, as sent), ``event_p50_ms``/``event_p95_ms``
        (|pin pulse - rendered event|), ``crossings``, ``crossing_p50_ms``/``crossing_p95_ms``
        (|pin pulse - true crossing|, with ``bumps``), ``fired``, ``shortened``,
        ``skipped``, ``late`` (the board's counters of scheduled pulses).
    """
    from .surface.straight import STROKE_S, MirroredSurface, fold_into
    from .boardhost.virtual_board import VirtualBoard

    duration = STROKE_S if duration_s is None else float(duration_s)
    surface_rendering = getattr(profile, "rendering", "steady") == "surface"
    with VirtualBoard(circuit=circuit) as board:
        host = _host(board, circuit)
        board.until(_ORIGIN_S - 0.01)
        if surface_rendering:
            if surface is None:
                raise ValueError("a surface profile's stroke needs the picture's surface")
            row, zero_s, events_s = _play_events(board, host, profile, surface, speed_m_s, duration)
        else:
            row, zero_s, events_s = _play_steady(board, host, profile, features, speed_m_s, duration)
        board.until(zero_s + duration + 0.05)
        counts = _pong(board).counts[0]
        pins = np.array(board.pulse_starts_us(0)) / 1e6
    inside = pins[(pins >= zero_s - 0.005) & (pins < zero_s + duration)]
    row.update(pulses=int(inside.size), pulses_per_s=inside.size / duration,
               fired=counts.fired, shortened=counts.shortened, skipped=counts.skipped, late=counts.late)
    ev = _errors_ms(inside, zero_s + events_s) if surface_rendering else {"p50_ms": None, "p95_ms": None}
    row.update(event_p50_ms=ev["p50_ms"], event_p95_ms=ev["p95_ms"], crossings=None, crossing_p50_ms=None,
               crossing_p95_ms=None)
    if bumps is not None and surface is not None:
        from .surface.fields import true_crossings

        t, x, y = _stroke(surface, speed_m_s, duration)
        # the crossings of the bumps themselves: the stroke's positions folded onto the picture
        w, h = MirroredSurface.folded_size(surface.width_m, surface.height_m)
        truth = true_crossings(t, fold_into(x, w), fold_into(y, h), bumps.centres_m, bumps.radii_m)
        cr = _errors_ms(inside, zero_s + truth)
        row.update(crossings=int(truth.size), crossing_p50_ms=cr["p50_ms"], crossing_p95_ms=cr["p95_ms"])
    return row


def _stroke(surface: Any, speed_m_s: float, duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The steady straight stroke's samples (t [s], x [m], y [m]) over ``[0, duration)``: the
    pin is counted over that window, so nothing is rendered after it."""
    from .surface.straight import straight_stroke

    t, x, y = straight_stroke(surface.width_m, surface.height_m, speed_m_s, 0.0, duration)
    keep = t < duration
    return t[keep], x[keep], y[keep]


def _play_events(board: Any, host: Any, profile: Any, surface: Any, speed_m_s: float,
                 duration: float) -> tuple[dict[str, Any], float, np.ndarray]:
    """A surface profile's stroke as scheduled pulses; (row, board time [s] of stroke time 0, event times [s])."""
    from .actuators import frames as P
    from .actuators.clock_sync import ClockSync
    from .actuators.serial_events import EventSender, plan_pulses
    from .surface.clock import StrokeClock
    from .surface.rendering import stroke_events
    from .surface.stroke import LOOKAHEAD_S
    from .surface.straight import MirroredSurface
    from .surface.equivalent import equivalent_drive

    t, x, y = _stroke(surface, speed_m_s, duration)
    events = stroke_events(MirroredSurface(surface), t.tolist(), x.tolist(), y.tolist()) if speed_m_s > 0 else []
    times = np.array([e.t_s for e in events], dtype=float)
    operating = host.make_safe(equivalent_drive(events, duration, profile, window_s=duration + 1.0)) \
        if events else Drive.off()
    status = host.controller_status
    widths = (int(math.ceil(status.min_pulse_width_s * 1e6)), int(status.max_pulse_width_s * 1e6))
    clock, sender, stroke_clock = ClockSync(), EventSender(1), StrokeClock()
    zero_s = _ORIGIN_S + TRANSPORT_S
    for tb in np.arange(0.0, duration, BATCH_S):
        arrival = _ORIGIN_S + float(tb) + TRANSPORT_S  # host and board clocks read alike here
        board.until(arrival)
        clock.add(arrival, _pong(board).board_us, arrival + 2 * 25e-6)
        zero = stroke_clock.host_s(float(tb), arrival)
        ahead = [e for e in events if tb <= e.t_s <= tb + LOOKAHEAD_S]
        pulses = plan_pulses(ahead, zero, arrival, clock.board_us, operating, host.make_safe, widths)
        payload = sender.payload(0, pulses, now_us=clock.board_us(arrival))
        if payload is not None:
            board.send(P.Command.EVENTS, payload)
    row = {"rendering": "surface", "rendered": len(events), "rendered_per_s": len(events) / duration,
           "frequency_hz": None}
    return row, zero_s, times


def _play_steady(board: Any, host: Any, profile: Any, features: Any, speed_m_s: float,
                 duration: float) -> tuple[dict[str, Any], float, np.ndarray]:
    """A steady profile's drive sent with SET and heartbeats; (row, board time [s] it starts, no events)."""
    from .actuators import frames as P

    d = host.make_safe(profile.drive(features, speed_m_s))
    zero_s = _ORIGIN_S + TRANSPORT_S
    board.until(zero_s)
    if d.is_off:
        board.set(0, 0.0, 0.0, 0.0)
    else:
        board.set(0, d.pulse_frequency_hz, d.pulse_width_s, d.amplitude, d.regularity)
    for tb in np.arange(_HEARTBEAT_S, duration, _HEARTBEAT_S):
        board.until(zero_s + float(tb))
        board.send(P.Command.HEARTBEAT)
    f = 0.0 if d.is_off else d.pulse_frequency_hz
    row = {"rendering": "steady", "rendered": int(round(f * duration)), "rendered_per_s": f, "frequency_hz": f}
    return row, zero_s, np.array([])


def serial_report(profile: Any, images: dict[str, Any] | None, speeds_mm_s: Sequence[float], *,
                  circuit: str = "aa-resistor", material: Any = None) -> list[dict[str, Any]]:
    """:func:`board_stroke` per texture (the built-in ones when ``images`` is None) and speed
    [mm/s] (the report's :data:`~tactilize.report.SPEEDS_MM_S`); one dict a row, with
    ``texture`` and ``speed_mm_s``.  A surface rendering renders every picture as ``material``
    (a :class:`tactilize.materials.MaterialChoice`) when given."""
    if images is None:
        from .data import get_texture, texture_ids

        images = {tid: get_texture(tid).image for tid in texture_ids()}
    surface_rendering = getattr(profile, "rendering", "steady") == "surface"
    rows = []
    for name, img in images.items():
        if surface_rendering:
            from .surface.model import surface_model

            made = {} if material is None else material.surface_kwargs()
            kw: dict[str, Any] = {"surface": surface_model(img, tip_radius_m=profile.tip_radius_m, **made)}
        else:
            from .features import extract_features

            kw = {"features": extract_features(img)}
        for v in speeds_mm_s:
            rows.append({"texture": name, "speed_mm_s": float(v),
                         **board_stroke(profile, float(v) / 1e3, circuit=circuit, **kw)})
    return rows
