"""What the finger gets from a steady stroke: the simulated output run offline and read back.

:func:`feel` plays one drive on a simulated wire exactly as ``tactilize serve``
would (controller, standby, envelope, closed loop) and reports whether every
pulse moves the pin, by how much, and how long after the pen touched the first
felt pulse came.  ``tactilize simulate --texture`` and ``bench/bench_felt.py``
print it.

Units: SI inside; the report's keys name the display units (ms, um, mA).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..errors import WireError, check_finite
from ..drive import Drive
from .simulated import SimulatedOutput
from .sma.circuit import Circuit
from .sma.simulate import FOLLOW_THRESHOLD_M
from .sma.wire import WireSpec

__all__ = ["FeltReport", "feel"]

#: Share of an irregular drive's pulses that must have their own peak.
IRREGULAR_FOLLOWED_SHARE = 0.95
#: Simulated time [s] the wire spends in standby before the pen touches: eight
#: thermal time constants of the 75 um wire, so the bias has settled.
STANDBY_SETTLE_S = 4.0


@dataclass(frozen=True)
class FeltReport:
    """What one steady drive gives the finger.

    Attributes
    ----------
    follows : bool
        Every pulse in the settled window (the last two thirds of the run) has
        its own displacement peak of at least 0.5 um.  For an irregular drive
        (``regularity`` below 1), at least :data:`IRREGULAR_FOLLOWED_SHARE` of
        them: a pulse that comes early, close after the previous one, merges with
        it into one bump, as a stylus meeting two close grains feels one.
    displacement_pp_um : float
        Median per-pulse swing in that window [um].
    first_follow_ms : float
        From the drive's arrival to the end of the first pulse that is followed
        [ms]; ``inf`` when none is.
    current_ma, pulse_width_ms : float
        The pulse current [mA] and width [ms] the controller chose (last pulse).
    peak_temperature_c : float
        Highest wire temperature over the whole run [deg C].
    pulse_frequency_hz : float
        The drive's frequency (the profile's, unchanged).
    pulses, pulses_followed : int
        Pulses in the settled window, and how many were followed.
    standby : bool
        The wire was in standby when the drive arrived (else cold and off).
    """

    follows: bool
    displacement_pp_um: float
    first_follow_ms: float
    current_ma: float
    pulse_width_ms: float
    peak_temperature_c: float
    pulse_frequency_hz: float
    pulses: int
    pulses_followed: int
    standby: bool

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        if not math.isfinite(d["first_follow_ms"]):
            d["first_follow_ms"] = None
        return d


def feel(
    drive: Drive,
    wire: WireSpec | str | None = None,
    circuit: Circuit | str | None = None,
    *,
    standby: bool = True,
    duration_s: float | None = None,
    closed_loop: bool = True,
    plant_wire: WireSpec | None = None,
    plant_circuit: Circuit | None = None,
) -> FeltReport:
    """Play a steady drive on one simulated wire and report what the finger gets.

    Parameters
    ----------
    drive : Drive
        As the profile made it (its ``strength`` is its place in the felt band).
    wire, circuit : optional
        As configured; the paper's 75 um on ``aa-resistor`` by default.
    standby : bool
        The wire waits in standby (True) or cold and off (False) when the drive
        arrives.
    duration_s : float, optional
        Length of the stroke [s]; default 1.5 s, or four periods if longer.
    closed_loop : bool
        The controller uses the measured resistance and current.
    plant_wire, plant_circuit : optional
        The real wire and circuit when they differ from the configured ones.
    """
    if not isinstance(drive, Drive):
        raise WireError("<drive>", f"expected a Drive, got {type(drive).__name__}")
    f = drive.pulse_frequency_hz
    if duration_s is None:
        duration_s = max(1.5, 4.0 / f) if f > 0 else 1.5
    check_finite(duration_s, "<duration>", what="duration", error=WireError, above=0.0, unit="s")
    out = SimulatedOutput(wire, circuit=circuit, channels=1, start=False, closed_loop=closed_loop,
                          plant_wire=plant_wire, plant_circuit=plant_circuit, trace_seconds=0.1,
                          trace_rate_hz=100.0, standby_s=3600.0)
    try:
        if standby:
            out.standby()
            out.advance(STANDBY_SETTLE_S)
        t0 = out.time_s
        out.reset_peak()
        out.apply([drive])
        step = 0.01
        for _ in range(int(math.ceil(duration_s / step))):
            out.advance(step)
        log = [p for p in out.pulse_log(0) if p[0] >= t0 - 1e-9]
        st = out.state()[0]
        peak = out.peak_temperature_c(0)
    finally:
        out.close()
    start_window = t0 + duration_s / 3
    window = [p for p in log if p[0] >= start_window]
    followed = [p for p in window if p[1] >= FOLLOW_THRESHOLD_M]
    first = next((p for p in log if p[1] >= FOLLOW_THRESHOLD_M), None)
    first_ms = (first[0] + st["pulse_width_ms"] * 1e-3 - t0) * 1e3 if first is not None else math.inf
    irregular = drive.regularity is not None and drive.regularity < 1.0
    needed = math.ceil(IRREGULAR_FOLLOWED_SHARE * len(window)) if irregular else len(window)
    return FeltReport(
        follows=bool(window) and len(followed) >= needed,
        displacement_pp_um=float(np.median([p[2] for p in window]) * 1e6) if window else 0.0,
        first_follow_ms=first_ms,
        current_ma=st["current_ma"],
        pulse_width_ms=st["pulse_width_ms"],
        peak_temperature_c=peak,
        pulse_frequency_hz=f,
        pulses=len(window),
        pulses_followed=len(followed),
        standby=standby,
    )
