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

import copy
import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..messages.errors import CosimError, MissingVariableError, ScenarioError
from ..model.archive import LimitOverrides
from ..plan import resolution as system
from ..scenario import document as scenario
from ..scenario.document import Inheritance, RunSpec, Scenario
from . import execution

Resolver = Callable[[str], "Path | None"]
#: What a run's carry gives: (run's carry {parameter ref: "run.instance.variable"}, final values of the runs
#: so far {run: {column: value}}) -> {parameter ref: value}.
Carry = Callable[[dict[str, str], dict[str, dict[str, float]]], dict[str, Any]]


@dataclass(frozen=True)
class Protocol:
    """A scenario file read once: its merged document and the scenario it makes, with the resolver of
    its model names and the caller's archive limits; every run's scenario is made from the document."""

    file: str
    document: dict[str, Any]
    scenario: Scenario
    resolver: Resolver | None = None
    limits: LimitOverrides | None = None
    inherited: tuple[Inheritance, ...] = ()   # what each file of its base chain takes from its base

    @property
    def runs(self) -> list[RunSpec]:
        """The runs (one default run named "run" if the file declares none)."""
        return self.scenario.runs or [RunSpec("run")]

    def variant_parameters(self, variant: str | None) -> dict[str, Any]:
        """The parameters a variant sets ({} for None); ScenarioError for a variant the file does not declare."""
        if variant is None:
            return {}
        if variant not in self.scenario.variants:
            known = ", ".join(self.scenario.variants) or "none"
            raise ScenarioError(self.file, f"--variant {variant}", f"not declared by this file (declared: {known})")
        return self.scenario.variants[variant]

    @classmethod
    def from_document(cls, file: str, document: dict[str, Any], resolver: Resolver | None = None,
                      limits: LimitOverrides | None = None,
                      inherited: tuple[Inheritance, ...] = ()) -> "Protocol":
        """The protocol of a document already read (:func:`~.scenario.read_document`: its bases merged,
        its paths absolute), parsed for the file ``file`` names in messages; ``limits``: the caller's
        archive limits; ``inherited``: what read_document reported of its base chain.  The document is not
        changed."""
        return cls(file, document, scenario.parse(copy.deepcopy(document), file, resolver, limits), resolver, limits,
                   tuple(inherited))

    def with_parameters(self, overrides: dict[str, Any] | None) -> Scenario:
        """The scenario with ``overrides`` ({'inst.param': value}) applied to a copy of the document."""
        if not overrides:
            return self.scenario
        doc = scenario.apply_overrides(copy.deepcopy(self.document), overrides, self.file)
        return scenario.parse(doc, self.file, self.resolver, self.limits)


def read_protocol(path: str | os.PathLike, resolver: Resolver | None = None, limits: LimitOverrides | None = None,
                  shipped: Path | None = None) -> Protocol:
    """Read and parse a scenario file once (:class:`Protocol`); ``limits``: the caller's archive limits;
    ``shipped``: the caller's folder of scenario files a ``base`` may name
    (:func:`~.scenario.read_document`)."""
    inherited: list[Inheritance] = []
    document = scenario.read_document(Path(path), shipped=shipped, inherited=inherited)
    return Protocol.from_document(str(Path(path)), document, resolver, limits, tuple(inherited))


def _protocol(source: str | os.PathLike | Protocol, resolver: Resolver | None,
              limits: LimitOverrides | None) -> Protocol:
    return source if isinstance(source, Protocol) else read_protocol(source, resolver, limits)


def plan_runs(path: str | os.PathLike | Protocol, resolver: Resolver | None = None, variant: str | None = None,
              limits: LimitOverrides | None = None
              ) -> tuple[Scenario, list[RunSpec], dict[str, Any]]:
    """The scenario, its runs (one default run if it declares none) and the variant's parameters."""
    proto = _protocol(path, resolver, limits)
    return proto.scenario, proto.runs, proto.variant_parameters(variant)


#: A value of each kind, standing for a carried value that is not known before its source run ends.
_STAND_IN: dict[str, Any] = {"Real": 0.0, "Integer": 0, "Enumeration": 0, "Boolean": False, "String": ""}


def _run_scenario(proto: Protocol, run: str, params: dict[str, Any]) -> Scenario:
    """The scenario of one run: the document with ``params`` set, and the requirements of this run."""
    sc = proto.with_parameters(params)
    if any(r.runs is not None for r in sc.requirements):   # the requirements of this run (a copy: not shared)
        sc = dataclasses.replace(sc, requirements=[r for r in sc.requirements if r.runs is None or run in r.runs])
    return sc


def _resolve_run(proto: Protocol, run: str, params: dict[str, Any], force: bool, isolate: bool) -> system.Plan:
    """The checked plan of one run; a failure names the run."""
    sc = _run_scenario(proto, run, params)
    try:
        return system.resolve(sc, force, isolate_all=isolate)
    except MissingVariableError as exc:
        raise MissingVariableError(exc.file, f"runs.{run}: {exc.field}" if exc.field else f"runs.{run}",
                                   exc.reason, exc.ref) from None
    except ScenarioError as exc:
        where = f"runs.{run}: {exc.field}" if exc.field else f"runs.{run}"
        raise ScenarioError(exc.file, where, exc.reason) from None


