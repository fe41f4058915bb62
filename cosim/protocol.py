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
from .errors import ScenarioError

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


def run_protocol(path: str | os.PathLike, out_dir: str | os.PathLike, resolver: Resolver | None = None,
                 variant: str | None = None, overrides: dict[str, Any] | None = None,
                 progress: bool | None = None, only: list[str] | None = None,
                 on_run: Callable[[str, execution.RunResult], None] | None = None,
                 force: bool = False, isolate: bool = False, carry: Carry | None = None
                 ) -> dict[str, execution.RunResult]:
    """Run every run of the file in order into ``out_dir/<run>``; returns {run name: result}.

    A run whose carried source run failed is still run if the source recorded the value; a carried value
    that was not recorded is a ScenarioError before that run starts.  ``overrides`` ("inst.param" ->
    value) apply to every run, after the variant and the run's own parameters.  ``carry`` replaces the
    plain lookup of carried values (a resolver to other FMUs may need the names translated).
    """
    sc, runs, vparams = plan_runs(path, resolver, variant)
    out = Path(out_dir)
    results: dict[str, execution.RunResult] = {}
    for run in runs:
        if only is not None and run.name not in only:
            continue
        params = {**vparams, **run.parameters}
        carried: dict[str, Any] = {}
        for ref, src in run.carry.items():
            src_run, col = src.split(".", 1)
            if src_run not in results:
                raise ScenarioError(sc.file, f"runs.{run.name}.carry.{ref}", f"run {src_run!r} has not been run")
            if carry is None:
                if col not in results[src_run].final:
                    raise ScenarioError(sc.file, f"runs.{run.name}.carry.{ref}",
                                        f"{src!r} was not recorded by run {src_run!r}")
                carried[ref] = results[src_run].final[col]
        if carry is not None:
            carried = carry(run.carry, {n: r.final for n, r in results.items()})
        params.update(carried)
        params.update(overrides or {})
        plan = system.resolve(scenario.load(path, resolver, params), force)
        for ip in plan.instances.values():
            ip.spec.isolate = ip.spec.isolate or isolate
        res = execution.run(plan, out / run.name, progress=progress)
        results[run.name] = res
        if on_run is not None:
            on_run(run.name, res)
    return results
