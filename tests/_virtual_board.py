"""The virtual-time board of the firmware tests: :mod:`tactilize.boardhost.virtual_board`, patched
through pytest's ``monkeypatch`` (undone after each test)."""

from __future__ import annotations

from tactilize.boardhost.virtual_board import VirtualBoard, VirtualMachine, firmware, install, peak_on_wire

__all__ = ["Board", "VirtualMachine", "fw", "install", "peak_on_wire", "PIN0", "PIN1", "BIAS0", "BIAS1"]

fw = firmware()
PIN0, PIN1 = fw.CHANNEL_PINS
BIAS0, BIAS1 = fw.BIAS_PINS


class Board(VirtualBoard):
    """The firmware on a virtual board, with its store in ``tmp``."""

    def __init__(self, monkeypatch, tmp, circuit="aa-resistor", after_watchdog_reset=False, **options):
        super().__init__(tmp, circuit, set_attr=monkeypatch.setattr, after_watchdog_reset=after_watchdog_reset,
                         **options)
