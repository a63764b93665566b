"""Validators for the exported haptic formats: the rules each format's players hold a file to.

One table of rules per format (each rule with its id, what it asks and its
source in docs/references.md) and one function that lists every rule a
document breaks.  Every export passes its validator: the registry validates
each document before it returns its bytes (:func:`validate`).

======== ============================ =========================================
format   rules                        whose rules
======== ============================ =========================================
hjif     :data:`HJIF_RULES`           the MPEG-I haptics reference reader and its conformance suite
haptic   :data:`HAPTIC_RULES`         Meta's haptic data model (Lofelt/NiceVibrations)
ahap     :data:`AHAP_RULES`           Apple's AHAP documentation
android  :data:`ANDROID_RULES`        Google's ``VibrationEffect`` documentation
======== ============================ =========================================

References
----------
.. [1] docs/references.md, section 6 (haptic file formats).
"""

from __future__ import annotations

import json
from typing import Any, Callable

from ...errors import SignalError
from ._core import ConformanceError, Rule, Violation
from .ahap import AHAP_RULES, check_ahap
from .android import ANDROID_RULES, check_android
from .haptic import HAPTIC_RULES, check_haptic
from .hjif import HJIF_RULES, check_hjif

__all__ = ["Rule", "Violation", "ConformanceError", "RULES", "CHECKS", "check", "validate",
           "HJIF_RULES", "HAPTIC_RULES", "AHAP_RULES", "ANDROID_RULES",
           "check_hjif", "check_haptic", "check_ahap", "check_android"]

#: Every format's rules, by format name.
RULES: dict[str, dict[str, Rule]] = {"hjif": HJIF_RULES, "haptic": HAPTIC_RULES, "ahap": AHAP_RULES,
                                     "android": ANDROID_RULES}
#: Every format's check, by format name.
CHECKS: dict[str, Callable[[Any], list[Violation]]] = {"hjif": check_hjif, "haptic": check_haptic,
                                                       "ahap": check_ahap, "android": check_android}


def check(doc: Any, fmt: str) -> list[Violation]:
    """The rules of format ``fmt`` that ``doc`` breaks (a parsed document, or its JSON text or bytes)."""
    if fmt not in CHECKS:
        raise SignalError(str(fmt), f"no validator for this format (use one of: {', '.join(CHECKS)})")
    if isinstance(doc, (bytes, bytearray, str)):
        try:
            doc = json.loads(doc)
        except ValueError as exc:
            raise SignalError(f"<{fmt}>", f"not valid JSON ({exc})") from None
    return CHECKS[fmt](doc)


def validate(doc: Any, fmt: str, source: str | None = None) -> Any:
    """``doc`` itself if it keeps every rule of ``fmt``.

    Raises
    ------
    ConformanceError
        (a :class:`~tactilize.errors.SignalError`) naming the first broken
        rule; ``violations`` lists them all.
    """
    found = check(doc, fmt)
    if found:
        raise ConformanceError(source or f"<{fmt}>", found)
    return doc
