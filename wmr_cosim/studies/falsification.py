"""Falsification: the search of a parameter space for the point where a requirement is closest to failing,
or fails worst (the lowest robustness), with a global optimiser, every point a full co-simulation on the
sweep machinery (Dask, one JSON per point: a search started again with the same output folder takes the
points already run, and, being deterministic for its seed, gives the same answer).

A falsification file (``scenarios/falsify-*.toml``)::

    base = "g1_requirements.toml"     # a scenario or protocol with [[requirements]]
    requirement = "tracking"          # the one whose robustness is minimised
    run = "foam"                      # which run of a protocol (optional for a scenario of one run)
    variant = "freeze"                # optional: a variant the base declares
    seed = 1
    budget = 40                       # co-simulations of the search (the nominal run and the re-run of the
                                      # worst case come on top)
    [space]                           # the box searched ('+' links parameters to one value)
    "plant.foam_da1+plant.foam_da2" = { low = 0.2, high = 1.2 }
    "plant.foam_t_on" = { low = 5.0, high = 11.0 }

The optimiser is scipy's differential evolution (``scipy.optimize.differential_evolution``: deferred
updating, so that each generation's population is one batch of points run in parallel; its initial
population a Latin hypercube drawn from the seed; no local polish, which would add runs beyond the
budget).  With N axes the population has M = max(5, min(10 N, budget // 4)) members and the search runs
budget // M - 1 generations after the initial one: budget // M * M co-simulations.  Why not dual
annealing or CMA-ES: each proposes one point after another (no batch to run in parallel); Nevergrad
would be one more dependency for the same batched evolution.
"""
from __future__ import annotations

import json
import math
import os
import shlex
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..cosim import CosimError, LimitOverrides, RunStatus, ScenarioError, unknown_key
from .cluster import Cluster
from .sweep import run_points
from .system import System

_KEYS = {"description", "base", "requirement", "run", "variant", "seed", "budget", "space"}


@dataclass
class FalsifySpec:
    file: str
    base: str
    requirement: str
    run: str = "run"
    variant: str | None = None
    seed: int = 0
    budget: int = 40
    space: dict[str, tuple[float, float]] = field(default_factory=dict)   # "a.x+b.y" -> (low, high)
    description: str = ""

    @property
    def parameters(self) -> list[str]:
        """Every parameter the space sets ("a.x+b.y" sets both)."""
        return [ref for key in self.space for ref in key.split("+")]

    @property
    def column(self) -> str:
        """The results table's column of the requirement's robustness."""
        return f"{self.run}.{self.requirement}.robustness"


#: The largest seed: the optimiser's generator (numpy's RandomState) takes seeds of 32 bits.
MAX_SEED = 2**32 - 1
#: The fewest co-simulations of a search: a population of 5, two generations.
MIN_BUDGET = 10


def load_falsification(path: str | os.PathLike, seed: int | None = None, budget: int | None = None) -> FalsifySpec:
    """Read and check a falsification file: its keys, the space (finite bounds, low < high, parameters
    as "instance.param"), the seed and the budget (``seed`` and ``budget``: a command line's, over the
    file's, checked alike and named by their options), and the base (beside the file or a shipped
    scenario): it parses, declares the requirement, and the run.  The space against the base's FMUs is
    :func:`check_space`'s."""
    from ..cosim import plan_runs
    from ..cosim import read_toml
    from .sweep_file import base_file, read_base

    p = Path(path)
    f = str(p)
    doc = read_toml(p)
    unknown = sorted(set(doc) - _KEYS)
    if unknown:
        raise ScenarioError(f, unknown[0], unknown_key(unknown[0], _KEYS))
    for key in ("base", "requirement"):
        if not isinstance(doc.get(key), str):
            raise ScenarioError(f, key, "missing (a string)")
    spec = FalsifySpec(f, str(base_file(p, doc["base"])), doc["requirement"],
                       description=str(doc.get("description", "")))
    for key, given in (("seed", seed), ("budget", budget)):
        if key in doc:
            reason = _whole(doc[key])
            if reason:
                raise ScenarioError(f, key, reason)
            setattr(spec, key, doc[key])
        if given is not None:   # the command line's, over the file's
            reason = _whole(given)
            if reason:
                raise CosimError(f"--{key} {reason}")
            setattr(spec, key, given)
    spec.space = _read_space(f, doc.get("space"))
    if spec.budget < MIN_BUDGET:
        reason = f"{spec.budget}: at least {MIN_BUDGET} co-simulations (a population of 5, two generations)"
        raise CosimError(f"--budget {reason}") if budget is not None else ScenarioError(f, "budget", reason)
    if "variant" in doc:
        spec.variant = str(doc["variant"])
    sc, runs, _ = plan_runs(read_base(spec.base, lambda name: Path(name)), variant=spec.variant)
    names = [r.name for r in runs]
    spec.run = str(doc.get("run", names[0] if len(names) == 1 else ""))
    if spec.run not in names:
        raise ScenarioError(f, "run", f"{spec.run!r}: one of the base's runs ({', '.join(names)})" if spec.run
                            else f"the base has runs {', '.join(names)}: say which one's requirement")
    known = [r.name for r in sc.requirements]
    if spec.requirement not in known:
        raise ScenarioError(f, "requirement", f"{spec.requirement!r}: the base declares "
                                              f"{', '.join(repr(k) for k in known) or 'no requirements'}")
    return spec


