"""The exceptions tactilize raises for bad input.

Every fault a user can cause has one exception type, all derived from
:class:`TactilizeError`.  Each message names the input (a file path, ``<bytes>``,
``<array>``, a profile name...) and what is wrong with it, so that the CLI can
print it as one line and exit with status 2.
"""

from __future__ import annotations

import math
from typing import Any


class TactilizeError(Exception):
    """Base class of every error caused by bad input.

    Parameters
    ----------
    source : str
        What the faulty input is (a path, ``<bytes>``, ``<array>``, a name).
    fault : str
        What is wrong with it, in a few words.
    """

    def __init__(self, source: str, fault: str):
        self.source = str(source)
        self.fault = str(fault)
        super().__init__(f"{self.source}: {self.fault}")


class ImageError(TactilizeError):
    """An image cannot be read or analysed (unreadable, truncated, empty, too large, non-finite...)."""


class ProfileError(TactilizeError):
    """A profile (preset name or TOML file) is unknown, unreadable or invalid."""


class DriveError(TactilizeError):
    """A drive or drive request is invalid (negative speed, NaN, out-of-range value...)."""


class OutputError(TactilizeError):
    """An output device cannot be used: a serial port that cannot be opened, a
    controller that does not answer or refuses a drive, a missing audio backend."""


class SignalError(TactilizeError):
    """A signal request is invalid (duration, sample rate, burst length, export format or parameters...)."""


class WireError(TactilizeError):
    """A wire specification or simulation request is invalid (unknown preset, non-physical value, bad current)."""


class CatalogError(TactilizeError):
    """A source, manifest, output or scheduler that a batch cannot use."""


class CatalogVersionError(CatalogError):
    """A catalog written by another version of tactilize or of its analysis.

    Resuming it would mix rows computed two ways in one catalog, so a batch
    refuses; reading it is fine.  The message names both versions.
    """


class MissingExtraError(TactilizeError):
    """A command or option needs an optional extra that is not installed
    (:mod:`tactilize.extras` builds the message: which module, which extra)."""


class RequestError(TactilizeError):
    """A request a server refuses (the pen page's, the experiments' routes).

    Parameters
    ----------
    source, fault : str
        As for :class:`TactilizeError`.
    status : int
        The HTTP status to answer with.
    **detail
        More JSON-ready fields for the answer.
    """

    def __init__(self, source: str, fault: str, status: int = 400, **detail: object):
        super().__init__(source, fault)
        self.status = int(status)
        self.detail = detail

    def to_dict(self) -> dict[str, object]:
        """The answer's body: ``error`` (what is wrong), ``source`` and any detail."""
        return {"error": self.fault, "source": self.source, **self.detail}


def check_finite(
    value: object,
    source: str,
    *,
    what: str = "",
    error: type[TactilizeError] = TactilizeError,
    minimum: float | None = None,
    above: float | None = None,
    maximum: float | None = None,
    unit: str = "",
) -> float:
    """``value`` as a float, if it is a real finite number within the bounds given.

    The one check every module uses for a number from outside (a profile, a
    command line, a request): booleans, strings, NaN and infinities are refused.

    Parameters
    ----------
    value : object
        What was given.
    source : str
        The input it came from, for the message (``<speed>``, ``--duration``...).
    what : str
        The quantity's name, to start the message with ("pulse_width_s").
    error : type
        The :class:`TactilizeError` subclass to raise.
    minimum, above, maximum : float, optional
        ``value >= minimum``, ``value > above``, ``value <= maximum``.
    unit : str
        Unit for the message ("s", "Hz", "m/s").

    Raises
    ------
    TactilizeError
        Of type ``error``: "<what> must be a finite number >= 0 [s], got 'x'".
    """
    ok = False
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        v = float(value)
        ok = (minimum is None or v >= minimum) and (above is None or v > above) and (maximum is None or v <= maximum)
    if not ok:
        bound = f" >= {minimum:g}" if minimum is not None else f" > {above:g}" if above is not None else ""
        if maximum is not None:
            bound += f" and <= {maximum:g}"
        kind = "a finite number"
        if above == 0 and minimum is None:
            kind, bound = "a positive finite number", bound.replace(" > 0", "", 1)
        head = f"{what} must" if what else "must"
        raise error(source, f"{head} be {kind}{bound}{' [' + unit + ']' if unit else ''}, got {value!r}")
    return v


def path_fault(path: Any) -> str | None:
    """Why ``path`` cannot be opened, in a few words, or None when it can be stat'ed.

    The one place a missing file is told apart from a symbolic link loop or a
    dangling link (``Path.exists`` calls all three "not there").
    """
    import errno
    import os

    try:
        os.stat(path)
        return None
    except FileNotFoundError:
        return "broken symbolic link (its target does not exist)" if os.path.islink(path) else "file not found"
    except PermissionError:
        return "permission denied"
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "symbolic link loop (the link points back to itself)"
        return f"cannot open ({exc.strerror or exc})"


def check_output_path(path: Any, error: type[TactilizeError] = TactilizeError, *, folder: bool = False) -> Any:
    """``path`` as a :class:`pathlib.Path`, if something can be written there; else ``error``.

    The one rule for every path the library and the commands write to (a file, or a
    folder they fill): its parent folder must already exist, so a mistyped path is
    refused in one line instead of making folders nobody asked for; a file's path
    must not be a folder, and a folder's path not a file.

    Parameters
    ----------
    path : str or os.PathLike
        Where to write.
    error : type
        The :class:`TactilizeError` subclass to raise.
    folder : bool
        ``path`` is a folder to fill (it may not exist yet) rather than a file.

    Raises
    ------
    TactilizeError
        Of type ``error``, naming ``path`` and the fault.
    """
    from pathlib import Path

    p = Path(path)
    parent = p.parent
    if not parent.is_dir():
        fault = "is a file, not a folder" if parent.exists() else "does not exist (create it first)"
        raise error(str(path), f"cannot write here: its folder {str(parent)!r} {fault}")
    if folder and p.exists() and not p.is_dir():
        raise error(str(path), "exists and is not a folder")
    if not folder and p.is_dir():
        raise error(str(path), "is a folder; give a file name")
    return p


def special_file_fault(path: Any) -> str | None:
    """What ``path`` is when it is neither a regular file nor a folder (a FIFO, a
    device, a socket), in a few words, following links; None otherwise.

    Reading a FIFO blocks until a writer comes and a device such as ``/dev/zero``
    never ends, so such entries are named, never read.
    """
    import os
    import stat

    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    for test, kind in ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return f"is {kind}, not an image file"
    return None


class MaterialError(TactilizeError):
    """A material name that is not in the library, or a material library or relief scale that is invalid."""
