"""The circuit that drives a wire: a source, a switch, and what limits the current.

The heat a wire gets is ``I^2 R``, and which of the two is fixed depends on the
driver, not on the wire.  The paper's controller switches two AA cells onto the
wire; 3 mm of 75 um wire is only 0.54 .. 0.68 ohm, so with nothing else in the
loop the pulse current would be 2.3 .. 3.4 A, several times the ~0.5 A operating
point (docs/references.md, section 8).  The board these presets describe, with
its schematic, parts and energy budget, is docs/hardware.md.  A :class:`Circuit` says what is in the
loop, and the current into the wire follows from it and from the wire's
resistance, which changes by about 25 % with its phase.

Two kinds:

``voltage``
    A source of EMF ``supply_v`` behind ``source_ohm`` (the cells' internal
    resistance, a series resistor, the MOSFET's on-resistance and the sense
    resistor, summed): ``I = V / (R_source + R_wire)``.
``current``
    A constant-current sink set to ``current_a``, fed from ``supply_v`` behind
    ``source_ohm``; it needs ``headroom_v`` across itself, and when the supply
    cannot give that (sagging cells) it saturates and the current falls like a
    voltage source's.

What "amplitude" means on an SMA output
---------------------------------------
The switch is a MOSFET: it is on or off.  A drive's ``amplitude`` on an SMA
output is the fraction of each pulse during which the switch conducts, chopped
at tens of kHz (far faster than the wire's thermal time constant, so the wire
sees the mean heat ``amplitude * I^2 R``).  The same chopping, between pulses,
makes the standby bias.  A current DAC would make the heat go as
``amplitude^2``; no circuit here has one.

Units: SI (volts, ohms, amperes, watts).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import WireError, check_finite
from .wire import WireSpec, changed_preset

__all__ = ["Circuit", "circuit_names", "SWITCH_OHM", "SENSE_OHM"]

#: On-resistance [ohm] of a logic-level N-MOSFET fully on at the Pico's 3.3 V gate
#: drive: the AO3400A of docs/hardware.md (Q1) at its upper bound
#: (docs/references.md, section 8 (logic-level switch)).
SWITCH_OHM = 0.05
#: The current-sense resistor in each channel's return path [ohm] (docs/hardware.md, R3).
SENSE_OHM = 0.1
#: Two alkaline AA cells, new: 1.5 V and about 0.15 ohm each (docs/references.md, section 8).
AA_PAIR_V = 3.0
AA_PAIR_OHM = 0.3
#: A USB port: 5 V; the cable and connector add about 0.1 ohm.
USB_V = 5.0
USB_OHM = 0.1


@dataclass(frozen=True)
class Circuit:
    """The driver of one wire channel.

    Parameters
    ----------
    name : str
        Label.
    kind : {"voltage", "current"}
        A voltage source behind a resistance, or a constant-current sink.
    supply_v : float
        EMF of the supply [V] (two AA cells: 3.0 new, about 2.2 nearly spent).
    source_ohm : float
        Everything in series with the wire but the wire [ohm]: the supply's
        internal resistance, a series resistor, the switch and the sense resistor.
    current_a : float
        The sink's set point [A] (``kind="current"`` only).
    headroom_v : float
        Voltage the sink needs across itself to regulate [V].

    Notes
    -----
    Use :meth:`preset` for the circuits of ``docs/hardware.md`` (schematic, parts, energy budget).
    """

    name: str = "custom"
    kind: str = "voltage"
    supply_v: float = AA_PAIR_V
    source_ohm: float = 5.1 + AA_PAIR_OHM + SWITCH_OHM + SENSE_OHM
    current_a: float = 0.0
    headroom_v: float = 0.3

    def __post_init__(self) -> None:
        src = f"<circuit {self.name}>"
        if self.kind not in ("voltage", "current"):
            raise WireError(src, f"kind must be 'voltage' or 'current', got {self.kind!r}")
        for key in ("supply_v", "source_ohm", "current_a", "headroom_v"):
            check_finite(getattr(self, key), src, what=key, error=WireError, minimum=0.0)
        if self.supply_v <= 0:
            raise WireError(src, "supply_v must be > 0")
        if self.kind == "voltage" and self.source_ohm <= 0:
            # A real source always has some resistance; 0 would make the
            # current of a cold wire unbounded in the limit of a short wire.
            raise WireError(src, "source_ohm must be > 0 for a voltage source")
        if self.kind == "current" and self.current_a <= 0:
            raise WireError(src, "a current sink needs current_a > 0")

    # -- presets

    @classmethod
    def preset(cls, name: str, wire: WireSpec | str | None = None, **changes: Any) -> "Circuit":
        """A circuit of ``docs/hardware.md`` sized for a wire.

        ``aa-resistor`` (the default): two AA cells, a series resistor sized so the
        relaxed wire takes the wire's ``rated_current_a``, the MOSFET, the sense
        resistor.  ``usb-resistor``: the same from USB 5 V.  ``aa-sink``: two AA cells
        into a constant-current sink at the rated current.  ``aa-direct``: the
        paper's controller as documented before, cells switched straight onto the
        wire (several amperes; kept to show that the envelope holds on it).
        """
        spec = WireSpec.resolve(wire)
        key = str(name).strip().lower()
        fixed = SWITCH_OHM + SENSE_OHM
        if key == "aa-resistor":
            series = _series_for(AA_PAIR_V, spec.rated_current_a, AA_PAIR_OHM + fixed + spec.resistance_martensite_ohm)
            c = cls(key, "voltage", AA_PAIR_V, AA_PAIR_OHM + series + fixed)
        elif key == "usb-resistor":
            series = _series_for(USB_V, spec.rated_current_a, USB_OHM + fixed + spec.resistance_martensite_ohm)
            c = cls(key, "voltage", USB_V, USB_OHM + series + fixed)
        elif key == "aa-sink":
            c = cls(key, "current", AA_PAIR_V, AA_PAIR_OHM + fixed, current_a=spec.rated_current_a)
        elif key == "aa-direct":
            c = cls(key, "voltage", AA_PAIR_V, AA_PAIR_OHM + SWITCH_OHM)
        else:
            raise WireError(str(name), f"no such circuit (known: {', '.join(circuit_names())})")
        return changed_preset(c, name, changes)

    @classmethod
    def resolve(cls, circuit: "Circuit | str | None", wire: WireSpec | str | None = None) -> "Circuit":
        """A circuit from a value, a preset name, or None (``aa-resistor`` for the wire)."""
        if isinstance(circuit, Circuit):
            return circuit
        return cls.preset("aa-resistor" if circuit is None else circuit, wire)

    @classmethod
    def ideal_current(cls, current_a: float) -> "Circuit":
        """An ideal current source of ``current_a`` [A] (no compliance limit): the
        current asked for is the current that flows, whatever the wire does."""
        i = check_finite(current_a, "<current>", what="current", error=WireError, above=0.0, unit="A")
        return cls("ideal-current", "current", 1e9, 0.0, current_a=i, headroom_v=0.0)

    def replace(self, **changes: Any) -> "Circuit":
        return dataclasses.replace(self, **changes)

    # -- the electrical facts

    def current_at(self, wire_ohm: float) -> float:
        """Current [A] through the wire while the switch conducts, at a wire resistance [ohm]."""
        if self.kind == "current":
            return min(self.current_a, max(0.0, self.supply_v - self.headroom_v) / (self.source_ohm + wire_ohm))
        return self.supply_v / (self.source_ohm + wire_ohm)

    def currents_at(self, wire_ohm: np.ndarray) -> np.ndarray:
        """:meth:`current_at` over an array of resistances [ohm] -> [A]."""
        r = np.asarray(wire_ohm, dtype=float)
        if self.kind == "current":
            return np.minimum(self.current_a, max(0.0, self.supply_v - self.headroom_v) / (self.source_ohm + r))
        return self.supply_v / (self.source_ohm + r)

    def power_at(self, wire_ohm: float) -> float:
        """Heat [W] into the wire while the switch conducts: I^2 R."""
        i = self.current_at(wire_ohm)
        return i * i * wire_ohm

    def power_and_slope(self, wire_ohm: float) -> tuple[float, float]:
        """(I^2 R [W], its derivative with respect to R [W/ohm]) while the switch conducts."""
        if self.kind == "current":
            v = max(0.0, self.supply_v - self.headroom_v)
            if self.current_a * (self.source_ohm + wire_ohm) <= v:
                i2 = self.current_a * self.current_a
                return i2 * wire_ohm, i2
        else:
            v = self.supply_v
        s = self.source_ohm + wire_ohm
        v2 = v * v
        return v2 * wire_ohm / (s * s), v2 * (self.source_ohm - wire_ohm) / (s * s * s)

    def max_power_w(self, wire: WireSpec) -> float:
        """The most heat [W] the switched-on circuit can put into this wire, over
        every resistance the wire can have (martensite to austenite)."""
        lo, hi = wire.resistance_martensite_ohm, wire.resistance_austenite_ohm
        points = [lo, hi, min(hi, max(lo, self.source_ohm))]
        if self.kind == "current" and self.current_a > 0:
            knee = max(0.0, self.supply_v - self.headroom_v) / self.current_a - self.source_ohm
            points.append(min(hi, max(lo, knee)))
        return max(self.power_at(r) for r in points)

    def describe(self, wire: WireSpec) -> dict[str, Any]:
        """JSON-ready summary: the fields and the currents into the relaxed and contracted wire."""
        return {
            **dataclasses.asdict(self),
            "current_relaxed_a": self.current_at(wire.resistance_martensite_ohm),
            "current_contracted_a": self.current_at(wire.resistance_austenite_ohm),
            "max_power_w": self.max_power_w(wire),
        }


def _series_for(supply_v: float, current_a: float, other_ohm: float) -> float:
    """The E24 resistor [ohm] nearest above the one that gives ``current_a`` [A]."""
    exact = max(0.0, supply_v / current_a - other_ohm)
    if exact == 0:
        return 0.0
    decade = 10 ** math.floor(math.log10(exact))
    for m in _E24:
        if m * decade >= exact * 0.985:  # within tolerance counts
            return round(m * decade, 6)
    return round(10 * decade, 6)


_E24 = (1.0, 1.1, 1.2, 1.3, 1.5, 1.6, 1.8, 2.0, 2.2, 2.4, 2.7, 3.0, 3.3, 3.6, 3.9, 4.3, 4.7, 5.1, 5.6, 6.2, 6.8, 7.5, 8.2, 9.1)


def circuit_names() -> list[str]:
    """Names of the preset circuits."""
    return ["aa-resistor", "usb-resistor", "aa-sink", "aa-direct"]
