"""The optional extras: which Python modules each one brings, and the one rule
for a missing one.

``pip install tactilize`` gives the core (analysis, drives, the simulated wire,
``tactilize serve``).  The rest comes in extras (``pip install 'tactilize[batch]'``;
``tactilize[all]`` has every one but ``test``).  Code that needs an optional module
asks :func:`require` for it, and the command line turns a
:class:`~tactilize.errors.MissingExtraError` (and any ``ModuleNotFoundError`` of a
module listed here, so that nothing slips through) into one line naming the
extra to install, with exit status 2.  The README's "Extras" section is this
table in words.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import MissingExtraError, TactilizeError

__all__ = ["EXTRAS", "SYSTEM_PACKAGES", "extra_for", "missing", "require"]

#: extra -> the top-level modules it installs that tactilize imports (pyproject.toml's
#: [project.optional-dependencies], without their own dependencies).
EXTRAS: dict[str, tuple[str, ...]] = {
    "plot": ("matplotlib",),
    "audio": ("sounddevice",),
    "experiments": ("pandas", "matplotlib", "pingouin", "pyarrow"),
    "batch": ("pandas", "pyarrow", "dask", "distributed"),
    "bench": ("skimage",),
}

#: extra -> what it needs from the operating system beside the Python packages.
SYSTEM_PACKAGES: dict[str, str] = {
    "audio": "the PortAudio library (Debian/Ubuntu: apt install libportaudio2; macOS: brew install portaudio)",
}


def extra_for(module: str, prefer: str | None = None) -> str | None:
    """The extra that installs ``module`` (its top-level name counts): ``prefer``
    when that one does, else the first listed; None for a module of no extra."""
    top = module.split(".")[0]
    having = [name for name, mods in EXTRAS.items() if top in mods]
    if not having:
        return None
    return prefer if prefer in having else having[0]


def missing(source: str, module: str, prefer: str | None = None,
            error: type[TactilizeError] = MissingExtraError) -> TactilizeError:
    """The error for ``source`` (an option, a command) needing ``module``, not installed.

    The message names the module and the extra that brings it, and how to install
    it: ``needs pyarrow, in the 'batch' extra (pip install 'tactilize[batch]')``.
    """
    top = module.split(".")[0]
    extra = extra_for(top, prefer)
    if extra is None:
        return error(source, f"needs the Python module {top}, which is not installed")
    return error(source, f"needs {top}, in the '{extra}' extra (pip install 'tactilize[{extra}]')")


def require(module: str, source: str, prefer: str | None = None,
            error: type[TactilizeError] = MissingExtraError) -> ModuleType:
    """Import ``module``, or raise :func:`missing`'s error for ``source``.

    Parameters
    ----------
    module : str
        The module to import (``"pyarrow.parquet"``).
    source : str
        What asked for it, as the user wrote it (``"--plot"``, ``"batch --out"``).
    prefer : str, optional
        The extra to name when several bring the module (``"batch"`` for pandas in a batch).
    error : type
        The :class:`~tactilize.errors.TactilizeError` subclass to raise.
    """
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        # Only a missing optional module is the user's to fix; a module missing
        # *inside* an installed one is a broken install, reported as it is.
        name = (exc.name or module).split(".")[0]
        if extra_for(name) is None and name != module.split(".")[0]:
            raise
        raise missing(source, name, prefer, error) from None
