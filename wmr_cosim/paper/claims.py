"""Pass/fail statements of the report, computed from the metrics they sit beside.

A claim names a number of ``metrics.json`` by its path (dots between keys, list indices as numbers),
a relation and a bound.  Its text is generated from the number, so it cannot say more than the number:
``gamma* (53) of G1 at 50 s = 13.60 > 11 (gamma of Table 1): no``.  :func:`check_claims` re-reads
every claim's number from the metrics and fails on any disagreement (value, verdict or wording).
"""
from __future__ import annotations

import math
import operator
from typing import Any

from .document import fmt

_OPS = {"<=": operator.le, "<": operator.lt, ">=": operator.ge, ">": operator.gt, "==": operator.eq}
#: the relation that holds when the claimed one does not
_NEG = {"<=": ">", "<": ">=", ">=": "<", ">": "<=", "==": "!="}


def resolve(metrics: dict[str, Any], path: str) -> Any:
    """The value at ``path`` ('tasks.G1.foam.edge_peak_u', 'tasks.LINE.frozen.cruise_u.0'); a path
    ending in '#len' gives the length of a list."""
    x: Any = metrics
    for key in path.split("."):
        if key == "#len":
            x = len(x)
        elif isinstance(x, list):
            x = x[int(key)]
        else:
            x = x[key]
    return x


def holds(value: Any, op: str, bound: float) -> bool:
    """Whether ``value op bound``; a missing or non-finite value never holds."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return False
    return bool(_OPS[op](value, bound))


def claim_text(subject: str, value: Any, op: str, bound: float, bound_name: str, digits: int) -> str:
    """The sentence of a claim: the number, the relation that is true, the bound, and yes / no."""
    ok = holds(value, op, bound)
    rel = op if ok else _NEG[op]
    if value is None:
        return f"{subject}: not available (claimed {op} {fmt(bound, digits)}, {bound_name}): no"
    return f"{subject} = {fmt(value, digits)} {rel} {fmt(bound, digits)} ({bound_name}): {'yes' if ok else 'no'}"


def make_claim(metrics: dict[str, Any], cid: str, path: str, subject: str, op: str, bound: float,
               bound_name: str, digits: int = 2) -> dict[str, Any]:
    """A claim from the number at ``path`` of ``metrics``."""
    try:
        value = resolve(metrics, path)
    except (KeyError, IndexError, TypeError, ValueError):
        value = None
    if isinstance(value, bool):
        value = int(value)
    return {"id": cid, "path": path, "subject": subject, "value": value, "op": op, "bound": bound,
            "bound_name": bound_name, "digits": digits, "holds": holds(value, op, bound),
            "text": claim_text(subject, value, op, bound, bound_name, digits)}


def check_claims(metrics: dict[str, Any], report_text: str | None = None) -> list[str]:
    """Every disagreement between a claim of ``metrics['claims']`` and the metrics (and, with
    ``report_text``, a claim missing from the report): an empty list when all agree."""
    errors = []
    for c in metrics.get("claims", []):
        try:
            value = resolve(metrics, c["path"])
        except (KeyError, IndexError, TypeError, ValueError):
            value = None
        if isinstance(value, bool):
            value = int(value)
        same = (value is None and c["value"] is None) or (
            value is not None and c["value"] is not None and math.isclose(value, c["value"], rel_tol=1e-12))
        if not same:
            errors.append(f"{c['id']}: the claim says {c['value']!r}, metrics.{c['path']} is {value!r}")
            continue
        ok = holds(value, c["op"], c["bound"])
        if ok != c["holds"]:
            errors.append(f"{c['id']}: holds = {c['holds']} but {value!r} {c['op']} {c['bound']!r} is {ok}")
        want = claim_text(c["subject"], value, c["op"], c["bound"], c["bound_name"], c["digits"])
        if c["text"] != want:
            errors.append(f"{c['id']}: the text {c['text']!r} does not state {want!r}")
        if report_text is not None and c["text"] not in report_text:
            errors.append(f"{c['id']}: not in the report: {c['text']!r}")
    return errors
