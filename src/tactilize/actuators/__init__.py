"""Actuator outputs and models: every output implements :class:`tactilize.actuators.base.Output`."""
