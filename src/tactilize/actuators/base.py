"""The Output interface: what every output implements (simulated wire, serial controller, audio).

An output receives one :class:`~tactilize.drive.Drive` per channel (the pen has
two actuators) with :meth:`Output.apply`, and :meth:`Output.stop` turns every
channel off.  Outputs are context managers: leaving the ``with`` block stops and
closes them, so an exception never leaves an actuator heating.

Besides those, an output has a few capabilities the pen server and the CLI use,
all declared here with what an output that lacks them answers
(:class:`OutputBase` gives those defaults, so callers never guess):

=========================  ===================================================
``channels``               how many actuators (2)
``amplitude_is_intensity`` amplitude is felt intensity (True) or, on the SMA
                           wire, a place in its felt band (False)
``standby()``              texture off, actuators held ready (default: stop)
``after_batch()``          a time-critical step just ended (default: nothing)
``traces(seconds)``        recent traces for the page, or None (no simulation)
``connected``              the device answers (True)
``events``                 what happened to the connection, as (time, kind, detail)
``play(frame, now_s, ch)`` plays one rendered frame (its pulse events and the
                           operating point beside them, docs/surfaces.md); the
                           default applies the operating point (``apply``)
``fault``                  why the output cannot be trusted now (a faulty sense
                           path, a stopped simulation), one line, or None
=========================  ===================================================
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, Sequence, runtime_checkable

from ..drive import Drive

if TYPE_CHECKING:  # the surface package loads scipy; outputs only pass its frames on
    from ..surface.rendering import Frame


@runtime_checkable
class Output(Protocol):
    """The Output interface: something that turns drives into actuator motion (or sound, or a file).

    A :class:`typing.Protocol`, so any class with these members is an output; subclass
    :class:`OutputBase` for the defaults.
    """

    @property
    def channels(self) -> int:
        """How many actuators this output drives."""
        ...

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Set every channel's drive at once.

        Returns the drives actually applied, after the actuator's safety envelope
        (their ``clamped`` names what it changed).
        """
        ...

    def stop(self) -> None:
        """Turn every channel off at once."""
        ...

    def close(self) -> None:
        """Stop and release the device."""
        ...

    def __enter__(self) -> "Output": ...

    def __exit__(self, *exc: object) -> None: ...

    # Read-only to callers: an output may keep them as plain attributes or properties.
    @property
    def amplitude_is_intensity(self) -> bool:
        """A drive's amplitude is felt intensity (True) or a place in the SMA wire's felt band (False)."""
        ...

    @property
    def connected(self) -> bool:
        """The device answers."""
        ...

    @property
    def events(self) -> Sequence[tuple[float, str, str]]:
        """(time [s], kind, detail) of what happened to the connection."""
        ...

    def standby(self) -> None:
        """Texture off, actuators held ready for the next touch."""
        ...

    def after_batch(self) -> None:
        """A time-critical step (a pen batch) just ended."""
        ...

    def traces(self, seconds: float = 2.0) -> dict[str, Any] | None:
        """Recent traces for the page, or None."""
        ...

    def play(self, frame: "Frame", now_s: float, channels: Sequence[Drive]) -> list[Drive]:
        """Play one rendered frame: its pulse events (``frame.events``, times on the stroke's
        clock, ``now_s`` [s] the stroke time that is now) replace those handed over before and
        not yet fired, ``channels`` (the frame's Drive split per channel) is the operating point
        beside them.  How is the output's choice: one that schedules events plays them, one that
        cannot (a recording, an older board) plays the operating point.  Returns the drives
        applied."""
        ...


class OutputBase:
    """Shared plumbing: context manager and a check on the number of channels."""

    channels: int = 2
    #: True where a drive's amplitude is the felt intensity (voice coil, LRA);
    #: False for the SMA wire, where the controller turns it into a place in the
    #: wire's felt band and both pins play the same drive.
    amplitude_is_intensity: bool = True

    # connected and fault are read-only, as in Output: outputs on a link compute them
    @property
    def connected(self) -> bool:
        """The device answers (outputs on a link override it)."""
        return True

    #: (time [s], kind, detail) of what happened to the connection
    events: Sequence[tuple[float, str, str]] = ()
    def play(self, frame: "Frame", now_s: float, channels: Sequence[Drive]) -> list[Drive]:
        """Play one rendered frame (:meth:`Output.play`); an output that cannot schedule events
        plays the operating point beside them, ``channels``, the frame's Drive per channel
        (for the surface rendering the steady drive of the window, docs/surfaces.md)."""
        return self.apply(channels)

    @property
    def fault(self) -> str | None:
        """One line saying why the output cannot be trusted now, or None."""
        return None

    def standby(self) -> None:
        """Texture off, actuators held ready for the next touch (the pen lifted or
        hovers).  Outputs with nothing to hold ready just stop; the SMA outputs
        keep the wire just below its transformation for a while."""
        self.stop()

    def after_batch(self) -> None:
        """A time-critical step just ended (nothing to do by default)."""

    def traces(self, seconds: float = 2.0) -> dict[str, Any] | None:
        """Recent traces for the page; None: this output simulates nothing."""
        return None

    def __enter__(self):
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self.stop()

    def apply(self, channels: Sequence[Drive]) -> list[Drive]:
        """Every output implements it (the Output interface)."""
        raise NotImplementedError

    def stop(self) -> None:
        """Every output implements it (the Output interface)."""
        raise NotImplementedError

    def _check(self, channels: Sequence[Drive]) -> list[Drive]:
        drives = list(channels)
        if len(drives) > self.channels:
            raise ValueError(f"{type(self).__name__} has {self.channels} channels, got {len(drives)} drives")
        for d in drives:
            if not isinstance(d, Drive):
                raise TypeError(f"expected Drive, got {type(d).__name__}")
        # Channels not mentioned are off: a shorter list must never leave one running.
        if len(drives) < self.channels:  # (an off Drive is built only then: every pen batch comes here)
            drives += [Drive.off()] * (self.channels - len(drives))
        return drives
