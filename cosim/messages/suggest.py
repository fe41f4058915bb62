"""Suggestions for a name that is not known but close to one that is (a misspelt variable, instance,
parameter or experiment field): the "did you mean ...?" of the one-line error messages."""
from __future__ import annotations

import difflib
from collections.abc import Iterable

#: How close a known name must be (difflib's ratio, 0..1; its own default) to be suggested.
CUTOFF = 0.6


def close_names(name: str, known: Iterable[str], n: int = 1) -> list[str]:
    """The (at most ``n``) known names closest to ``name``, best first; [] when none is close."""
    return difflib.get_close_matches(name, list(known), n=n, cutoff=CUTOFF)


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``" (did you mean 'gamma'?)"`` for the known name closest to ``name``, or "" when none is close:
    appended to an error message as it is."""
    best = close_names(name, known)
    return f" (did you mean {best[0]!r}?)" if best else ""


def unknown_key(key: str, allowed: Iterable[str], what: str = "key", also: str = "") -> str:
    """The one refusal of a key that a table does not take: ``"unknown key (allowed: a, b)"``, the allowed
    names sorted, ``also`` after them (the keys of another form, e.g. ``", iteration.KEY"``), and the
    allowed name closest to ``key`` when one is close (:func:`did_you_mean`).  ``what`` names the key when
    the message's field does not (``"experiment field 'stpo'"``)."""
    names = sorted(allowed)
    return f"unknown {what} (allowed: {', '.join(names)}{also}){did_you_mean(key, names)}"
