"""One home for each fact about a component parameter: its name (the dataclass field), default, unit,
accepted values (the check), meaning and whether it may change during a run.

A parameter dataclass declares every field with :func:`param`; its ``__post_init__`` calls
:func:`validate`, which applies each field's check, and then makes the checks that involve several
fields (M positive definite, the foam rectangle, ...), which stay in code.  The FMUs declare their
parameters from the same metadata (unit, range from the check's ``bounds``, description, tunable), and
the FMU interface documents are generated from the FMUs, so a fact written here reaches the validation,
the FMUs and the docs alike.  Nothing here knows about FMI: the metadata is plain data.

To add a parameter: add one ``param(...)`` field to the dataclass, use it in the component, and
regenerate the interface documents.
"""
from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from . import validation as _v
from .validation import ParameterError

DBL_MAX = sys.float_info.max
#: The smallest positive normal double: a lower bound of DBL_MIN stands for "> 0".
DBL_MIN = sys.float_info.min
INT_MAX = 2**31 - 1


@dataclass(frozen=True)
class Check:
    """The values one parameter accepts.

    ``apply(owner, name, value)`` returns the value converted to the parameter's type, or raises
    :class:`ParameterError` with one line naming the owner, the parameter and the value.
    ``kind`` names the check.  ``bounds`` (min, max) is the closed range an interface declares for it,
    None meaning unbounded: max = DBL_MAX excludes +inf, min = -DBL_MAX excludes -inf, min = DBL_MIN
    stands for "> 0".  ``hi_open``: the max itself is refused (a closed range cannot say so).
    ``values``: the only values accepted inside ``bounds`` (a sign, a power), or the names of a choice.
    """

    kind: str
    apply: Callable[[str, str, Any], Any]
    bounds: tuple[float | int | None, float | int | None] = (None, None)
    hi_open: bool = False
    values: tuple[Any, ...] = ()


finite = Check("finite", _v.finite, (-DBL_MAX, DBL_MAX))
positive = Check("positive", _v.positive, (DBL_MIN, DBL_MAX))
non_negative = Check("non_negative", _v.non_negative, (0.0, DBL_MAX))
#: A finite value or +inf ("never").
finite_or_inf = Check("finite_or_inf", _v.finite_or_inf, (-DBL_MAX, None))
boolean = Check("boolean", _v.boolean)
#: +1 or -1 (a sign, stored as a float).
sign = Check("sign", lambda o, n, x: float(_v.one_of(o, n, x, (1, -1), "+1 or -1")), (-1.0, 1.0), values=(1.0, -1.0))


def positive_int(hi: int = INT_MAX) -> Check:
    """An integer in [1, hi]."""
    return Check("positive_int", lambda o, n, x: _v.positive_int(o, n, x, hi), (1, hi))


def integer(lo: int, hi: int, text: str) -> Check:
    """An integer in [lo, hi]; ``text`` states the range in the error message."""
    return Check("integer", lambda o, n, x: _v.integer_in(o, n, x, lo, hi, text), (lo, hi))


def one_of_int(*values: int) -> Check:
    """One of a few integers (e.g. a power: 1 or 2)."""
    text = " or ".join(str(v) for v in values)
    return Check("one_of_int", lambda o, n, x: int(_v.one_of(o, n, x, values, text)),
                 (min(values), max(values)), values=values)


def half_open(lo: float, hi: float, unit: str = "") -> Check:
    """A finite value in [lo, hi); ``unit`` is named in the error message."""
    text = f"in [{lo:g}, {hi:g})" + (f" {unit}" if unit else "")
    return Check("half_open", lambda o, n, x: _v.interval(o, n, x, lo, hi, text), (lo, hi), hi_open=True)


def choice(*names: str) -> Check:
    """One of a fixed set of names."""
    return Check("choice", lambda o, n, x: _v.choice(o, n, x, names), values=names)


def vector(size: int, element: Check, labels: str = "") -> Check:
    """A tuple of ``size`` values, each passing ``element``; ``labels`` names them in the message."""
    need = f"needs {size} values" + (f" ({labels})" if labels else "")

    def apply(owner: str, name: str, value: Any) -> tuple[Any, ...]:
        if not hasattr(value, "__len__") or len(value) != size:
            raise ParameterError(f"{owner} parameter {name} = {value!r}: {need}")
        return tuple(element.apply(owner, f"{name}[{i}]", x) for i, x in enumerate(value))

    return Check(f"vector_{element.kind}", apply, element.bounds)


def param(default: Any, *, check: Check, doc: str, unit: str | None = None, tunable: bool = False) -> Any:
    """A parameter field: its default, its ``check``, its meaning ``doc`` (one line, the FMU variable's
    description), its ``unit`` (required for a real number or a vector of them; None for flags, counts and
    choices) and whether it may change during a run (``tunable``: the component accepts a new value
    between steps)."""
    return dataclasses.field(default=default,
                             metadata={"check": check, "doc": doc, "unit": unit, "tunable": tunable})


def facts(cls_or_obj: Any) -> dict[str, dict[str, Any]]:
    """The metadata of every field of a parameter dataclass (class or instance), by field name."""
    return {f.name: dict(f.metadata) for f in dataclasses.fields(cls_or_obj)}


def validate(obj: Any, owner: str) -> None:
    """Apply each field's check to ``obj`` in field order, storing the converted values.

    Raises :class:`ParameterError` (one line naming ``owner``, the field and the value) at the first
    refused value."""
    for f in dataclasses.fields(obj):
        setattr(obj, f.name, f.metadata["check"].apply(owner, f.name, getattr(obj, f.name)))
