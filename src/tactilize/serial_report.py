"""What reaches the board's pin over the serial link: ``tactilize profile report --serial``.

For each texture and speed, :func:`board_stroke` plays the profile's steady straight
stroke (:mod:`tactilize.surface.straight`, the stroke the rest of the report measures)
along the one whole-stroke path (:func:`~tactilize.surface.playback.play_stroke`: the
pen page's batches every :data:`BATCH_S`, the pen tracker, the profile's rendering,
:func:`~tactilize.surface.rendering.rendering_for`), and hands every frame, as it
arrives :data:`TRANSPORT_S` after its batch, to the host's serial output
(:meth:`SerialOutput.play <tactilize.actuators.serial.SerialOutput.play>`, which plays a
regular train with SET and other events as scheduled pulses, through the felt band, the
safety envelope and the board's own limits, the board's clock kept by PING/PONG with
every heartbeat) connected to the controller firmware on the virtual-time board
(:class:`~tactilize.boardhost.virtual_serial.VirtualSerialOutput`,
:mod:`tactilize.boardhost.virtual_board`).  The pen lifts with the last batch: what is
not yet played then is withdrawn.

Then it reads the pin: pulses per second that reached it, p50/p95 of
|pulse on the pin - scheduled event| (and - true crossing, when the bumps are
known), and the board's counters (pulses fired, shortened or skipped by its
running heat estimate, late).  Simulated time: nothing waits on the wall clock,
every run gives the same figures, and the figures are the method's (host
planning, clock sync, the firmware's scheduling and heat gate), not the
machine's load; the real-time link over a pseudo-terminal is measured by
``bench/bench_surfaces.py --only serial``.

Units: SI (s, m, Hz); the board's microseconds where named ``_us``.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Sequence

import numpy as np

from .surface.playback import BATCH_S, TRANSPORT_S

__all__ = ["board_stroke", "serial_report", "played_on_board", "BoardRun", "BATCH_S", "TRANSPORT_S"]

#: Board time [s] of stroke time 0 (after the handshake).
_ORIGIN_S = 0.1


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
    surface : SurfaceModel, optional
        The picture's surface (a rendering that reads it crosses it, mirrored beyond its edges).
    features : object, optional
        The picture's features (a rendering of the profile's laws reads them).
    bumps : BumpField, optional
        The surface's known bumps: errors against the true crossings too.
    circuit : str
        The circuit the board is configured for (its stored limits and the envelope).
    duration_s : float, optional
        The stroke's length [s]; :data:`~tactilize.surface.straight.STROKE_S` by default.

    Returns
    -------
    dict
        ``rendering`` (its name), ``rendered`` (the events the stroke fired,
        :func:`~tactilize.surface.playback.play_stroke`), ``rendered_per_s``, ``pulses`` (on
        channel 0's pin), ``pulses_per_s``, ``frequency_hz`` (the drive of the last regular
        train, as sent with SET; None when none was), ``event_p50_ms``/``event_p95_ms``
        (|pin pulse - scheduled event|, None when no event was scheduled), ``crossings``,
        ``crossing_p50_ms``/``crossing_p95_ms`` (|pin pulse - true crossing|, with ``bumps``),
        ``fired``, ``shortened``, ``skipped``, ``late`` (the board's counters of scheduled pulses).

    Raises
    ------
    ValueError
        The profile's rendering reads the picture's features and none are given.
    """
    from .pen.samples import PenSample
    from .surface.playback import Everywhere
    from .surface.rendering import rendering_for
    from .surface.straight import STROKE_S, MirroredSurface, fold_into

    duration = STROKE_S if duration_s is None else float(duration_s)
    rendering = rendering_for(profile, None if surface is None else MirroredSurface(surface))
    if features is None and not rendering.reads_surface:
        raise ValueError("the stroke needs the picture: its features (or its surface, for a profile that "
                         "renders the surface)")
    t, x, y = _stroke(surface, speed_m_s, duration)
    samples = [PenSample(a, b, c, None) for a, b, c in zip(t.tolist(), x.tolist(), y.tolist())]
    run = played_on_board(rendering, samples, None if features is None else Everywhere(features), circuit=circuit)
    played, counts, pins = run.played, run.counts, run.pins_s
    inside = pins[(pins >= -0.005) & (pins < duration)]
    scheduled = np.array([e.t_s for e, (_, regular) in zip(played.events, played.regular) if not regular])
    last = run.trains[-1] if run.trains else None
    row: dict[str, Any] = {
        "rendering": rendering.name, "rendered": len(played.events), "rendered_per_s": len(played.events) / duration,
        "frequency_hz": None if last is None else (0.0 if last.is_off else last.pulse_frequency_hz),
        "pulses": int(inside.size), "pulses_per_s": inside.size / duration,
        "fired": counts.fired, "shortened": counts.shortened, "skipped": counts.skipped, "late": counts.late,
    }
    ev = _errors_ms(inside, scheduled)
    row.update(event_p50_ms=ev["p50_ms"], event_p95_ms=ev["p95_ms"], crossings=None, crossing_p50_ms=None,
               crossing_p95_ms=None)
    if bumps is not None and surface is not None:
        from .surface.fields import true_crossings

        # the crossings of the bumps themselves: the stroke's positions folded onto the picture
        w, h = MirroredSurface.folded_size(surface.width_m, surface.height_m)
        truth = true_crossings(t, fold_into(x, w), fold_into(y, h), bumps.centres_m, bumps.radii_m)
        cr = _errors_ms(inside, truth)
        row.update(crossings=int(truth.size), crossing_p50_ms=cr["p50_ms"], crossing_p95_ms=cr["p95_ms"])
    return row