def _read_space(f: str, space: Any) -> dict[str, tuple[float, float]]:
    """A falsification file's ``space`` ("instance.param" -> (low, high)), each box finite with low < high;
    ScenarioError naming the file ``f`` and the key."""
    from .sweep_file import parameter_refs

    if not isinstance(space, dict) or not space:
        raise ScenarioError(f, "space", "missing: a table \"instance.param\" = { low = ..., high = ... }")
    out: dict[str, tuple[float, float]] = {}
    for key, box in space.items():
        fld = f"space.{key}"
        parameter_refs(f, fld, key)
        if not isinstance(box, dict) or set(box) != {"low", "high"}:
            raise ScenarioError(f, fld, "must be { low = ..., high = ... }")
        lo, hi = box["low"], box["high"]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in (lo, hi)):
            raise ScenarioError(f, fld, "low and high must be finite numbers")
        if not lo < hi:
            raise ScenarioError(f, f"{fld}.high", "must be above low")
        out[key] = (float(lo), float(hi))
    return out


def _whole(v: Any) -> str | None:
    """Why ``v`` is not a seed or a budget (a whole number from 0 to :data:`MAX_SEED`: the optimiser's seeds
    are of 32 bits, and a budget beyond is centuries of runs), or None."""
    if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= MAX_SEED:
        return f"{v!r}: must be a whole number from 0 to {MAX_SEED}"
    return None


def check_space(spec: FalsifySpec, archive_limits: LimitOverrides | None = None, system: System | None = None
                ) -> None:
    """The space against the base's runs (their FMUs resolved: the system's model names only if the base
    names them), before any run: each parameter exists, can be set, is Real, and its declared range holds
    the box."""
    from ..cosim import check_protocol
    from .sweep_file import check_parameters, read_base

    models = (system or System()).models
    plans = check_protocol(read_base(spec.base, models, archive_limits), variant=spec.variant)
    check_parameters(spec.file, {f"space.{k}": k for k in spec.space}, plans,
                     ranges={f"space.{k}": box for k, box in spec.space.items()})


