"""The tactile controller's firmware and its host-side emulator.

``controller.py`` is a MicroPython program for an RP2040 board (flash it as
``main.py``, see docs/firmware.md); it imports MicroPython's ``machine`` and so is
not importable on the host by itself.  :mod:`tactilize.firmware.emulator` runs it
on the host against :mod:`tactilize.firmware.host_machine`.
"""
