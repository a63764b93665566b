"""Open an output from a short text spec, as the CLI and the web server take it.

=====================  ==================================================
``simulated``          the SMA wire model in real time (the default)
``serial:PATH``        a tactile controller on a serial port
``audio``              the default sound device
``audio:DEVICE``       a sound device by index or (part of its) name
=====================  ==================================================

Each backend is imported only when asked for, so a missing optional
dependency (sounddevice) only matters to whoever wants that output.
"""

from __future__ import annotations

from typing import Any

from ..errors import OutputError
from .base import Output

__all__ = ["open_output", "OUTPUT_KINDS"]

OUTPUT_KINDS = ("simulated", "serial:PATH", "audio[:DEVICE]")


def open_output(spec: str, **options: Any) -> Output:
    """An opened output for ``spec`` (see the module docstring).

    Parameters
    ----------
    spec : str
        ``"simulated"``, ``"serial:PATH"`` or ``"audio[:DEVICE]"``.
    **options
        Passed to the output's constructor (for example ``envelope=``).

    Raises
    ------
    OutputError
        Unknown spec, or the device cannot be opened.
    """
    text = str(spec).strip()
    kind, _, arg = text.partition(":")
    kind = kind.lower()
    if kind == "simulated" and not arg:
        from . import simulated

        cls = getattr(simulated, "SimulatedOutput", None)
        if cls is None:
            raise OutputError(text, "the simulated output is not available in this build")
        return cls(**options)
    if kind == "serial":
        if not arg:
            raise OutputError(text, "give the port, e.g. serial:/dev/ttyACM0")
        from .serial import SerialOutput

        return SerialOutput(arg, **options)
    if kind == "audio":
        from .audio import AudioOutput

        device: int | str | None = None
        if arg:
            device = int(arg) if arg.isdigit() else arg
        return AudioOutput(device=device, **options)
    raise OutputError(text, f"unknown output (use one of: {', '.join(OUTPUT_KINDS)})")
