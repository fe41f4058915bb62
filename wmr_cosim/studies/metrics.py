"""Metrics over recorded variables, for a sweep over any system: the sweep file's ``[metric.NAME]`` tables.

    [metric.x_end]                  # a column "x_end" of the results table
    of = "final"                    # what is measured (KINDS)
    variable = "dq.x"               # a recorded column of the run
    run = "run"                     # which run of the base (optional where it has one run)

    [metric.x_cross]
    of = "first_crossing"
    variable = "dq.x"
    level = 0.5                     # the time [s] the variable first reaches 0.5 (either way)

    [metric.x_err]
    of = "rmse"
    variable = "dq.x"
    reference = "ref.csv"           # a CSV file beside the sweep file: time first, then columns
    column = "x"                    # its column (default: the variable's name); or against = "other.var"

    [metric.x_settle]
    of = "settling_time"
    variable = "dq.x"
    target = 0.0
    band = 0.02                     # the time [s] from which |x - target| <= band until the end

Every definition is over the recorded samples (t_k, y_k) of the run, a time [s] taken where the run records
it: ``final`` y at the last sample; ``min``, ``max``; ``mean`` and ``rms`` over time (the trapezoidal rule
divided by the run's duration); ``integral`` (trapezoidal, [unit.s]); ``first_crossing`` (linear between
the two samples around the crossing, the start time where it begins on the level); ``rmse`` against a
reference (linear in the reference's time, which must cover the run's) or another recorded variable, over
the samples; ``settling_time``.  A run that recorded nothing, or a measure that does not happen (no
crossing, never settled), gives NaN.  The reference tables are read in the parent and travel with the
measure: a worker reads no file of the sweep.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..cosim import ScenarioError, read_signals, unknown_key

#: What a metric measures -> the keys it needs beside ``of``, ``variable`` and ``run``, and its unit given
#: the variable's ("{u}": the variable's own).
KINDS: dict[str, tuple[tuple[str, ...], str]] = {
    "final": ((), "{u}"), "min": ((), "{u}"), "max": ((), "{u}"), "mean": ((), "{u}"), "rms": ((), "{u}"),
    "integral": ((), "{u}.s"), "first_crossing": (("level",), "s"), "rmse": ((), "{u}"),
    "settling_time": (("target", "band"), "s"),
}
_KEYS = {"of", "variable", "run", "level", "reference", "column", "against", "target", "band"}


@dataclass(frozen=True)
class MetricSet:
    """A named set of metrics an application registers for its system (:func:`register_set`), which a sweep
    file asks for by name (``sets = ["NAME"]``): ``measure(row, results, work)`` puts its metrics of the
    point's runs (their folders in ``work``) into the row and may set its status and reason (a module-level
    function: it travels to the workers); ``columns(runs)`` every column it may add for these runs;
    ``description`` what ``sweep.json``'s table of columns says they hold; ``default``: asked for by a sweep
    file that names no metric."""

    name: str
    measure: Callable[[dict[str, Any], dict[str, Any], Path], None]
    columns: Callable[[list[str]], list[str]]
    description: str
    default: bool = False


#: The named sets of metrics a sweep file may ask for (``sets``), by name: those the applications registered.
SETS: dict[str, MetricSet] = {}


def register_set(metric_set: MetricSet) -> None:
    """Make a named set of metrics known to sweep files (again: replaced)."""
    SETS[metric_set.name] = metric_set


def default_sets() -> list[str]:
    """The sets a sweep file that names no metric measures."""
    return [name for name, s in SETS.items() if s.default]


@dataclass(frozen=True)
class MetricSpec:
    """One metric: a column of the results table (``name``)."""

    name: str
    of: str
    variable: str
    run: str | None = None
    level: float | None = None
    target: float | None = None
    band: float | None = None
    against: str | None = None
    reference: tuple[np.ndarray, np.ndarray] | None = field(default=None, compare=False)   # (time, values)
    reference_file: str | None = None

    def as_dict(self) -> dict[str, Any]:
        """What sweep.json says of it (the reference by its file)."""
        return {k: v for k, v in (("of", self.of), ("variable", self.variable), ("run", self.run),
                                  ("level", self.level), ("target", self.target), ("band", self.band),
                                  ("against", self.against), ("reference", self.reference_file)) if v is not None}


def parse_metrics(file: str, table: Any, folder: Path) -> list[MetricSpec]:
    """The ``[metric.NAME]`` tables of a sweep file (``folder``: where its reference files are); a bad one
    is a ScenarioError naming ``metric.NAME.field``."""
    if not isinstance(table, dict):
        raise ScenarioError(file, "metric", "must be a table of metrics ([metric.NAME])")
    return [_metric(file, name, d, folder) for name, d in table.items()]


def _metric(file: str, name: str, d: Any, folder: Path) -> MetricSpec:
    fld = f"metric.{name}"
    if not isinstance(d, dict):
        raise ScenarioError(file, fld, "must be a table (of, variable, ...)")
    for k in d:
        if k not in _KEYS:
            raise ScenarioError(file, f"{fld}.{k}", unknown_key(k, _KEYS))
    of = d.get("of")
    if of not in KINDS:
        raise ScenarioError(file, f"{fld}.of", f"{of!r}: unknown metric (known: {', '.join(KINDS)})")
    variable = d.get("variable")
    if not isinstance(variable, str) or "." not in variable:
        raise ScenarioError(file, f"{fld}.variable", f"{variable!r}: a recorded variable, \"instance.variable\"")
    run = d.get("run")
    if run is not None and not isinstance(run, str):
        raise ScenarioError(file, f"{fld}.run", f"{run!r}: the name of a run of the base")
    nums: dict[str, Any] = {}
    for k in KINDS[of][0]:
        if k not in d:
            raise ScenarioError(file, f"{fld}.{k}", f"missing: {of} needs {' and '.join(KINDS[of][0])}")
    for k in ("level", "target", "band"):
        if k in d:
            v = d[k]
            if k not in KINDS[of][0]:
                raise ScenarioError(file, f"{fld}.{k}", f"{of} takes no {k}")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or \
                    (k == "band" and v < 0):
                raise ScenarioError(file, f"{fld}.{k}", f"{v!r}: must be a finite number" + (" >= 0" if k == "band" else ""))
            nums[k] = float(v)
    against, reference = d.get("against"), None
    if of == "rmse":
        if ("reference" in d) == (against is not None):
            raise ScenarioError(file, fld, "rmse needs one of reference (a CSV file) and against (a variable)")
        if against is not None and (not isinstance(against, str) or "." not in against):
            raise ScenarioError(file, f"{fld}.against", f"{against!r}: a recorded variable, \"instance.variable\"")
        if "reference" in d:
            reference = _reference(file, fld, d["reference"], d.get("column", variable), folder)
            nums["reference_file"] = str(d["reference"])
    elif "reference" in d or "against" in d or "column" in d:
        raise ScenarioError(file, fld, f"{of} takes no reference, column or against (rmse does)")
    return MetricSpec(name, of, variable, run, against=against, reference=reference, **nums)


def _reference(file: str, fld: str, ref: Any, column: Any, folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], values) of a reference CSV's column: UTF-8 text, a header, time first, rising, every value of
    the two columns a finite number (a bad one named by its line and column)."""
    if not isinstance(ref, str):
        raise ScenarioError(file, f"{fld}.reference", f"{ref!r}: a CSV file beside the sweep file")
    path = folder / ref
    try:   # (is_file raises for a name the system cannot look up: too long)
        if not path.is_file():
            raise ScenarioError(file, f"{fld}.reference", f"{ref}: file not found")
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            rows = [(reader.line_num, r) for r in reader]
    except UnicodeDecodeError:
        raise ScenarioError(file, f"{fld}.reference", f"{ref}: not a text file (a CSV file is UTF-8 text)") from None
    except (OSError, csv.Error) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else " ".join(str(exc).split())
        raise ScenarioError(file, f"{fld}.reference", f"{ref[:60]}: cannot be read ({why})") from None
    if len(rows) < 3:
        raise ScenarioError(file, f"{fld}.reference", f"{ref}: a header and at least two rows are needed")
    head = [h.strip() for h in rows[0][1]]
    if column not in head[1:]:
        raise ScenarioError(file, f"{fld}.column", f"{ref} has no column {column!r} (it has: {', '.join(head[1:])})")
    j = head.index(column)
    t, v = np.empty(len(rows) - 1), np.empty(len(rows) - 1)
    for i, (line, r) in enumerate(rows[1:]):
        for k, out in ((0, t), (j, v)):
            text = r[k].strip() if k < len(r) else ""
            try:
                out[i] = float(text)
            except ValueError:
                out[i] = math.nan
            if not math.isfinite(out[i]):
                raise ScenarioError(file, f"{fld}.reference", f"{ref}, line {line}, column {head[k]!r}: "
                                                              f"{text!r} is not a finite number")
    if not np.all(np.diff(t) > 0):
        raise ScenarioError(file, f"{fld}.reference", f"{ref}: the times (first column) must rise")
    return t, v


