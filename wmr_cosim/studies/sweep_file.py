"""Sweep files: their parser and the points they describe (the runs are sweep.py's).

A sweep file (``scenarios/sweep-*.toml``)::

    base = "paper/g1.toml"        # a scenario or protocol file (its runs: learn, frozen, foam, ...)
    variant = "freeze"            # optional: a variant the base declares
    runs = ["learn", "frozen", "foam"]   # optional: which of its runs (default all)
    seed = 1                      # for the random draws
    samples = 8                   # random draws per grid point (default 1)
    metrics = ["foam.rmse_e1", "gamma_star"]   # the columns to plot (the table keeps every metric)
    sets = ["robot"]              # named sets of metrics (default: those registered as such, unless [metric] is given)
    [metric.x_end]                # a metric over a recorded variable (metrics.py): any system
    of = "final"
    variable = "dq.x"
    [grid]                        # the cartesian product of these
    "plant.foam_da1+plant.foam_da2" = [0.2, 0.4, 0.8]   # '+' links parameters to one value
    [random]                      # drawn with the seed, `samples` times per grid point
    "plant.foam_t_on" = { dist = "uniform", low = 7.0, high = 10.0 }
    "controller.l1" = { dist = "normal", mean = 0.16, std = 0.004 }

Points are drawn in the parent from the seed (:func:`draw_points`), so the results do not depend on the
number of workers.
"""
from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..cosim import ScenarioError, unknown_key
from .metrics import SETS, MetricSpec, default_sets, parse_metrics

DISTRIBUTIONS = {"uniform": ("low", "high"), "normal": ("mean", "std"), "lognormal": ("mean", "sigma"),
                 "choice": ("values",)}
_KEYS = {"description", "base", "variant", "runs", "seed", "samples", "metrics", "grid", "random", "keep_runs",
         "metric", "sets"}


@dataclass
class SweepSpec:
    file: str
    base: str
    variant: str | None = None
    runs: list[str] | None = None
    seed: int = 0
    samples: int = 1
    metrics: list[str] = field(default_factory=list)
    grid: dict[str, list[Any]] = field(default_factory=dict)       # "a.x+b.y" -> values
    random: dict[str, dict[str, Any]] = field(default_factory=dict)
    keep_runs: bool = False
    description: str = ""
    measures: list[MetricSpec] = field(default_factory=list)   # [metric.NAME]
    sets: list[str] = field(default_factory=list)              # named sets of metrics ("robot")


def load_sweep(path: str | os.PathLike) -> SweepSpec:
    """Read and check a sweep file; errors name the file, the field and the reason."""
    path = Path(path)
    f = str(path)
    doc = _read(path)
    spec = SweepSpec(f, str(base_file(path, doc.get("base"))), doc.get("variant"), doc.get("runs"),
                     description=str(doc.get("description", "")))
    _check_settings(f, doc, spec)
    _check_measures(f, doc, spec, path.parent)
    _check_grid(f, doc, spec)
    _check_random(f, doc, spec)
    _check_base(f, spec)
    return spec


def _read(path: Path) -> dict[str, Any]:
    """The sweep file's table: a file, valid TOML, no unknown key."""
    from ..cosim import read_toml

    f = str(path)
    doc = read_toml(path)
    for k in doc:
        if k not in _KEYS:
            raise ScenarioError(f, k, unknown_key(k, _KEYS))
    return doc


def _check_settings(f: str, doc: dict[str, Any], spec: SweepSpec) -> None:
    """seed, samples, metrics, runs and keep_runs into ``spec``."""
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f, "seed", f"{seed!r}: must be an integer >= 0")
    spec.seed = seed
    samples = doc.get("samples", 1)
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ScenarioError(f, "samples", f"{samples!r}: must be an integer >= 1")
    spec.samples = samples
    metrics = doc.get("metrics", [])
    if not isinstance(metrics, list) or not all(isinstance(m, str) for m in metrics):
        raise ScenarioError(f, "metrics", "must be an array of metric names")
    spec.metrics = metrics
    if spec.runs is not None and (not isinstance(spec.runs, list) or not all(isinstance(r, str) for r in spec.runs)):
        raise ScenarioError(f, "runs", "must be an array of run names")
    keep = doc.get("keep_runs", False)
    if not isinstance(keep, bool):
        raise ScenarioError(f, "keep_runs", "must be true or false")
    spec.keep_runs = keep


