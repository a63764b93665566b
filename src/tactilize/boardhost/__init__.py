"""The host's tools for the tactile controller board (the firmware is :mod:`tactilize.firmware`).

- :mod:`~tactilize.boardhost.board`: what the board stores (``tactile_cfg.txt``),
  built from the host's wire model, and the pen's energy budget;
- :mod:`~tactilize.boardhost.emulator`: the firmware run on the host behind a
  pseudo-terminal (``tactilize controller-emulator``);
- :mod:`~tactilize.boardhost.host_machine`: the RP2040 stand-in for MicroPython's
  ``machine`` that the emulator runs the firmware against.
"""
