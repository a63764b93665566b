"""The tactile controller's firmware: the files that run ON the board.

``controller.py`` is a MicroPython program for an RP2040 board (flash it as
``main.py``, with the ``tactile_*.py`` modules beside it; see docs/firmware.md).
It imports MicroPython's ``machine`` and so is not importable on the host by
itself.  Nothing here imports the rest of tactilize (the import contract
``firmware-stands-alone`` pins it): the board has only these files.  The host's
tools for the board (what it stores, the emulator, the RP2040 stand-in) are
:mod:`tactilize.boardhost`.
"""