def _check_measures(f: str, doc: dict[str, Any], spec: SweepSpec, folder: Path) -> None:
    """[metric.NAME] and ``sets`` into ``spec`` (the registered default sets where no metric is given)."""
    spec.measures = parse_metrics(f, doc["metric"], folder) if "metric" in doc else []
    sets = doc.get("sets", [] if spec.measures else default_sets())
    if not isinstance(sets, list) or not all(s in SETS for s in sets):
        raise ScenarioError(f, "sets", f"{sets!r}: an array of named sets of metrics ({', '.join(SETS)})")
    spec.sets = list(sets)


def _check_grid(f: str, doc: dict[str, Any], spec: SweepSpec) -> None:
    """The [grid] table into ``spec.grid``."""
    grid = doc.get("grid", {})
    if not isinstance(grid, dict):
        raise ScenarioError(f, "grid", "must be a table \"instance.param\" = [values]")
    for key, values in grid.items():
        parameter_refs(f, f"grid.{key}", key)
        if not isinstance(values, list) or not values:
            raise ScenarioError(f, f"grid.{key}", "must be a non-empty array of values")
        spec.grid[key] = list(values)


def _check_random(f: str, doc: dict[str, Any], spec: SweepSpec) -> None:
    """The [random] table into ``spec.random``."""
    rnd = doc.get("random", {})
    if not isinstance(rnd, dict):
        raise ScenarioError(f, "random", "must be a table \"instance.param\" = {dist = ..., ...}")
    for key, d in rnd.items():
        fld = f"random.{key}"
        parameter_refs(f, fld, key)
        _check_distribution(f, fld, d)
        spec.random[key] = dict(d)