def check_metrics(file: str, metrics: list[MetricSpec], runs: dict[str, dict[str, str | None]],
                  spans: dict[str, tuple[float, float]] | None = None, taken: dict[str, str] | None = None
                  ) -> dict[str, str | None]:
    """Each metric against what the base's runs record (``runs``: run -> {column: unit}): the run exists
    (or the base has one run), its variables are recorded, its reference covers the run's time (``spans``:
    run -> (start, stop) [s]), its name is not a column the results table has already (``taken``: column
    -> what it holds).  Returns each metric's unit."""
    units: dict[str, str | None] = {}
    for m in metrics:
        fld = f"metric.{m.name}"
        if taken and m.name in taken:
            raise ScenarioError(file, fld, f"{m.name!r} is already a column of the results table ({taken[m.name]}): "
                                           "name the metric otherwise")
        if m.run is None and len(runs) != 1:
            raise ScenarioError(file, f"{fld}.run", f"missing: the base has {len(runs)} runs ({', '.join(runs)})")
        run = m.run if m.run is not None else next(iter(runs))
        if run not in runs:
            raise ScenarioError(file, f"{fld}.run", f"{run!r} is not a run of the base ({', '.join(runs)})")
        for key, var in (("variable", m.variable), ("against", m.against)):
            if var is not None and var not in runs[run]:
                raise ScenarioError(file, f"{fld}.{key}", f"{var!r} is not recorded by run {run!r}")
        if m.reference is not None and spans and run in spans:
            (t0, t1), rt = spans[run], m.reference[0]
            if rt[0] > t0 or rt[-1] < t1:
                raise ScenarioError(file, f"{fld}.reference", f"{m.reference_file}: its times ({rt[0]:g} to "
                                                              f"{rt[-1]:g} s) do not cover run {run!r} ({t0:g} to "
                                                              f"{t1:g} s)")
        u, unit = runs[run][m.variable], KINDS[m.of][1]
        units[m.name] = unit if "{u}" not in unit else unit.format(u=u) if u is not None else None
    return units


