"""The SMA micro-wire: its description, its driver circuit, its physics, its safety and its control.

=================  ==================================================================
``wire``           :class:`WireSpec`: material, size, transformation temperatures
``circuit``        :class:`Circuit`: the source, switch and current limit that drive it
``model``          :class:`WireModel`: the lumped electro-thermal integrator
``simulate``       :func:`simulate`, :func:`simulate_drive`, :func:`steady_cycle`
``envelope``       :class:`SafetyEnvelope`: what the wire may get on that circuit, in energy
``controller``     :class:`WireController`: felt band, standby, warming, closed loop
``limiter``        the hardware limits that hold with the gate's logic stuck high or toggled
``limiter_worst``  what a limit lets through at its worst, judged on the model
=================  ==================================================================

Data moves one way: wire and circuit -> model -> simulation; envelope -> controller.
"""

from .circuit import Circuit, circuit_names
from .controller import STATES, ControllerState, PulsePlan, WireController
from .envelope import DESIGN_AMBIENT_C, ENVELOPE_MARGIN, SafetyEnvelope, build_envelope, default_envelope
from .model import WireModel, branch_fraction
from .simulate import (
    DEFAULT_DT_S,
    FOLLOW_THRESHOLD_M,
    CycleResult,
    SimulationResult,
    simulate,
    simulate_drive,
    steady_cycle,
)
from .wire import MODEL_VERSION, WireSpec, wire_names

__all__ = [
    "WireSpec",
    "wire_names",
    "MODEL_VERSION",
    "Circuit",
    "circuit_names",
    "WireModel",
    "branch_fraction",
    "SimulationResult",
    "CycleResult",
    "simulate",
    "simulate_drive",
    "steady_cycle",
    "DEFAULT_DT_S",
    "FOLLOW_THRESHOLD_M",
    "SafetyEnvelope",
    "build_envelope",
    "default_envelope",
    "DESIGN_AMBIENT_C",
    "ENVELOPE_MARGIN",
    "WireController",
    "PulsePlan",
    "STATES",
    "ControllerState",
]
