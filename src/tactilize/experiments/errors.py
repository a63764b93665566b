"""The experiments' errors: the bottom layer, imported by every other module of the package."""

from __future__ import annotations

from ..errors import RequestError, TactilizeError

__all__ = ["DesignError", "ProtocolError", "FlowError"]


class DesignError(TactilizeError):
    """An experiment's design (a protocol file, or a built-in's name) is unknown, unreadable or invalid."""


#: The name users meet in ``experiment protocols`` and in protocol files.
ProtocolError = DesignError


class FlowError(RequestError):
    """A request the participant flow refuses; ``status`` is the HTTP status to answer with."""