def _check_distribution(f: str, fld: str, d: Any) -> None:
    """One distribution of [random]: a known ``dist`` with its parameters, and only those, each a value the
    draw takes: finite numbers, low < high (a finite width), std and sigma >= 0, a non-empty array of
    values."""
    if not isinstance(d, dict) or not isinstance(d.get("dist"), str) or d["dist"] not in DISTRIBUTIONS:
        raise ScenarioError(f, fld, f"needs dist = one of {', '.join(DISTRIBUTIONS)}")
    need = DISTRIBUTIONS[d["dist"]]
    extra = set(d) - set(need) - {"dist"}
    if extra:
        raise ScenarioError(f, f"{fld}.{sorted(extra)[0]}", f"unknown key for dist = {d['dist']!r}")
    for k in need:
        if k not in d:
            raise ScenarioError(f, f"{fld}.{k}", f"missing (dist = {d['dist']!r} needs {', '.join(need)})")
    if d["dist"] == "choice":
        if not isinstance(d["values"], list) or not d["values"]:
            raise ScenarioError(f, f"{fld}.values", "must be a non-empty array of values")
        return
    for k in need:
        v = d[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ScenarioError(f, f"{fld}.{k}", f"{v!r}: must be a finite number")
    if d["dist"] == "uniform" and not d["low"] < d["high"]:
        raise ScenarioError(f, f"{fld}.high", "must be above low")
    if d["dist"] == "uniform" and not math.isfinite(float(d["high"]) - float(d["low"])):
        raise ScenarioError(f, f"{fld}.high", "high - low must be a finite number")
    spread = {"normal": "std", "lognormal": "sigma"}.get(d["dist"])
    if spread is not None and not d[spread] >= 0:
        raise ScenarioError(f, f"{fld}.{spread}", f"{d[spread]!r}: must be >= 0")


def _check_base(f: str, spec: SweepSpec) -> None:
    """The base must parse (model names are not built here), and the variant and runs must exist."""
    from ..cosim import plan_runs

    _, runs, _ = plan_runs(read_base(spec.base, lambda name: Path(name)), variant=spec.variant)
    if spec.runs:
        names = [r.name for r in runs]
        for r in spec.runs:
            if r not in names:
                raise ScenarioError(f, "runs", f"{r!r} is not a run of {spec.base} ({', '.join(names)})")


def parameter_refs(file: str, fld: str, key: str) -> list[str]:
    """The parameters a key of [grid] or [random] names ("a.x+b.y": linked), each "instance.param"."""
    refs = key.split("+")
    for r in refs:
        if r.count(".") < 1 or not all(r.split(".", 1)):
            raise ScenarioError(file, fld, f"{r!r} is not of the form \"instance.param\"")
    return refs


def base_file(path: Path, base: Any) -> Path:
    """The base scenario a study file (a sweep or falsification file at ``path``) names, by the rule of a
    scenario's ``base``: beside the file, else among the shipped scenarios; ScenarioError naming the file's
    ``base`` otherwise."""
    from ..cosim import base_path
    from ..scenario_files import shipped_folder

    f = str(path)
    if not isinstance(base, str) or not base:
        raise ScenarioError(f, "base", "missing: the base scenario (a file name)")
    found = base_path(path, base, shipped_folder())
    try:
        found.is_file()
    except OSError as exc:   # a name the system cannot look up (too long, ...)
        raise ScenarioError(f, "base", f"{base[:60]!r}...: cannot be read ({exc.strerror or exc})") from None
    if not found.is_file():
        raise ScenarioError(f, "base", f"{base!r}: the base scenario is "
                                       f"{'a folder' if found.is_dir() else 'not found'} ({found}; nor a shipped "
                                       "scenario)")
    return found.resolve()


def read_base(base: str, resolver: Any, limits: Any = None) -> Any:
    """A study's base scenario read once (a :class:`~wmr_cosim.cosim.Protocol`) as ``run`` reads a scenario:
    its own ``base`` found beside it, else among the shipped scenarios; ``resolver``: model name -> FMU;
    ``limits``: the caller's archive limits."""
    from ..cosim import read_protocol
    from ..scenario_files import shipped_folder

    return read_protocol(base, resolver, limits, shipped_folder())


def check_parameters(file: str, axes: dict[str, str], plans: dict[str, Any],
                     ranges: dict[str, tuple[float, float]] | None = None) -> None:
    """The parameters a study varies (``axes``: its field, e.g. "grid.a.x+b.y", -> the key), each against
    the base's runs (``plans``: run -> its checked plan), by the rule a scenario's parameters follow: the
    instance exists, it has the variable (else the nearest name), the variable can be set.  A reference to
    ``experiment.FIELD`` or ``record.FIELD`` is the scenario's own to judge, at each point.  With ``ranges``
    (field -> (low, high), a falsification's box), each is a Real whose declared range holds the box.
    ScenarioError naming ``file`` and the field."""
    from ..cosim import PARAMETERS, SET_TABLES, did_you_mean, variable

    for fld, key in axes.items():
        for ref in parameter_refs(file, fld, key):
            inst, name = ref.split(".", 1)
            for plan in plans.values():
                if inst not in plan.instances:
                    if inst in SET_TABLES:
                        break
                    raise ScenarioError(file, fld, f"{ref}: the base has no instance {inst!r}"
                                                   f"{did_you_mean(inst, plan.instances)}")
                var = variable(file, fld, plan.instances[inst], name, PARAMETERS)
                reason = var.settable()
                if reason:
                    raise ScenarioError(file, fld, f"{ref}: {reason}")
                if ranges is None:
                    continue
                if var.type != "Real" or var.shape:
                    raise ScenarioError(file, fld, f"{ref} is {'an array' if var.shape else var.type}: a search "
                                                   "varies Real parameters")
                for v in ranges[fld]:
                    reason = var.check_range(v)
                    if reason:
                        raise ScenarioError(file, fld, f"{ref}: {reason}")


def draw_points(spec: SweepSpec) -> list[dict[str, Any]]:
    """Every point: {'id': i, 'params': {'instance.param': value}}; random values drawn from the seed."""
    rng = np.random.default_rng(spec.seed)
    grid_keys = list(spec.grid)
    combos = list(itertools.product(*(spec.grid[k] for k in grid_keys))) if grid_keys else [()]
    out: list[dict[str, Any]] = []
    for combo in combos:
        for _ in range(spec.samples):
            params: dict[str, Any] = {}
            for key, value in zip(grid_keys, combo):
                for ref in key.split("+"):
                    params[ref] = value
            for key, d in spec.random.items():
                v = _draw(rng, d)
                for ref in key.split("+"):
                    params[ref] = v
            out.append({"id": len(out), "params": params})
    return out


def _draw(rng: np.random.Generator, d: dict[str, Any]) -> Any:
    """One value of the distribution ``d`` of [random]."""
    if d["dist"] == "uniform":
        return float(rng.uniform(d["low"], d["high"]))
    if d["dist"] == "normal":
        return float(rng.normal(d["mean"], d["std"]))
    if d["dist"] == "lognormal":
        return float(rng.lognormal(d["mean"], d["sigma"]))
    return d["values"][int(rng.integers(len(d["values"])))]
