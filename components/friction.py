"""Friction of motion (36) and its shape function.

(36) prints F_i = a_{4+i} (2 - 2 exp(-cF w)) / (1 + exp(-cF w)), which is identically
2 a_{4+i} tanh(cF w / 2) (decision 16 in docs/decisions.md): the tanh form cannot overflow and is the
default.  Both are written as F_i = 2 a_{4+i} g(k w) with k = cF / 2 so that the hot paths call one
function on one argument.
"""
from __future__ import annotations

import math
from collections.abc import Callable

from .validation import choice

FRICTION_FORMS = ("tanh", "printed")


def _printed_half(x: float) -> float:
    """The printed shape of (36) in the half-argument form: (1 - e^-2x) / (1 + e^-2x) = tanh(x).

    Overflows (OverflowError) for x < -354, as the printed formula does for large negative speeds.
    """
    e = math.exp(-2.0 * x)
    return (1.0 - e) / (1.0 + e)


def shape_function(form: str, owner: str = "plant") -> Callable[[float], float]:
    """g such that F_i(w) = 2 a_{4+i} g(cF w / 2) [N.m]; ``form`` is 'tanh' (default) or 'printed'."""
    choice(owner, "friction_form", form, FRICTION_FORMS)
    return math.tanh if form == "tanh" else _printed_half


def friction(a: float, cF: float, w: float, form: str = "tanh") -> float:
    """F_i(w) of (36) [N.m] for rolling-resistance parameter a [N.m], slope cF [s/rad], wheel speed w [rad/s]."""
    return 2.0 * a * shape_function(form)(0.5 * cF * w)
