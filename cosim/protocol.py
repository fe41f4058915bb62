"""Protocols: several runs declared in one scenario file (``[[runs]]``), each with its own parameter
values, and values carried from an earlier run's final outputs into a later run's parameters (a learned
weight, say); and named variants (``[variants.NAME]``) that set parameters of every run.

    [[runs]]
    name = "learn"
    [[runs]]
    name = "frozen"
    parameters = { "controller.adapt" = false }
    carry = { "controller.W1_init" = "learn.controller.W1" }

Each run writes its own results folder ``OUT/<run name>/``.  A file without ``[[runs]]`` is one run
named "run".
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

from . import execution, scenario, system
from .errors import CosimError, ScenarioError

Resolver = Callable[[str], "Path | None"]
#: What a run's carry gives: (run's carry {parameter ref: "run.instance.variable"}, final values of the runs
#: so far {run: {column: value}}) -> {parameter ref: value}.
Carry = Callable[[dict[str, str], dict[str, dict[str, float]]], dict[str, Any]]


def plan_runs(path: str | os.PathLike, resolver: Resolver | None = None, variant: str | None = None
              ) -> tuple[scenario.Scenario, list[scenario.RunSpec], dict[str, Any]]:
    """The scenario, its runs (one default run if it declares none) and the variant's parameters."""
    sc = scenario.load(path, resolver)
    runs = sc.runs or [scenario.RunSpec("run")]
    vparams: dict[str, Any] = {}
    if variant is not None:
        if variant not in sc.variants:
            known = ", ".join(sc.variants) or "none"
            raise ScenarioError(str(path), f"--variant {variant}", f"not declared by this file (declared: {known})")
        vparams = sc.variants[variant]
    return sc, runs, vparams


#: A value of each kind, standing for a carried value that is not known before its source run ends.
_STAND_IN: dict[str, Any] = {"Real": 0.0, "Integer": 0, "Enumeration": 0, "Boolean": False, "String": ""}


def _resolve_run(path: str | os.PathLike, resolver: Resolver | None, run: str, params: dict[str, Any],
                 force: bool) -> system.Plan:
    """The checked plan of one run; a failure names the run."""
    try:
        return system.resolve(scenario.load(path, resolver, params), force)
    except ScenarioError as exc:
        where = f"runs.{run}: {exc.field}" if exc.field else f"runs.{run}"
        raise ScenarioError(exc.file, where, exc.reason) from None


def _carried(file: str, run: scenario.RunSpec, finals: dict[str, dict[str, Any]], carry: Carry | None
             ) -> dict[str, Any]:
    """The values a run carries from the final values of the runs before it ({run: {column: value}})."""
    for ref, src in run.carry.items():
        src_run = src.split(".", 1)[0]
        if src_run not in finals:
            raise ScenarioError(file, f"runs.{run.name}.carry.{ref}", f"run {src_run!r} has not been run")
    if carry is not None:
        try:
            return carry(run.carry, finals)
        except ScenarioError:
            raise
        except CosimError as exc:
            raise ScenarioError(file, f"runs.{run.name}.carry", str(exc)) from None
    carried: dict[str, Any] = {}
    for ref, src in run.carry.items():
        src_run, col = src.split(".", 1)
        if col not in finals[src_run]:
            raise ScenarioError(file, f"runs.{run.name}.carry.{ref}", f"{src!r} was not recorded by run {src_run!r}")
        carried[ref] = finals[src_run][col]
    return carried


def check_protocol(path: str | os.PathLike, resolver: Resolver | None = None, variant: str | None = None,
                   overrides: dict[str, Any] | None = None, only: list[str] | None = None, force: bool = False,
                   carry: Carry | None = None) -> dict[str, system.Plan]:
    """Resolve every run of the file (the ones in ``only``) before any of them starts: each run's parameters
    against its FMUs, each carry against what its source run records and what its target takes (type and
    shape; the range once the value is known).  Returns {run name: plan}; raises ScenarioError naming the
    run and the field."""
    return _check_runs(path, plan_runs(path, resolver, variant), resolver, overrides, only, force, carry)


def _check_runs(path: str | os.PathLike, parsed: tuple[scenario.Scenario, list[scenario.RunSpec], dict[str, Any]],
                resolver: Resolver | None, overrides: dict[str, Any] | None, only: list[str] | None, force: bool,
                carry: Carry | None) -> dict[str, system.Plan]:
    """:func:`check_protocol` of a file already parsed by :func:`plan_runs`."""
    sc, runs, vparams = parsed
    overrides = overrides or {}
    plans: dict[str, system.Plan] = {}
    finals: dict[str, dict[str, Any]] = {}
    for run in runs:
        if only is not None and run.name not in only:
            continue
        carried = {ref: v for ref, v in _carried(sc.file, run, finals, carry).items() if ref not in overrides}
        plan = _resolve_run(path, resolver, run.name, {**vparams, **run.parameters, **overrides}, force)
        for ref, value in carried.items():
            system.check_carried(sc.file, f"runs.{run.name}.carry.{ref}", plan, ref, value)
        plans[run.name] = plan
        finals[run.name] = {rp.column: _STAND_IN.get(rp.var.type, 0.0) for rp in plan.record}
    return plans


def run_protocol(path: str | os.PathLike, out_dir: str | os.PathLike, resolver: Resolver | None = None,
                 variant: str | None = None, overrides: dict[str, Any] | None = None,
                 progress: bool | None = None, only: list[str] | None = None,
                 on_run: Callable[[str, execution.RunResult], None] | None = None,
                 force: bool = False, isolate: bool = False, carry: Carry | None = None
                 ) -> dict[str, execution.RunResult]:
    """Run every run of the file in order into ``out_dir/<run>``; returns {run name: result}.

    Every run is checked first (:func:`check_protocol`), so a run that cannot work stops the protocol
    before its first run starts.  A run whose carried source run failed is still run if the source
    recorded the value.  ``overrides`` ("inst.param" -> value) apply to every run, after the variant and
    the run's own parameters and carried values.  ``carry`` replaces the plain lookup of carried values
    (a resolver to other FMUs may need the names translated).
    """
    parsed = plan_runs(path, resolver, variant)
    _check_runs(path, parsed, resolver, overrides, only, force, carry)
    sc, runs, vparams = parsed
    out = Path(out_dir)
    results: dict[str, execution.RunResult] = {}
    for run in runs:
        if only is not None and run.name not in only:
            continue
        params = {**vparams, **run.parameters}
        params.update(_carried(sc.file, run, {n: r.final for n, r in results.items()}, carry))
        params.update(overrides or {})
        plan = _resolve_run(path, resolver, run.name, params, force)
        for ip in plan.instances.values():
            ip.spec.isolate = ip.spec.isolate or isolate
        res = execution.run(plan, out / run.name, progress=progress)
        results[run.name] = res
        if on_run is not None:
            on_run(run.name, res)
    return results