def _every_missing(proto: Protocol, runs: list[RunSpec], params: dict[str, dict[str, Any]],
                   first: MissingVariableError) -> MissingVariableError:
    """The one error that lists every variable the runs name and their FMUs lack, run by run
    (:func:`~..plan.resolution.every_missing`): what a run sets in its parameters, what it carries (target and
    source), what its requirements, record, connections and events name; ``params``: each run's parameters."""
    found: dict[str, system.Missing] = {}
    for run in runs:
        sc = _run_scenario(proto, run.name, params[run.name])
        carries = {f"runs.{run.name}.carry.{ref}": ref for ref in run.carry}
        carries.update({f"runs.{run.name}.carry.{ref} (its source)": src.split(".", 1)[1]
                        for ref, src in run.carry.items() if src.count(".") >= 2})
        for ref, m in system.missing_variables(sc, carries).items():
            fields = [f"runs.{run.name}.parameters" if f.startswith("instances.") and ".parameters." in f
                      and ref in run.parameters else f for f in m.fields]
            known = found.setdefault(ref, system.Missing([], m.hint))
            known.fields += [f for f in fields if f not in known.fields]
            known.runs.append(run.name)
    return system.every_missing(proto.file, first, found, [r.name for r in runs])


def _carried(file: str, run: RunSpec, finals: dict[str, dict[str, Any]], carry: Carry | None
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


def check_protocol(path: str | os.PathLike | Protocol, resolver: Resolver | None = None, variant: str | None = None,
                   overrides: dict[str, Any] | None = None, only: list[str] | None = None, force: bool = False,
                   carry: Carry | None = None, limits: LimitOverrides | None = None, isolate: bool = False
                   ) -> dict[str, system.Plan]:
    """Resolve every run of the file (the ones in ``only``) before any of them starts: each run's parameters
    against its FMUs, each carry against what its source run records and what its target takes (type and
    shape; the range once the value is known).  Returns {run name: plan}; raises ScenarioError naming the
    run and the field.  ``path`` may be a file already read (:func:`read_protocol`: then ``resolver`` and
    ``limits`` are its own)."""
    proto = _protocol(path, resolver, limits)
    vparams = proto.variant_parameters(variant)
    overrides = overrides or {}
    plans: dict[str, system.Plan] = {}
    finals: dict[str, dict[str, Any]] = {}
    for run in proto.runs:
        if only is not None and run.name not in only:
            continue
        carried = {ref: v for ref, v in _carried(proto.file, run, finals, carry).items() if ref not in overrides}
        try:
            plan = _resolve_run(proto, run.name, {**vparams, **run.parameters, **overrides}, force, isolate)
            for ref, value in carried.items():
                system.check_carried(proto.file, f"runs.{run.name}.carry.{ref}", plan, ref, value)
        except MissingVariableError as exc:
            runs = [r for r in proto.runs if only is None or r.name in only]
            raise _every_missing(proto, runs, {r.name: {**vparams, **r.parameters, **overrides} for r in runs},
                                 exc) from None
        plans[run.name] = plan
        finals[run.name] = {rp.column: _STAND_IN.get(rp.var.type, 0.0) for rp in plan.record}
    return plans


def run_protocol(path: str | os.PathLike | Protocol, out_dir: str | os.PathLike, resolver: Resolver | None = None,
                 variant: str | None = None, overrides: dict[str, Any] | None = None,
                 progress: bool | None = None, only: list[str] | None = None,
                 on_run: Callable[[str, execution.RunResult], None] | None = None,
                 judge: Callable[[execution.RunResult], Any] | None = None,
                 force: bool = False, isolate: bool = False, carry: Carry | None = None,
                 limits: LimitOverrides | None = None,
                 on_check: Callable[[dict[str, system.Plan]], None] | None = None) -> dict[str, execution.RunResult]:
    """Run every run of the file in order into ``out_dir/<run>``; returns {run name: result}.

    Every run is checked first (:func:`check_protocol`), so a run that cannot work stops the protocol
    before its first run starts.  A run whose carried source run failed is still run if the source
    recorded the value.  ``overrides`` ("inst.param" -> value) apply to every run, after the variant and
    the run's own parameters and carried values.  ``carry`` replaces the plain lookup of carried values
    (a resolver to other FMUs may need the names translated).  ``isolate`` hosts every instance of every
    run in a child process of its own; ``limits``: the caller's archive limits.  ``path`` may be a file
    already read (:func:`read_protocol`).  ``on_check``: called with every run's checked plan before the
    first run starts (the command line prints their notes).  ``judge``: the application's check of each run
    as it finishes (it may set the result's status, e.g. to ``diverged``), before ``on_run``.
    """
    proto = _protocol(path, resolver, limits)
    plans = check_protocol(proto, variant=variant, overrides=overrides, only=only, force=force, carry=carry)
    if on_check is not None:
        on_check(plans)
    vparams = proto.variant_parameters(variant)
    out = Path(out_dir)
    results: dict[str, execution.RunResult] = {}
    for run in proto.runs:
        if only is not None and run.name not in only:
            continue
        params = {**vparams, **run.parameters}
        params.update(_carried(proto.file, run, {n: r.final for n, r in results.items()}, carry))
        params.update(overrides or {})
        plan = _resolve_run(proto, run.name, params, force, isolate)
        res = execution.run(plan, out / run.name, progress=progress)
        results[run.name] = res
        if judge is not None:
            judge(res)
        if on_run is not None:
            on_run(run.name, res)
    return results