def value(m: MetricSpec, t: np.ndarray, y: np.ndarray, other: np.ndarray | None = None) -> float:
    """The metric of one run's samples (t [s], y; ``other``: the ``against`` variable's)."""
    if len(t) == 0:
        return math.nan
    if m.of == "final":
        return float(y[-1])
    if m.of in ("min", "max"):
        return float(y.min() if m.of == "min" else y.max())
    if m.of in ("mean", "rms", "integral"):
        return _over_time(m.of, t, y)
    if m.of == "first_crossing":
        assert m.level is not None
        return _first_crossing(t, y, m.level)
    if m.of == "settling_time":
        assert m.target is not None and m.band is not None
        outside = np.flatnonzero(np.abs(y - m.target) > m.band)
        if len(outside) == 0:
            return float(t[0])
        return float(t[outside[-1] + 1]) if outside[-1] + 1 < len(t) else math.nan
    if other is None:
        assert m.reference is not None
        rt, rv = m.reference
        if t[0] < rt[0] or t[-1] > rt[-1]:
            return math.nan   # (the reference does not cover the run)
        other = np.interp(t, rt, rv)
    return float(np.sqrt(np.mean((y - other) ** 2)))


def _over_time(kind: str, t: np.ndarray, y: np.ndarray) -> float:
    """mean and rms over the run's duration, or the integral (trapezoidal rule)."""
    if kind == "integral":
        return _trapezoid(y, t)
    duration = float(t[-1] - t[0])
    if duration <= 0.0:
        return float(y[0]) if kind == "mean" else float(abs(y[0]))
    if kind == "mean":
        return _trapezoid(y, t) / duration
    return math.sqrt(_trapezoid(y * y, t) / duration)


def _trapezoid(y: np.ndarray, t: np.ndarray) -> float:
    """The trapezoidal rule's integral of y over t (numpy's trapezoid, which numpy 1.x names trapz)."""
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2.0)


def _first_crossing(t: np.ndarray, y: np.ndarray, level: float) -> float:
    d = y - level
    if d[0] == 0.0:
        return float(t[0])
    hit = np.flatnonzero(np.sign(d[1:]) != np.sign(d[:-1]))
    if len(hit) == 0:
        return math.nan
    i = int(hit[0])
    return float(t[i] + (t[i + 1] - t[i]) * d[i] / (d[i] - d[i + 1]))


@dataclass(frozen=True)
class SweepMeasure:
    """What a point measures (sweep.run_point's ``measure``): the named sets asked for, then each metric
    from its run's recorded signals (``work/<run>/signals.npy``); picklable, it travels to the workers."""

    metrics: tuple[MetricSpec, ...] = ()
    sets: tuple[MetricSet, ...] = ()
    runs: tuple[str, ...] = ()    # the base's runs, for the metrics that name none (a base of one run)

    def __call__(self, row: dict[str, Any], results: dict[str, Any], work: Path) -> None:
        for s in self.sets:
            s.measure(row, results, work)
        data: dict[str, Any] = {}   # each run's signals, read once
        for m in self.metrics:
            run = m.run if m.run is not None else self.runs[0]
            if run not in data:
                f = work / run / "signals.npy"
                data[run] = read_signals(f).signals if f.is_file() else None
            row[m.name] = _measured(m, data[run])


def _measured(m: MetricSpec, data: np.ndarray | None) -> float:
    """The metric of a run's recorded rows (None or none: NaN)."""
    if data is None or not len(data):
        return math.nan
    other = np.asarray(data[m.against], dtype=float) if m.against is not None else None
    return value(m, np.asarray(data["time"], dtype=float), np.asarray(data[m.variable], dtype=float), other)
