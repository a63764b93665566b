"""The host's serial output on a virtual board, in simulated time.

:class:`VirtualSerialOutput` is :class:`~tactilize.actuators.serial.SerialOutput`, the
output the pen server drives a board with, whose port is a
:class:`~tactilize.boardhost.virtual_board.VirtualBoard` and whose clock is the board's:
every frame it writes is received by the firmware at once and every reply is handled
as it is written, so nothing waits on the wall clock and a run gives the same pins
every time.  Its keeper's work (heartbeat, clock exchange, sense request every
``heartbeat_interval_s``) is done by :meth:`VirtualSerialOutput.advance` as the board's
clock passes each beat, rather than by a thread.  What it plays is
:meth:`SerialOutput.play <tactilize.actuators.serial.SerialOutput.play>`'s own: SET
for a regular train, scheduled pulses (EVENTS) for other events, through the felt band,
the safety envelope and the board's limits, the board's clock kept by PING/PONG.

Units: SI (s); the board's microseconds where named ``_us``.
"""

from __future__ import annotations

from typing import Any

from ..actuators import frames as P
from ..actuators.serial import SerialOutput
from .virtual_board import VirtualBoard

__all__ = ["VirtualSerialOutput"]


class _BoardPort:
    """The port's bytes go to the board; its replies go straight back to the output."""

    in_waiting = 0

    def __init__(self, output: VirtualSerialOutput) -> None:
        self._output = output

    def write(self, data: bytes) -> int:
        board = self._output.board
        board.receive(data)
        for frame in board.replies():
            self._output._dispatch(frame)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        return b""

    def reset_input_buffer(self) -> None:
        pass

    def close(self) -> None:
        pass


class VirtualSerialOutput(SerialOutput):
    """:class:`~tactilize.actuators.serial.SerialOutput` connected to ``board`` (module docstring).

    Parameters
    ----------
    board : VirtualBoard
        The board; its clock [s] is the host's.
    **kwargs
        :class:`~tactilize.actuators.serial.SerialOutput`'s (``circuit``, ``wire``,
        ``closed_loop``, ``heartbeat_interval_s``...).

    Raises
    ------
    OutputError
        The board does not answer the handshake.
    """

    def __init__(self, board: VirtualBoard, **kwargs: Any) -> None:
        self.board = board
        self._beat_s = board.now_s
        super().__init__(f"virtual-board:{id(board):x}", **kwargs)
        self._beat_s = board.now_s + self.heartbeat_interval_s

    def _now(self) -> float:
        return self.board.now_s

    def _open(self) -> Any:
        return _BoardPort(self)

    def _read_loop(self) -> None:
        """Nothing to read: the port hands every reply over as the board writes it."""

    def _keep_loop(self) -> None:
        """No keeper thread: :meth:`advance` beats on the board's clock."""

    def advance(self, t_s: float) -> None:
        """Run the board until its clock reads ``t_s`` [s], with the host's heartbeat (and its
        clock exchange) every ``heartbeat_interval_s`` on the way."""
        while self._beat_s <= t_s:
            self.board.until(self._beat_s)
            if self.connected:
                self._heartbeat()
            self._beat_s += self.heartbeat_interval_s
        self.board.until(t_s)

    def counts(self, channel: int = 0) -> P.EventCounts:
        """The board's counters of scheduled pulses on ``channel``, asked now (a clock exchange)."""
        self._ping(wait=True)
        assert self.event_counts is not None
        return self.event_counts[channel]
