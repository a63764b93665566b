"""What every format's validator shares: rules, violations, and the walk's small helpers.

A validator is a table of :class:`Rule` (an id, what it asks, where it comes
from) and one function that walks a document and reports each rule it breaks
as a :class:`Violation` with the JSON path where it broke.  A rule only judges
what it names: a field of the wrong type breaks the rule about that field's
type, and the rules about its value skip it, so one fault is one violation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, TypeGuard

from ...errors import SignalError

__all__ = ["Rule", "Violation", "ConformanceError", "Checker", "is_int", "is_num", "at"]


@dataclass(frozen=True)
class Rule:
    """One rule of a format: ``id`` (``format.topic``), what it asks, and its source."""

    id: str
    text: str
    source: str


@dataclass(frozen=True)
class Violation:
    """A rule a document breaks, where (a JSON path such as ``perceptions[0].id``), and how."""

    rule: str
    path: str
    message: str

    def __str__(self) -> str:
        return f"{self.path or '<root>'}: {self.message} [{self.rule}]"


class ConformanceError(SignalError):
    """A document breaks rules of its format; ``violations`` lists them all."""

    def __init__(self, source: str, violations: list[Violation]):
        self.violations = list(violations)
        more = f" (and {len(violations) - 1} more)" if len(violations) > 1 else ""
        super().__init__(source, f"does not conform: {violations[0]}{more}")


def is_int(x: Any) -> TypeGuard[int]:
    """An integer JSON number (a bool is not one)."""
    return isinstance(x, int) and not isinstance(x, bool)


def is_num(x: Any) -> TypeGuard[float]:
    """A finite JSON number, integer or not (a bool is not one)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def at(path: str, key: str | int) -> str:
    """``path`` extended by an object key or an array index."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


class Checker:
    """Collects the violations of one document against one table of rules."""

    def __init__(self, rules: dict[str, Rule]):
        self.rules = rules
        self.violations: list[Violation] = []

    def fail(self, rule: str, path: str, message: str) -> None:
        if rule not in self.rules:  # a typo in a validator is a bug, not a finding
            raise KeyError(rule)
        self.violations.append(Violation(rule, path, message))

    def need(self, ok: bool, rule: str, path: str, message: str) -> bool:
        """Report ``rule`` unless ``ok``; return ``ok``."""
        if not ok:
            self.fail(rule, path, message)
        return ok

    def items(self, doc: dict[str, Any], key: str, path: str) -> list[tuple[str, Any]]:
        """``(path, item)`` of the array ``doc[key]`` (nothing when it is not an array)."""
        seq = doc.get(key)
        if not isinstance(seq, list):
            return []
        return [(at(at(path, key), i), x) for i, x in enumerate(seq)]


def rule_table(source: str, rules: list[tuple[str, str]], sources: dict[str, str] | None = None) -> dict[str, Rule]:
    """A rule table from ``(id, text)`` pairs, each sourced from ``source`` unless ``sources`` says otherwise."""
    sources = sources or {}
    return {rid: Rule(rid, text, sources.get(rid, source)) for rid, text in rules}
