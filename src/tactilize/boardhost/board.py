"""What the board stores: its wire and circuit, in the numbers its firmware uses.

The firmware's energy limits (``tactile_wire.WireLimits``) are the host's
:class:`~tactilize.actuators.sma.SafetyEnvelope` evaluated on the board.  The
board cannot import the wire model, so it stores a few numbers in
``tactile_cfg.txt`` (written with mpremote in maintenance mode, never over the
protocol: a host cannot loosen them).  :func:`board_config_text` writes that file
for a wire and circuit; the defaults baked into ``tactile_wire.py`` are the
paper's 75 um wire on ``aa-resistor`` (a test checks they equal this).

:func:`energy_budget` is the budget of docs/hardware.md: the holding heat per
channel at the operating point, what the supply gives for it, and the hours two
AA cells last.

Units: SI (W, J, K, ohm, A, V, h).
"""

from __future__ import annotations

from typing import Any

from ..actuators.sma import Circuit, WireController, WireSpec, build_envelope

__all__ = ["board_config", "board_config_text", "energy_budget", "AA_PLANNING_CAPACITY_AH"]

#: Charge [Ah] two alkaline AA cells are planned with under 0.5 A pulses: below
#: their light-drain capacity (docs/references.md, section 8 (AA cell)).
AA_PLANNING_CAPACITY_AH = 1.5


def board_config(wire: WireSpec | str | None = None, circuit: Circuit | str | None = None,
                 design_air_c: float | None = None) -> dict[str, float]:
    """The numbers ``tactile_wire.py`` limits the wire with, for a wire and circuit.

    ``design_air_c`` [C]: the hottest air the board must be safe in (default the
    envelope's design ambient, 30 C); a warmer room needs a config made for it.

    Returns
    -------
    dict
        ``conductance_w_k`` [W/K], ``heat_capacity_j_k`` [J/K], ``budget_k`` [K],
        ``max_power_w`` [W] (the circuit's worst case into this wire),
        ``r_martensite_ohm`` and ``r_austenite_ohm`` [ohm], ``current_min_a`` [A]
        (the least current the circuit gives the wire over that range) and
        ``current_spread`` [1] (see ``tactile_wire.WireLimits``), ``design_air_c``
        [C].
    """
    env = build_envelope(wire, circuit) if design_air_c is None else build_envelope(wire, circuit, design_ambient_c=design_air_c)
    spec = env.spec
    return {
        "conductance_w_k": spec.conductance_w_k,
        "heat_capacity_j_k": spec.heat_capacity_j_k,
        "budget_k": env.budget_k,
        "max_power_w": env.max_power_w,
        "r_martensite_ohm": spec.resistance_martensite_ohm,
        "r_austenite_ohm": spec.resistance_austenite_ohm,
        "current_min_a": min(env.circuit.current_at(r) for r in (spec.resistance_martensite_ohm, spec.resistance_austenite_ohm)),
        "current_spread": _current_spread(env.circuit, spec),
        "design_air_c": max(env.design_ambient_c, spec.ambient_c),
    }


def _current_spread(circuit: Circuit, spec: WireSpec) -> float:
    """1 for a voltage circuit; for a sink, how much its current can vary with the
    wire's resistance once the supply cannot feed it: (R_loop + R_hi) / (R_loop + R_lo)."""
    if circuit.kind != "current":
        return 1.0
    lo, hi = sorted((spec.resistance_martensite_ohm, spec.resistance_austenite_ohm))
    return (circuit.source_ohm + hi) / (circuit.source_ohm + lo)


def board_config_text(wire: WireSpec | str | None = None, circuit: Circuit | str | None = None,
                      design_air_c: float | None = None) -> str:
    """``tactile_cfg.txt`` for a wire and circuit (key value lines), safe in air up to ``design_air_c`` [C]."""
    cfg = board_config(wire, circuit, design_air_c)
    env = build_envelope(wire, circuit)
    head = (f"# tactilize board config: wire {env.spec.name}, circuit {env.circuit.name}, "
            f"air up to {cfg['design_air_c']:g} C\n")
    return head + "".join(f"{k} {v!r}\n" for k, v in cfg.items())


def energy_budget(
    wire: WireSpec | str | None = None,
    circuit: Circuit | str | None = None,
    *,
    channels: int = 2,
    capacity_ah: float = AA_PLANNING_CAPACITY_AH,
) -> dict[str, Any]:
    """Energy at the operating point, per channel and for the pen.

    The holding heat is the controller's (:class:`WireController`, nominal air):
    pulses plus bias together keep the wire at its setpoint.  While the switch
    conducts the supply gives ``V I`` and the wire takes ``I^2 R``, so the supply
    gives ``hold * V / (I R)`` on average.

    Returns
    -------
    dict
        ``wire_mw`` (heat into the wire per channel [mW]), ``supply_mw`` (drawn
        from the supply per channel [mW]), ``mean_current_ma`` per channel [mA],
        ``pulse_current_a`` [A], ``hours`` on ``capacity_ah`` for all channels
        (only meaningful for the AA circuits).
    """
    ctrl = WireController(wire, circuit)
    spec, circ = ctrl.spec, ctrl.circuit
    r = spec.resistance_at(ctrl.setpoint)
    i = circ.current_at(r)
    hold = ctrl.hold_w
    mean_a = hold / (i * r)
    return {
        "circuit": circ.name,
        "wire_mw": hold * 1e3,
        "supply_mw": hold * circ.supply_v / (i * r) * 1e3,
        "mean_current_ma": mean_a * 1e3,
        "pulse_current_a": i,
        "hours": capacity_ah / (channels * mean_a),
    }
