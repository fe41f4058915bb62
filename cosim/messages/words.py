"""Counts in the words of messages and of what the commands print: "1 instance", "2 instances"."""
from __future__ import annotations


def plural(n: int | float, noun: str, nouns: str | None = None) -> str:
    """``noun`` for a count of exactly one, else its plural: ``nouns``, by default ``noun`` + "s"
    ("recorded variable" -> "recorded variables")."""
    if n == 1:
        return noun
    return nouns if nouns is not None else noun + "s"


def count(n: int | float, noun: str, nouns: str | None = None) -> str:
    """``n`` and the noun in the number it takes: ``count(1, "step")`` is "1 step", ``count(3, "step")``
    "3 steps" (``nouns``: the plural where it is not ``noun`` + "s")."""
    return f"{n} {plural(n, noun, nouns)}"