class BoardRun(NamedTuple):
    """A stroke played to the virtual board (:func:`played_on_board`).

    Attributes
    ----------
    played : PlayedStroke
        What the one whole-stroke path fired (:func:`~tactilize.surface.playback.play_stroke`).
    pins_s : ndarray
        When each pulse on channel 0's pin began [s, on the stroke's clock: the board's
        clock less the instant stroke time 0 played there].
    counts : EventCounts
        The board's counters of scheduled pulses on channel 0, after the stroke.
    trains : tuple of Drive
        The drive of each regular train (a steady rendering's frames), as sent with SET.
    """

    played: Any
    pins_s: np.ndarray
    counts: Any
    trains: tuple[Any, ...]


def played_on_board(rendering: Any, samples: Sequence[Any], picture: Any = None, *,
                    circuit: str = "aa-resistor", after_s: float = 0.05) -> BoardRun:
    """A stroke through ``rendering`` (:func:`~tactilize.surface.rendering.rendering_for`) along
    the one whole-stroke path, each frame played by the host's serial output on a virtual
    board as its batch arrives (module docstring); the pen lifts with the last batch.

    Parameters
    ----------
    rendering : Rendering
    samples : sequence of PenSample
        The stroke (times [s] increasing from 0, positions [display m], y down).
    picture : PictureLookup, optional
        The features under the pen (:class:`~tactilize.surface.playback.Everywhere`); None for
        a rendering that reads only the surface.
    circuit : str
        The circuit the board is configured for.
    after_s : float
        The board runs on this long after the last sample [s].
    """
    from .boardhost.virtual_board import VirtualBoard
    from .boardhost.virtual_serial import VirtualSerialOutput
    from .surface.playback import play_stroke

    # Stroke time 0 plays on the board once its batch has come: the output maps the stroke's
    # clock onto its own by the least lag, TRANSPORT_S.
    zero_s = _ORIGIN_S + TRANSPORT_S
    trains: list[Any] = []
    with VirtualBoard(circuit=circuit) as board, VirtualSerialOutput(board, circuit=circuit,
                                                                     closed_loop=False) as out:

        def on_frame(batch: list[Any], state: Any, feat: Any, frame: Any, arrival_s: float) -> None:
            out.advance(_ORIGIN_S + arrival_s)
            if frame is None:
                out.stop()  # nothing rendered (no pen state yet): the output rests
                return
            sent = out.play(frame, batch[-1].t_s, [frame.drive] * out.channels)
            if frame.regular:
                trains.append(sent[0])

        played = play_stroke(rendering, samples, picture, batch_s=BATCH_S, transport_s=TRANSPORT_S,
                             on_frame=on_frame)
        out.stop()  # the pen lifts: what the last batch left pending is withdrawn
        out.advance(zero_s + (samples[-1].t_s if samples else 0.0) + after_s)
        counts = out.counts(0)
        pins = np.array(board.pulse_starts_us(0)) / 1e6 - zero_s
    return BoardRun(played, pins, counts, tuple(trains))


def _stroke(surface: Any, speed_m_s: float, duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The steady straight stroke's samples (t [s], x [m], y [m]) over ``[0, duration)`` (from the
    picture's centre; from the origin without a surface): the pin is counted over that window, so
    nothing is rendered after it."""
    from .surface.straight import straight_stroke

    w, h = (0.0, 0.0) if surface is None else (surface.width_m, surface.height_m)
    t, x, y = straight_stroke(w, h, speed_m_s, 0.0, duration)
    keep = t < duration
    return t[keep], x[keep], y[keep]


def serial_report(profile: Any, images: dict[str, Any] | None, speeds_mm_s: Sequence[float], *,
                  circuit: str = "aa-resistor", material: Any = None) -> list[dict[str, Any]]:
    """:func:`board_stroke` per texture (the built-in ones when ``images`` is None) and speed
    [mm/s] (the report's :data:`~tactilize.report.SPEEDS_MM_S`); one dict a row, with
    ``texture`` and ``speed_mm_s``.  A rendering that reads the surface renders every picture
    as ``material`` (a :class:`tactilize.materials.MaterialChoice`) when given."""
    from .surface.rendering import rendering_for

    if images is None:
        from .data import get_texture, texture_ids

        images = {tid: get_texture(tid).image for tid in texture_ids()}
    made = {} if material is None else material.surface_kwargs()
    rows = []
    for name, img in images.items():
        rendering = rendering_for(profile, image=img, **made)  # its surface, when it reads one
        features = None
        if not rendering.reads_surface:
            from .features import extract_features

            features = extract_features(img)
        for v in speeds_mm_s:
            rows.append({"texture": name, "speed_mm_s": float(v),
                         **board_stroke(profile, float(v) / 1e3, surface=rendering.surface, features=features,
                                        circuit=circuit)})
    return rows
