"""Parameter checks that fail with one line naming the parameter and the bad value."""
from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any


class ParameterError(ValueError):
    """A component parameter is invalid; the message is one line naming the parameter and the value."""


def finite(owner: str, name: str, value: float) -> float:
    """Return ``float(value)`` or raise if it is not a finite real number."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{owner} parameter {name} = {value!r}: not a real number") from None
    if not math.isfinite(v):
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be finite")
    return v


def not_nan(owner: str, name: str, value: float) -> float:
    """Return ``float(value)``; infinity is allowed (e.g. 'never'), NaN is not."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{owner} parameter {name} = {value!r}: not a real number") from None
    if math.isnan(v):
        raise ParameterError(f"{owner} parameter {name} = nan: must be a number")
    return v


def positive(owner: str, name: str, value: float) -> float:
    """A finite value > 0."""
    v = finite(owner, name, value)
    if v <= 0.0:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be > 0")
    return v


def non_negative(owner: str, name: str, value: float) -> float:
    """A finite value >= 0."""
    v = finite(owner, name, value)
    if v < 0.0:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be >= 0")
    return v


def positive_int(owner: str, name: str, value: int, hi: int | None = None) -> int:
    """An integer >= 1, and <= ``hi`` if given (a float with an integral value is accepted)."""
    v = finite(owner, name, value)
    if v != int(v) or v < 1:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be an integer >= 1")
    if hi is not None and v > hi:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be an integer <= {hi}")
    return int(v)


def integer_in(owner: str, name: str, value: int, lo: int, hi: int, text: str) -> int:
    """An integer in [lo, hi] (a float with an integral value is accepted); ``text`` says so in the message."""
    v = finite(owner, name, value)
    if v != int(v) or not lo <= v <= hi:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be {text}")
    return int(v)


def finite_or_inf(owner: str, name: str, value: float) -> float:
    """A finite value or +inf (e.g. 'never'); NaN and -inf are refused."""
    v = not_nan(owner, name, value)
    if v == -math.inf:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be finite or +inf")
    return v


def interval(owner: str, name: str, value: float, lo: float, hi: float, text: str) -> float:
    """A finite value with lo <= value < hi; ``text`` says so in the message (e.g. 'in [0, 1) counts')."""
    v = finite(owner, name, value)
    if not lo <= v < hi:
        raise ParameterError(f"{owner} parameter {name} = {v!r}: must be {text}")
    return v


def one_of(owner: str, name: str, value: Any, allowed: tuple[Any, ...], text: str) -> Any:
    """One of a few numbers (compared by value); ``text`` lists them in the message (e.g. '1 or 2')."""
    if value not in allowed:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be {text}")
    return value


def boolean(owner: str, name: str, value: bool) -> bool:
    """A true/false flag (0 and 1 are accepted)."""
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)) and value in (0, 1):
        return bool(value)
    raise ParameterError(f"{owner} parameter {name} = {value!r}: must be true or false")


def mass_matrix_pd(owner: str, a1: float, a2: float, a3: float) -> None:
    """M of (35) = [[a1+a2+a3, a1-a2], [a1-a2, a1+a2+a3]] must be positive definite: a1+a2+a3 > |a1-a2|."""
    m11, m12 = a1 + a2 + a3, a1 - a2
    if not m11 > abs(m12):
        kind = "singular" if m11 == abs(m12) else "not positive definite"
        raise ParameterError(
            f"{owner} parameters a1 = {a1!r}, a2 = {a2!r}, a3 = {a3!r}: M of (35) is {kind} "
            f"(a1+a2+a3 = {m11:.6g}, |a1-a2| = {abs(m12):.6g})")


def choice(owner: str, name: str, value: str, allowed: Iterable[str]) -> str:
    """One of a fixed set of names."""
    allowed = tuple(allowed)
    if value not in allowed:
        raise ParameterError(f"{owner} parameter {name} = {value!r}: must be one of {', '.join(allowed)}")
    return value


def step(owner: str, dt: float) -> float:
    """A communication step [s]: finite and > 0."""
    if not (dt > 0.0 and math.isfinite(dt)):
        raise ParameterError(f"{owner}: step size h = {dt!r} s: must be finite and > 0")
    return float(dt)
