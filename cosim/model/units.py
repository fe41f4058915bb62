"""Units of FMI variables: conversion between convertible units, rejection of incompatible ones.

A unit is its exponents of the SI base units (kg, m, s, A, K, mol, cd, rad) with a factor and an offset:
value in base units = factor * value + offset (FMI 2.0, section 2.2.2).  Units are taken from the model
description's UnitDefinitions; a unit an FMU names without defining it is looked up in a small table of
common units; a variable without a unit is compatible with anything (nothing to check).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..messages.errors import CosimError

#: The SI base units (and the radian) whose exponents make a unit, in the order of :attr:`Unit.exps`.
BASES = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


@dataclass(frozen=True)
class Unit:
    """A unit: name, exponents of (kg, m, s, A, K, mol, cd, rad), factor and offset to the base unit."""

    name: str
    exps: tuple[int, ...]
    factor: float = 1.0
    offset: float = 0.0


def unit(name: str, factor: float = 1.0, offset: float = 0.0, **exps: int) -> Unit:
    """The Unit ``name`` with the exponents given by base unit name (``unit("N", kg=1, m=1, s=-2)``; the
    bases not given have exponent 0): value in base units = factor * value + offset."""
    return Unit(name, tuple(exps.get(b, 0) for b in BASES), factor, offset)


_DEG = math.pi / 180.0
#: Common units, used when an FMU names a unit it does not define.
KNOWN: dict[str, Unit] = {u.name: u for u in (
    unit("1"), unit("-"), unit("rad", rad=1), unit("deg", _DEG, rad=1), unit("rev", 2 * math.pi, rad=1),
    unit("rad/s", rad=1, s=-1), unit("deg/s", _DEG, rad=1, s=-1), unit("rpm", 2 * math.pi / 60, rad=1, s=-1),
    unit("rad/s2", rad=1, s=-2), unit("rad/s^2", rad=1, s=-2), unit("deg/s2", _DEG, rad=1, s=-2),
    unit("m", m=1), unit("mm", 1e-3, m=1), unit("cm", 1e-2, m=1), unit("km", 1e3, m=1),
    unit("m/s", m=1, s=-1), unit("km/h", 1 / 3.6, m=1, s=-1), unit("mm/s", 1e-3, m=1, s=-1),
    unit("m/s2", m=1, s=-2), unit("s", s=1), unit("ms", 1e-3, s=1), unit("min", 60.0, s=1), unit("h", 3600.0, s=1),
    unit("1/s", s=-1), unit("Hz", s=-1), unit("kg", kg=1), unit("g", 1e-3, kg=1),
    unit("N", kg=1, m=1, s=-2), unit("N.m", kg=1, m=2, s=-2), unit("Nm", kg=1, m=2, s=-2),
    unit("N*m", kg=1, m=2, s=-2), unit("mN.m", 1e-3, kg=1, m=2, s=-2), unit("kg.m2", kg=1, m=2),
    unit("kg.m^2", kg=1, m=2), unit("N.m.s/rad", kg=1, m=2, s=-1, rad=-1), unit("s/rad", s=1, rad=-1),
    unit("W", kg=1, m=2, s=-3), unit("V", kg=1, m=2, s=-3, A=-1), unit("A", A=1), unit("K", K=1),
    unit("degC", 1.0, 273.15, K=1),
)}


def units_of(model_description) -> dict[str, Unit]:
    """The UnitDefinitions of an FMPy model description (FMI 2.0 or 3.0), by name; a definition without
    BaseUnit is the common unit of that name, or left out when there is none (then known by name only)."""
    out: dict[str, Unit] = {}
    for ud in model_description.unitDefinitions:   # (FMPy: an empty list when there are none)
        bu = ud.baseUnit
        if bu is None:
            if ud.name in KNOWN:
                out[ud.name] = KNOWN[ud.name]
            continue
        out[ud.name] = Unit(ud.name, tuple(int(getattr(bu, b)) for b in BASES),
                            float(bu.factor), float(bu.offset))
    return out


def lookup(name: str | None, defined: dict[str, Unit]) -> Unit | None:
    """The Unit named ``name``: from the FMU's definitions, else the table of common units, else a unit
    with unknown base (compatible only with itself by name).  None when there is no unit."""
    if not name:
        return None
    if name in defined:
        return defined[name]
    if name in KNOWN:
        return KNOWN[name]
    return Unit(name, ())


def same_unit(a: Unit, b: Unit | None) -> bool:
    """Whether two units are the same unit: the same name, or the same known base, factor and offset
    (``N.m`` and ``Nm``)."""
    if b is None:
        return False
    if a.name == b.name:
        return True
    return bool(a.exps) and a.exps == b.exps and a.factor == b.factor and a.offset == b.offset


def conversion(src: Unit | None, dst: Unit | None) -> tuple[float, float]:
    """(factor, offset) such that value_in_dst = factor * value_in_src + offset.

    Raises CosimError (message without context; the caller adds file and field) for incompatible units.
    """
    if src is None or dst is None or src.name == dst.name:
        return 1.0, 0.0
    if not src.exps or not dst.exps:
        raise CosimError(f"unit '{src.name}' is not convertible to '{dst.name}' (unknown unit)")
    if src.exps != dst.exps:
        raise CosimError(f"unit '{src.name}' is incompatible with '{dst.name}'")
    f = src.factor / dst.factor
    o = (src.offset - dst.offset) / dst.factor
    return f, o
