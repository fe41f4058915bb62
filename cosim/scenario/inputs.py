"""Tabulated inputs: input signals read from a CSV file and sampled at the communication points.

The file has a time column first and one column per input, named ``instance.variable`` (or just
``variable`` when the system has one instance); two columns naming one input are refused.  Values are
read as the variable's type: Real as float, Integer and Enumeration as integers (exactly: a 64-bit value
is never passed through a float), Boolean as true/false/1/0, String as text.

Timing (the convention of FMPy's ``simulate_fmu(input=...)``): before the step from t_k, each input is set
to the table's value at t_k.  Real inputs of continuous variability are interpolated linearly by default
(``interpolation = "linear"``); at a time that appears twice in the table (a step in the signal) the value
after the step is taken.  Every other input (Real discrete, Integer, Boolean, String, Enumeration), and a
Real column declared ``"hold"``, holds the value of the last row at or before t_k.  Before the first row
the first value holds, after the last row the last value.  Times are compared with a relative tolerance
of 1e-9.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..messages.errors import ScenarioError
from ..model.description import Variable
from ..model.types import INT_RANGES

INTERPOLATIONS = ("linear", "hold")


@dataclass
class InputPlan:
    """One tabulated input: its instance and variable, and its value at every communication point."""

    instance: str
    var: Variable
    column: str
    mode: str
    values: np.ndarray          # one value per step k = 0 .. n_steps - 1 (float64, int64, bool or object)


def _isclose(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=1e-9)


def _convert(text: str, var: Variable, where: str, fld: str) -> float | int | bool | str:
    t = text.strip()
    try:
        if var.type == "Real":
            return float(t)
        if var.is_integer:
            v = int(t)
            lo, hi = INT_RANGES.get(var.fmi_type, INT_RANGES["Integer"])
            if not lo <= v <= hi:
                raise ScenarioError(where, fld, f"{t} does not fit the {var.fmi_type} {var.name} ({lo}..{hi})")
            return v
        if var.type == "Boolean":
            if t.lower() not in ("true", "false", "1", "0"):
                raise ValueError(t)
            return t.lower() in ("true", "1")
        return text
    except ValueError:
        raise ScenarioError(where, fld, f"{t!r} is not a valid {var.type}") from None


def sample_hold(t: np.ndarray, v: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """The value of the last row at or before each grid time (the first row's before it)."""
    idx = np.empty(len(grid), dtype=np.int64)
    i, n = 0, len(t)
    for k, tk in enumerate(grid.tolist()):
        while i + 1 < n and (t[i + 1] < tk or _isclose(tk, t[i + 1])):
            i += 1
        idx[k] = i
    return v[idx]


def sample_linear(t: np.ndarray, v: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Linear interpolation at each grid time; at a repeated time the value after the step."""
    out = np.empty(len(grid))
    tl = t.tolist()
    for k, tk in enumerate(grid.tolist()):
        i0 = int(np.searchsorted(t, tk))
        if i0 == 0:
            out[k] = v[0]
        elif i0 == len(tl):
            out[k] = v[-1]
        elif _isclose(tk, tl[i0]):
            while i0 + 1 < len(tl) and _isclose(tl[i0], tl[i0 + 1]):
                i0 += 1
            out[k] = v[i0]
        else:
            t0, t1 = tl[i0 - 1], tl[i0]
            w0 = (t1 - tk) / (t1 - t0)
            out[k] = w0 * v[i0 - 1] + (1 - w0) * v[i0]
    return out


def read_inputs(file: Path, where: str, interpolation: dict[str, str],
                resolve_var: Callable[[str], tuple[str, Variable]], grid: np.ndarray) -> list[InputPlan]:
    """Read the table ``file`` for the scenario ``where``; ``resolve_var(column) -> (instance, Variable)``
    names the input a column drives (raising ScenarioError if it cannot)."""
    fld = "inputs.file"
    try:
        with open(file, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(where, fld, f"cannot read {file}: {exc}") from None
    rows = [r for r in rows if r and not (len(r) == 1 and not r[0].strip())]
    if len(rows) < 2:
        raise ScenarioError(where, fld, f"{file}: needs a header row and at least one row of values")
    header = [h.strip() for h in rows[0]]
    for j, r in enumerate(rows[1:], start=2):
        if len(r) != len(header):
            raise ScenarioError(where, fld, f"{file}: line {j} has {len(r)} values for {len(header)} columns")
    try:
        t = np.array([float(r[0]) for r in rows[1:]])
    except ValueError as exc:
        raise ScenarioError(where, fld, f"{file}: the time column must hold numbers ({exc})") from None
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise ScenarioError(where, fld, f"{file}: the times must be finite and not decreasing")
    for ref, mode in interpolation.items():
        if ref not in header[1:]:
            raise ScenarioError(where, f"inputs.interpolation.{ref}", f"no column {ref!r} in {file}")
        if mode not in INTERPOLATIONS:
            raise ScenarioError(where, f"inputs.interpolation.{ref}", f"{mode!r}: must be linear or hold")
    plans = []
    first: dict[tuple[str, str], str] = {}   # (instance, variable) -> the column that drives it
    for j, col in enumerate(header[1:], start=1):
        inst, var = resolve_var(col)
        cfld = f"inputs.{col}"
        if (inst, var.name) in first:
            raise ScenarioError(where, cfld, f"{file}: column {col!r} drives {inst}.{var.name}, "
                                             f"as column {first[(inst, var.name)]!r} does")
        first[(inst, var.name)] = col
        vals = [_convert(r[j], var, where, cfld) for r in rows[1:]]
        continuous = var.type == "Real" and var.variability == "continuous"
        mode = interpolation.get(col, "linear" if continuous else "hold")
        if mode == "linear" and var.type != "Real":
            raise ScenarioError(where, f"inputs.interpolation.{col}", f"{var.type} inputs always hold their value")
        if var.type == "Real":
            arr = np.array(vals, dtype=np.float64)
            if not np.all(np.isfinite(arr)):
                raise ScenarioError(where, cfld, "values must be finite")
        elif var.type == "Boolean":
            arr = np.array(vals, dtype=bool)
        elif var.type == "String":
            arr = np.array(vals, dtype=object)
        elif var.fmi_type == "UInt64":
            arr = np.array(vals, dtype=np.uint64)
        else:
            arr = np.array(vals, dtype=np.int64)
        sampled = sample_linear(t, arr, grid) if mode == "linear" else sample_hold(t, arr, grid)
        plans.append(InputPlan(inst, var, col, mode, sampled))
    return plans