def population(budget: int, axes: int) -> tuple[int, int]:
    """(members, generations after the initial one) for a budget of co-simulations over ``axes`` axes."""
    members = max(5, min(10 * axes, budget // 4))
    return members, budget // members - 1


def falsify(path: str | os.PathLike, out: str | os.PathLike | None = None, workers: int | None = None,
            scheduler: str | None = None, progress: bool | None = None, security: Any = None,
            dashboard: bool = False, archive_limits: LimitOverrides | None = None,
            say: Callable[[str], None] | None = None, seed: int | None = None,
            budget: int | None = None, system: System | None = None) -> dict[str, Any]:
    """Search the file's space for the lowest robustness of its requirement; write falsify.json,
    falsify.csv and falsify.png into ``out`` (default results/<file>) and the worst case's re-run into
    ``out/worst``; return falsify.json's content.  ``say``: told a line after each generation; ``seed``
    and ``budget``: over the file's; ``system``: the system the points run (:class:`System`; none by
    default, every FMU named by its path).  The file, the options and the space against the base's FMUs are
    checked before the results folder is made."""
    from .cluster import check_worker_count
    from ..cosim import OutputLock, make_folder

    check_worker_count(workers)
    spec = load_falsification(path, seed, budget)
    system = system if system is not None else System()
    check_space(spec, archive_limits, system)
    out = make_folder(Path(out) if out is not None else Path("results") / Path(path).stem)
    with OutputLock(out):
        return _search(spec, out, workers, scheduler, progress, security, dashboard, archive_limits, say, system)


def _params(spec: FalsifySpec, x: np.ndarray) -> dict[str, float]:
    params: dict[str, float] = {}
    for key, v in zip(spec.space, x):
        for ref in key.split("+"):
            params[ref] = float(v)
    return params


def _robustness(spec: FalsifySpec, row: dict[str, Any]) -> float:
    """A point's robustness of the requirement; +inf for a point that failed (it gave no robustness: see
    :func:`.sweep.point_status`)."""
    v = row.get(spec.column)
    if row["status"] != RunStatus.FAILED and isinstance(v, (int, float)) and not math.isnan(v):
        return float(v)
    return math.inf


def _search(spec: FalsifySpec, out: Path, workers: int | None, scheduler: str | None, progress: bool | None,
            security: Any, dashboard: bool, archive_limits: LimitOverrides | None,
            say: Callable[[str], None] | None, system: System) -> dict[str, Any]:
    meta = out / "falsify.json"
    if meta.is_file():
        old = json.loads(meta.read_text()).get("spec")
        if old != json.loads(json.dumps(asdict(spec))):
            raise CosimError(f"{out}: holds the results of another search (a different file, seed or space); "
                             "use another --out")
    members, generations = population(spec.budget, len(spec.space))
    rows: list[dict[str, Any]] = []
    with Cluster(workers, scheduler, security, dashboard) as cl:
        # every run of the base (a later run may carry an earlier one's values)
        nominal = run_points([{"id": 0, "params": {}}], spec.base, spec.variant, None, out, cl,
                             progress=False, label="falsify nominal", archive_limits=archive_limits,
                             system=system, measure=None)[0]

        def run(pts: list[dict[str, Any]], label: str) -> list[dict[str, Any]]:
            return run_points(pts, spec.base, spec.variant, None, out, cl, progress=progress, label=label,
                              archive_limits=archive_limits, system=system, measure=None)
        _evolve(spec, members, generations, run, rows, out, say)
    worst = min(rows, key=lambda r: (_robustness(spec, r), r["point"]))
    result = _result(spec, members, generations, rows, nominal, worst, out, archive_limits, system)
    meta.write_text(json.dumps(result, indent=1, default=str) + "\n")
    _table(spec, rows, out / "falsify.csv")
    _plot(spec, rows, result, out / "falsify.png")
    return result


def _evolve(spec: FalsifySpec, members: int, generations: int,
            run: Callable[[list[dict[str, Any]], str], list[dict[str, Any]]], rows: list[dict[str, Any]], out: Path,
            say: Callable[[str], None] | None) -> None:
    """scipy's differential evolution, each generation's population one batch of points (``run``); every
    point's row appended to ``rows`` with its generation."""
    from scipy.optimize import differential_evolution
    from scipy.stats import qmc

    axes = list(spec.space)
    bounds = [spec.space[k] for k in axes]
    lo, hi = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
    init = lo + qmc.LatinHypercube(d=len(axes), seed=spec.seed).random(members) * (hi - lo)

    def batch(_func: Any, xs: Any) -> list[float]:
        """One generation: its points run on the cluster at once (scipy's ``workers`` map)."""
        generation = len(rows) // members
        pts: list[dict[str, Any]] = [{"id": 1 + len(rows) + i, "params": _params(spec, np.asarray(x))}
                                     for i, x in enumerate(xs)]
        done = run(pts, f"falsify generation {generation}")
        for p, r in zip(pts, done):
            if {k: r.get(k) for k in p["params"]} != p["params"]:
                raise CosimError(f"{out}: point {p['id']} on disk has other parameters; use another --out")
            r["generation"] = generation
            rows.append(r)
        if say is not None:
            best = min(rows, key=lambda r: _robustness(spec, r))
            say(f"falsify: generation {generation} of {generations}, {len(rows)}/{members * (generations + 1)} runs: "
                f"lowest robustness {_robustness(spec, best):.6g} at "
                + ", ".join(f"{k} = {best[k.split('+')[0]]:.6g}" for k in axes))
        return [_robustness(spec, r) for r in done]

    differential_evolution(lambda x: 0.0, bounds, init=init, maxiter=generations, seed=spec.seed,
                           updating="deferred", workers=batch, polish=False, tol=0.0, atol=0.0)


def _result(spec: FalsifySpec, members: int, generations: int, rows: list[dict[str, Any]], nominal: dict[str, Any],
            worst: dict[str, Any], out: Path, archive_limits: LimitOverrides | None, system: System
            ) -> dict[str, Any]:
    """falsify.json: the spec, the optimiser, the nominal run, the worst case with the command that runs
    it, its re-run here (into ``out/worst``), the points that failed."""
    params = {k: worst[k] for k in spec.parameters}
    command = (f"wmr-cosim run {shlex.quote(spec.base)}"
               + (f" --variant {shlex.quote(spec.variant)}" if spec.variant else "")
               + "".join(f" --set {shlex.quote(f'{k}={v!r}')}" for k, v in params.items())
               + f" --out {shlex.quote(str(out / 'worst'))}")
    verdict = f"{spec.run}.{spec.requirement}.verdict"
    return {
        "spec": json.loads(json.dumps(asdict(spec))),
        "optimiser": {"name": "scipy.optimize.differential_evolution", "members": members, "generations": generations,
                      "runs": len(rows), "updating": "deferred", "init": "latin hypercube", "polish": False},
        "nominal": {"robustness": _robustness(spec, nominal), "verdict": nominal.get(verdict), "status": nominal["status"]},
        "worst": {"point": worst["point"], "generation": worst["generation"], "params": params,
                  "robustness": _robustness(spec, worst), "verdict": worst.get(verdict), "command": command},
        "rerun": _rerun(spec, worst, params, out / "worst", archive_limits, system),
        "failed": sum(1 for r in rows if _robustness(spec, r) == math.inf),
    }


def _rerun(spec: FalsifySpec, worst: dict[str, Any], params: dict[str, Any], folder: Path,
           archive_limits: LimitOverrides | None, system: System) -> dict[str, Any]:
    """The worst point (its ``params``) run again here, as its command runs it: its robustness and whether
    it is the same."""
    from ..cosim import run_protocol
    from .sweep_file import read_base

    results = run_protocol(read_base(spec.base, system.models, archive_limits), folder, variant=spec.variant,
                           overrides=params, progress=False, judge=system.judge)
    verdicts = {v["name"]: v for v in results[spec.run].requirements}
    v = verdicts.get(spec.requirement, {})
    rob = math.inf if v.get("robustness") is None else v["robustness"]
    return {"folder": str(folder), "robustness": rob, "verdict": v.get("verdict"),
            "same": rob == _robustness(spec, worst)}


def _table(spec: FalsifySpec, rows: list[dict[str, Any]], path: Path) -> None:
    import pandas as pd

    cols = ["point", "generation", *[k.split("+")[0] for k in spec.space], "robustness", "verdict", "status", "reason"]
    df = pd.DataFrame([{**r, "robustness": _robustness(spec, r),
                        "verdict": r.get(f"{spec.run}.{spec.requirement}.verdict")} for r in rows])
    df[[c for c in cols if c in df]].to_csv(path, index=False)


def _plot(spec: FalsifySpec, rows: list[dict[str, Any]], result: dict[str, Any], path: Path) -> None:
    from matplotlib.figure import Figure   # (no pyplot: the process's backend is left as it is)

    rob = np.array([_robustness(spec, r) for r in rows])
    shown = np.where(np.isfinite(rob), rob, np.nan)
    axes = [k.split("+")[0] for k in spec.space]
    fig = Figure(figsize=(10, 4))
    a, b = fig.subplots(1, 2)
    a.plot(np.arange(1, len(rob) + 1), shown, "o", ms=4, label="a point")
    a.plot(np.arange(1, len(rob) + 1), np.fmin.accumulate(shown), "-", color="C3", label="lowest so far")
    a.axhline(result["nominal"]["robustness"], color="k", ls="--", lw=0.8, label="nominal run")
    a.axhline(0.0, color="C2", lw=0.8)
    a.set_xlabel("co-simulation of the search")
    a.set_ylabel(f"robustness of {spec.requirement!r}")
    a.legend(fontsize=7)
    a.grid(True, alpha=0.3)
    x = [r[axes[0]] for r in rows]
    y = [r[axes[1]] for r in rows] if len(axes) > 1 else list(shown)
    sc = b.scatter(x, y, c=shown, cmap="viridis", s=25)
    w = result["worst"]["params"]
    b.plot([w[axes[0]]], [w[axes[1]] if len(axes) > 1 else result["worst"]["robustness"]], "x", color="C3", ms=12,
           label="worst case")
    b.set_xlabel(axes[0])
    b.set_ylabel(axes[1] if len(axes) > 1 else "robustness")
    fig.colorbar(sc, ax=b, label="robustness")
    b.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
