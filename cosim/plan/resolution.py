"""Resolve a scenario against its FMUs: every check that can be made before the first step.

Checks (each a ScenarioError naming the file, the field and the reason): a missing or unsafe FMU file,
an FMU that is not FMI 2.0 or 3.0 co-simulation or model exchange, or lacks the interface an instance uses
(or its binary), a variable that does not exist, wrong causality (an input driven twice, an output or
parameter used as a connection target, a connection from a non-output), a type mismatch, a unit mismatch
(convertible units are converted), a step the FMU cannot take, a parameter or start value of the wrong
type or outside the min/max the model description declares.

The interface an instance uses: its ``interface``; else model exchange where it gives an integrator
setting (``solver``, ``max_step``, ``event_tolerance``) or the FMU has no co-simulation interface; else
co-simulation.  A model exchange instance's plan carries its integrator (:class:`.integrators.SolverSpec`,
with the tolerance the instance resolves to).
"""
from __future__ import annotations

import copy
import dataclasses
import math
import re
import zipfile
from typing import Any, Callable, cast

import numpy as np

from ..instances.integrators import DEFAULT_EVENT_TOLERANCE, DEFAULT_RTOL, ME_ALONE, SolverSpec
from ..messages.errors import CosimError, FmuLoadError, MissingVariableError, ScenarioError
from ..messages.suggest import did_you_mean
from ..messages.words import count, plural
from ..model.binary import PYTHON_FMU, runs_python
from ..model.description import (CO_SIMULATION, INTERFACE_NAMES, MODEL_EXCHANGE, SCHEDULED_EXECUTION, FmuModel,
                                 Variable, load_model)
from ..model.kinds import FileKind, file_kind
from ..model.types import PY_TYPES
from ..model.units import conversion, lookup, same_unit, units_of
from ..scenario.document import (SOLVER_KEYS, ConnectionSpec, EventSpec as _EventSpec, InstanceSpec, Scenario,
                                check_experiment, split_ref, steps_of)
from ..scenario.inputs import InputPlan, read_inputs
from ..stepping import table as algorithms
from ..stepping.graph import FeedGraph
from ..stepping.settings import SpecError, check_adaptive
from .clocked import (check_clocked, check_clocked_reads, clock_links, periodic_on_grid, ticks_named,
                      triggered_on_grid)
from .feeds import feed_graph
from .loops import check_iteration, coupling
from .records import ConnectionPlan, EventPlan, InstancePlan, Plan, RecordPlan, RequirementPlan, unit_of


def checked_value(file: str, fld: str, var: Variable, value: Any, check_range: bool = True) -> Any:
    """``value`` as ``var`` takes it (a Real as a float; an array as a list of its elements), or
    ScenarioError naming ``file`` and ``fld``: a wrong type or shape, a non-finite Real, a value outside the
    declared range (unless not ``check_range``)."""
    if var.shape:   # an FMI 3.0 array: every element, row-major
        if not isinstance(value, list) or len(value) != var.size:
            raise ScenarioError(file, fld, f"{var.name} is an array of {var.size} values {var.shape}: give a "
                                           f"list of {var.size}")
        return [_scalar_value(file, fld, var, v, check_range) for v in value]
    return _scalar_value(file, fld, var, value, check_range)


def _scalar_value(file: str, fld: str, var: Variable, value: Any, check_range: bool = True) -> Any:
    types = PY_TYPES.get(var.type)
    if types is None:
        raise ScenarioError(file, fld, f"variables of type {var.type} cannot be set")
    if isinstance(value, bool) and var.type != "Boolean":
        raise ScenarioError(file, fld, f"type mismatch: {var.name} is {var.type}, got a boolean {value!r}")
    if not isinstance(value, types):
        raise ScenarioError(file, fld, f"type mismatch: {var.name} is {var.type}, got {type(value).__name__} {value!r}")
    if var.type == "Real":
        value = float(cast(float, value))
        if not math.isfinite(value):
            raise ScenarioError(file, fld, f"{value!r} is not finite")
    reason = var.check_range(value) if check_range else None
    if reason:
        raise ScenarioError(file, fld, reason)
    return value


def check_carried(file: str, fld: str, plan: Plan, ref: str, value: Any) -> None:
    """Check, before any run starts, that a value carried into ``ref`` ("instance.parameter") can be set:
    the variable exists, is settable before initialisation and takes a value of ``value``'s type and shape
    (its range is checked when the carried value is known)."""
    inst, name = split_ref(file, fld, ref)
    if inst not in plan.instances:
        raise ScenarioError(file, fld, f"unknown instance {inst!r}")
    var = variable(file, fld, plan.instances[inst], name)
    reason = var.settable()
    if reason:
        raise ScenarioError(file, fld, reason)
    checked_value(file, fld, var, value, check_range=False)


#: What fits the place a variable is named in, for the suggestion of a misspelt name: what a connection
#: reads, what it drives, what an instance's ``parameters`` (and ``--set``) set.
OUTPUTS: Callable[[Variable], bool] = lambda v: v.causality == "output"
INPUTS: Callable[[Variable], bool] = lambda v: v.causality == "input"
PARAMETERS: Callable[[Variable], bool] = lambda v: v.causality == "parameter"


def variable(file: str, fld: str, inst: InstancePlan, name: str,
             fits: Callable[[Variable], bool] | None = None) -> Variable:
    """The variable the scenario calls ``name`` in instance ``inst`` (through its name map), or
    ScenarioError naming ``file`` and ``fld`` with the nearest name among the variables that ``fits`` the
    place (:data:`INPUTS`, :data:`OUTPUTS`, :data:`PARAMETERS`; None: any)."""
    theirs = inst.ours_to_theirs.get(name, name)
    var = inst.model.variables.get(theirs)
    if var is None:
        mapped = f" (mapped to {theirs!r})" if theirs != name else ""
        known = (inst.our_name(v) for v in inst.model.variables.values() if fits is None or fits(v))
        raise MissingVariableError(file, fld, f"{inst.name} ({inst.model.path.name}) has no variable {name!r}{mapped}"
                                              f"{did_you_mean(name, known)}", f"{inst.name}.{name}")
    return var


_ELEMENT = re.compile(r"^(.*)\[(\d+(?:,\d+)*)\]$")


def _element(file: str, fld: str, inst: InstancePlan, name: str,
             fits: Callable[[Variable], bool] | None = None) -> tuple[Variable, int | None]:
    """A variable, or one element of an FMI 3.0 array (``y[2]``, ``A[1,2]``: 1-based, row-major) with its
    flat index; an FMI name that is itself spelled with brackets (FMI 2.0's ``x[1]``) is a variable
    (``fits``: see :func:`variable`)."""
    theirs = inst.ours_to_theirs.get(name, name)
    if theirs in inst.model.variables:
        return inst.model.variables[theirs], None
    m = _ELEMENT.match(name)
    if m:
        base = inst.model.variables.get(inst.ours_to_theirs.get(m.group(1), m.group(1)))
        if base is not None and base.shape:
            idx = [int(i) for i in m.group(2).split(",")]
            if len(idx) != len(base.shape) or not all(1 <= i <= d for i, d in zip(idx, base.shape)):
                raise ScenarioError(file, fld, f"{name}: {base.name} has the shape {base.shape} (indices start at 1)")
            flat = 0
            for i, d in zip(idx, base.shape):
                flat = flat * d + (i - 1)
            return base, flat
    return variable(file, fld, inst, name, fits), None


def _declared_unit(file: str, fld: str, inst: InstancePlan, name: str, unit_name: str) -> str | None:
    """Check a ``units`` entry against the model description.  A unit for a variable that declares none, or
    the one it declares (under any name of the same unit), is accepted silently; one that contradicts the
    declared unit is refused, unless the instance sets ``override_declared_units`` (then the note that
    ``check`` prints is returned)."""
    var = variable(file, fld, inst, name)
    if var.type != "Real":
        raise ScenarioError(file, fld, f"{var.name} is {var.type}: units apply to Real variables")
    given = lookup(unit_name, units_of(inst.model.md))
    declared = var.unit
    if declared is None or same_unit(declared, given):
        return None
    if not inst.spec.override_declared_units:
        raise ScenarioError(file, fld, f"{unit_name!r} contradicts the unit {declared.name!r} that "
                                       f"{inst.model.path.name} declares for {var.name} (units are for variables "
                                       f"that declare none; to override it, set instances.{inst.name}."
                                       "override_declared_units = true)")
    return (f"{fld}: {unit_name!r} overrides the unit {declared.name!r} that {inst.model.path.name} declares "
            f"for {var.name}")


def _connection_types(file: str, fld: str, c: ConnectionSpec, svar: Variable, dvar: Variable,
                      si: InstancePlan, di: InstancePlan) -> tuple[float, float]:
    """The unit conversion (factor, offset) of a connection whose types agree (or that converts
    Boolean <-> Real where the scenario asks for it)."""
    pair = (svar.type, dvar.type)
    if c.convert:
        if pair not in (("Boolean", "Real"), ("Real", "Boolean")):
            raise ScenarioError(file, f"{fld}.convert", f"converts Boolean <-> Real only, not {pair[0]} -> {pair[1]}")
        if pair == ("Real", "Boolean") and (c.factor != 1.0 or c.offset != 0.0):
            raise ScenarioError(file, fld, "a Real -> Boolean conversion takes a threshold, not a factor or offset")
        return 1.0, 0.0
    if svar.type != dvar.type:
        hint = " (convert = true converts Boolean <-> Real)" if set(pair) == {"Boolean", "Real"} else ""
        raise ScenarioError(file, fld, f"type mismatch: {c.src} is {svar.type}, {c.dst} is {dvar.type}{hint}")
    if svar.type == "Real":
        try:
            return conversion(unit_of(si, svar), unit_of(di, dvar))
        except CosimError as exc:
            raise ScenarioError(file, fld, f"unit mismatch: {c.src} -> {c.dst}: {exc}") from None
    if c.factor != 1.0 or c.offset != 0.0:
        raise ScenarioError(file, fld, "a linear transform needs Real variables")
    return 1.0, 0.0


def _experiment(sc: Scenario, models: dict[str, FmuModel], notes: list[str]) -> None:
    """Fill start, stop and step the scenario leaves open from the FMUs' default experiments (refused
    where they disagree; a step given as 0 with none there is (stop - start) / 500, and ``notes`` says
    which value 0 took), then check the run's times.  (A tolerance is each FMU's own: see
    :func:`_tolerances`.)"""
    attrs = {"start": "startTime", "stop": "stopTime", "step": "stepSize"}
    for key, attr in attrs.items():
        if getattr(sc, key) is not None:
            continue
        found = {}
        for name, m in models.items():
            de = m.md.defaultExperiment
            v = getattr(de, attr, None) if de is not None else None
            if v is not None:
                found[name] = float(v)
        if len(set(found.values())) > 1:
            listed = ", ".join(f"{n} {v!r}" for n, v in found.items())
            raise ScenarioError(sc.file, f"experiment.{key}", f"not given, and the FMUs' default experiments "
                                                              f"disagree ({listed}): give one")
        if found:
            setattr(sc, key, next(iter(found.values())))
        elif key == "start":
            sc.start = 0.0
        elif key == "step" and key in sc.tools_choice and sc.stop is not None and sc.start is not None:
            sc.step = (sc.stop - sc.start) / 500   # FMPy's choice (start and stop are filled in by now)
        elif key in ("stop", "step"):
            raise ScenarioError(sc.file, f"experiment.{key}", "not given, and no FMU's default experiment gives one")
        if key in sc.tools_choice:
            how = "the FMUs' default experiment" if found else "(stop - start) / 500, as FMPy chooses"
            notes.append(f"experiment.{key} = 0 (the tool's choice): {getattr(sc, key)!r} s, {how}")
    check_experiment(sc)
    start, stop, step = sc.times()
    n = (stop - start) / step
    if n > sc.max_steps and not sc.force:
        raise ScenarioError(sc.file, "experiment.step", f"{n:.4g} steps of {step!r} s from {start!r} to "
                                                        f"{stop!r} s: more than max_steps = {sc.max_steps} "
                                                        "(raise experiment.max_steps, or --force)")


def _internal_steps(sc: Scenario, insts: dict[str, InstancePlan]) -> dict[str, int]:
    """The fixed internal steps each FMU that declares one (FMI 3.0 fixedInternalStepSize) takes over the
    run; a run in which one takes more than ``max_internal_steps`` is refused (unless forced): it would not
    finish (the Reference FMU Roberts over its default 1e8 s takes 1e11 steps of 1 ms)."""
    out: dict[str, int] = {}
    for name, ip in insts.items():
        h = ip.model.internal_step if ip.interface == CO_SIMULATION else None   # (model exchange: the master's steps)
        if h is None:
            continue
        start, stop, _ = sc.times()
        n = (stop - start) / h
        if n > sc.max_internal_steps and not sc.force:
            raise ScenarioError(sc.file, "experiment.stop", f"{name} ({ip.model.path.name}) takes fixed internal steps "
                                                            f"of {h:g} s: {n:.3g} from {start!r} to {stop!r} s, "
                                                            f"more than max_internal_steps = {sc.max_internal_steps} "
                                                            f"({_variable_step_hint(sc, ip)}a shorter run: "
                                                            "experiment.stop or --stop; or raise "
                                                            "experiment.max_internal_steps, or --force)")
        out[name] = int(math.ceil(n - 1e-9))
    return out


def _variable_step_hint(sc: Scenario, ip: InstancePlan) -> str:
    """For an FMU refused for its fixed internal steps that has a Model Exchange interface too: how to run
    that one instead, which the master integrates with steps of its own ("--solver cvode" for one FMU run
    alone, the instance's ``solver`` in a scenario); "" for one without."""
    if not ip.model.has_me:
        return ""
    if file_kind(sc.file) is FileKind.FMU:
        how = "--solver cvode"
    elif ip.spec.interface == CO_SIMULATION:
        how = f'instances.{ip.name}.interface = "model-exchange" and solver = "cvode"'
    else:
        how = f'instances.{ip.name}.solver = "cvode"'
    return f"it also has a Model Exchange interface, which the master integrates with steps of its own: {how}; or "


def _tolerances(sc: Scenario, insts: dict[str, InstancePlan], notes: list[str]) -> None:
    """Each FMU's solver tolerance: its instance's ``tolerance``, else the experiment's, else the one of
    its own default experiment, else none (toleranceDefined false); a note of the values the experiment's
    tolerance given as 0 left."""
    for ip in insts.values():
        de = ip.model.md.defaultExperiment
        own = getattr(de, "tolerance", None) if de is not None else None
        ip.tolerance = next((float(t) for t in (ip.spec.tolerance, sc.tolerance, own) if t is not None), None)
    if "tolerance" in sc.tools_choice:
        each = ", ".join(f"{n} {'none' if ip.tolerance is None else repr(ip.tolerance)}" for n, ip in insts.items())
        notes.append(f"experiment.tolerance = 0 (the tool's choice): each FMU's own ({each}; a model exchange "
                     f"integrator without one takes rtol {DEFAULT_RTOL!r})")


def _record(sc: Scenario, insts: dict[str, InstancePlan]) -> tuple[list[RecordPlan], list[str]]:
    """What to record (all outputs by default): exact names always; ``*`` and ``?`` as wildcards only
    where a name does not match exactly (FMI names such as ``x[1]`` or ``der(x)`` are plain names)."""
    file = sc.file
    candidates = [(n, v) for n in sc.order for v in insts[n].model.outputs()]
    record: list[RecordPlan] = []
    skipped: list[str] = []
    seen: set[tuple[Any, ...]] = set()
    for i, pat in enumerate(sc.record or ["*.*"]):
        fld = f"record.variables[{i}]"
        hits = [(n, v) for n, v in candidates if f"{n}.{insts[n].our_name(v)}" == pat]
        if not hits and ("*" in pat or "?" in pat):
            rx = re.compile("".join(".*" if ch == "*" else "." if ch == "?" else re.escape(ch) for ch in pat),
                            re.DOTALL)
            hits = [(n, v) for n, v in candidates if rx.fullmatch(f"{n}.{insts[n].our_name(v)}")]
            skipped += [f"{n}.{insts[n].our_name(v)}" for n, v in hits if v.is_text]
            hits = [(n, v) for n, v in hits if not v.is_text]  # reported, not recorded
            if not hits:
                raise ScenarioError(file, fld, f"{pat!r} matches no output")
        elif not hits:  # an explicit name may also be a non-output (a parameter, an input) or an element
            inst, var = split_ref(file, fld, pat)
            if inst not in insts:
                raise ScenarioError(file, fld, f"unknown instance {inst!r}")
            v, elem = _element(file, fld, insts[inst], var)
            if elem is not None:
                if (inst, v.name, elem) not in seen:
                    seen.add((inst, v.name, elem))
                    record.append(RecordPlan(inst, v, f"{inst}.{var}", elem))
                continue
            hits = [(inst, v)]
        for n, v in hits:
            if v.type == "String":
                raise ScenarioError(file, fld, f"{n}.{insts[n].our_name(v)} is a String: String variables "
                                               "cannot be recorded")
            if v.type == "Binary":
                raise ScenarioError(file, fld, f"{n}.{insts[n].our_name(v)} is Binary: Binary variables "
                                               "cannot be recorded")
            if (n, v.name) not in seen:
                seen.add((n, v.name))
                ours = insts[n].our_name(v)
                names = [ours] if not v.shape else [ours + e[len(v.name):] for e in v.element_names()]
                record += [RecordPlan(n, v, f"{n}.{name}", j) for j, name in enumerate(names)]
    return record, sorted(set(skipped))


def _inputs(sc: Scenario, insts: dict[str, InstancePlan], driven: dict[tuple[str, str], int]) -> list[InputPlan]:
    """The tabulated inputs, sampled at the communication points (each column an input no connection drives)."""
    if sc.inputs_file is None:
        return []
    file = sc.file

    def resolve_var(col: str) -> tuple[str, Variable]:
        inst, dot, name = col.partition(".")
        if not (dot and inst in insts):
            if len(insts) != 1:
                raise ScenarioError(file, f"inputs.{col}", "a column must be named \"instance.variable\"")
            inst, name = next(iter(insts)), col
        var = variable(file, f"inputs.{col}", insts[inst], name, INPUTS)
        if var.causality != "input":
            raise ScenarioError(file, f"inputs.{col}", f"{var.name} is {var.causality}, not an input")
        if (inst, var.name) in driven:
            raise ScenarioError(file, f"inputs.{col}", f"{col} is already driven by "
                                                       f"connections[{driven[(inst, var.name)]}]")
        return inst, var

    def column(col: str) -> tuple[str, Variable]:
        try:
            return resolve_var(col)
        except ScenarioError as exc:
            raise ScenarioError(file, exc.field, f"{exc.reason} (a column of {sc.inputs_file})") from None

    start, stop, step = sc.times()
    grid = start + np.arange(steps_of(start, stop, step)[0]) * step
    return read_inputs(sc.inputs_file, file, sc.interpolation, column, grid)


def _events(sc: Scenario, insts: dict[str, InstancePlan], driven: dict[tuple[str, str], int],
            inputs: list[InputPlan]) -> list[EventPlan]:
    """The events: override, bias or reset a Real input or output (see the wiring), or an Integer,
    Enumeration, Boolean or String input that no connection or table drives (set at the event's step; bias
    only on Integer); set a tunable parameter; stop the run.  At a time, or on a condition (its variables
    and types checked here)."""
    file = sc.file
    start, stop, step = sc.times()
    n_steps = steps_of(start, stop, step)[0]
    tabled = {(ip.instance, ip.var.name) for ip in inputs}
    events: list[EventPlan] = []
    for e in sc.events:
        fld = f"events[{e.index}]"
        k = 0
        if e.time is not None:
            if not start <= e.time < stop:
                raise ScenarioError(file, f"{fld}.time", f"{e.time!r} is outside the run {start!r}..{stop!r} s "
                                                         "(an event at the stop time would never act)")
            k = int(math.ceil((e.time - start) / step - 1e-9))
            if k >= n_steps:
                raise ScenarioError(file, f"{fld}.time", f"{e.time!r} is inside the short last step, after the "
                                                         f"last point of the step's grid before the stop {stop!r} "
                                                         "s: it would never act")
        reads = _condition_reads(file, f"{fld}.when", e, insts) if e.condition is not None else {}
        if e.action == "stop":
            events.append(EventPlan(e.time, k, None, None, "stop", None, None, e.index, e.when, e.condition,
                                    e.trigger, e.delay, reads))
            continue
        inst, vname = split_ref(file, f"{fld}.variable", e.variable)
        var = variable(file, f"{fld}.variable", insts[inst], vname)
        if var.shape:
            raise ScenarioError(file, f"{fld}.variable", f"{e.variable} is an array: events act on scalars")
        if e.action == "set":
            if var.causality != "parameter" or var.variability != "tunable":
                raise ScenarioError(file, f"{fld}.variable", f"{e.variable} is a {var.variability} {var.causality}: "
                                                             "set changes a tunable parameter during the run "
                                                             "(override changes an input)")
            value = checked_value(file, f"{fld}.value", var, e.value)
        else:
            if var.type == "Real":
                if var.causality not in ("input", "output"):
                    hint = " (set changes a tunable parameter)" if var.variability == "tunable" else ""
                    raise ScenarioError(file, f"{fld}.variable", f"{e.variable} must be an input or output{hint}")
            elif var.causality != "input" or (inst, var.name) in driven or (inst, var.name) in tabled:
                raise ScenarioError(file, f"{fld}.variable", f"{e.variable}: an event on a {var.type} variable "
                                                             "needs an input that no connection or table drives")
            elif e.action == "bias" and var.type != "Integer":
                raise ScenarioError(file, f"{fld}.action", f"a bias needs a Real or Integer variable, "
                                                           f"{e.variable} is {var.type}")
            if e.action == "reset":
                value = None
            elif e.action == "override" or var.type != "Real":
                value = checked_value(file, f"{fld}.value", var, e.value)
            else:
                value = float(checked_value(file, f"{fld}.value", Variable(var.name, 0, "Real", "input", "", None, None,
                                                                    None, None), e.value))
        events.append(EventPlan(e.time, k, inst, var, e.action, value, e.variable, e.index, e.when, e.condition,
                                e.trigger, e.delay, reads))
    return events


def given_event(plan: Plan, ref: str, value: Any, k: int, index: int = 0) -> EventPlan:
    """The timed event that gives ``ref`` (``"instance.variable"``) the value ``value`` before the step from
    step ``k`` of a run of ``plan`` (a driver's change while the run goes), checked as an ``[[events]]``
    entry at that time is: a tunable parameter is ``set``, an input is overridden (``override``), the value
    checked against the variable's type and the min/max its model description declares.  Anything else (an
    output, a fixed parameter, a local, an input a connection drives that is not Real, an array) is a
    ScenarioError whose reason says why."""
    file = plan.scenario.file
    fld = "variable"
    inst, vname = split_ref(file, fld, ref)
    if inst not in plan.instances:
        raise ScenarioError(file, fld, f"unknown instance {inst!r}{did_you_mean(inst, plan.instances)}")
    var = variable(file, fld, plan.instances[inst], vname)
    if var.causality == "parameter":
        action = "set"
    elif var.causality == "input":
        action = "override"
    else:
        raise ScenarioError(file, fld, f"{ref} is {'an' if var.causality[0] in 'aeiou' else 'a'} "
                                       f"{var.causality}: only tunable parameters and inputs can be given a value")
    start, _, step = plan.scenario.times()
    sc = dataclasses.replace(plan.scenario, events=[])
    sc.events.append(_EventSpec(start + k * step, ref, action, value, index))
    driven = {(c.dst, c.dst_var.name): i for i, c in enumerate(plan.connections)}
    (ev,) = _events(sc, plan.instances, driven, plan.inputs)
    ev.step = k
    return ev


def _condition_reads(file: str, fld: str, e: Any, insts: dict[str, InstancePlan]) -> dict[str, tuple[str, Variable]]:
    """The variables a condition reads (each must exist, be a scalar and not a String) and its type check."""
    from ..scenario.condition import ConditionError, check_types, variables

    reads: dict[str, tuple[str, Variable]] = {}
    for ref in variables(e.condition):
        inst, vname = ref.split(".", 1)
        var = variable(file, fld, insts[inst], vname)
        if var.shape:
            raise ScenarioError(file, fld, f"{ref} is an array: a condition reads scalars")
        if var.causality == "independent":
            raise ScenarioError(file, fld, f"{ref} is the independent variable: use t for the time")
        reads[ref] = (inst, var)
    try:
        check_types(e.condition, {ref: var.type for ref, (_, var) in reads.items()})
    except ConditionError as exc:
        raise ScenarioError(file, fld, str(exc)) from None
    return reads


def _requirements(sc: Scenario, insts: dict[str, InstancePlan], notes: list[str]) -> list[RequirementPlan]:
    """The requirements checked against their variables (each exists and is a scalar; types, units, the
    bounds against the communication step and the stop time), with what each reads; every variable a
    formula names is recorded.  A bound beyond the stop time is a note."""
    from ..requirements.formula import FormulaError, VarInfo, check, variables

    file = sc.file
    start, stop, step = sc.times()
    out: list[RequirementPlan] = []
    extra: list[str] = []
    for r in sc.requirements:
        fld = f"requirements[{r.index}].formula"
        reads: dict[str, tuple[str, Variable]] = {}
        info: dict[str, VarInfo] = {}
        for ref, pos in variables(r.node).items():
            inst, vname = ref.split(".", 1)
            where = f"requirement {r.name!r}: at character {pos}"
            try:
                var = variable(file, fld, insts[inst], vname)
            except MissingVariableError as exc:
                raise MissingVariableError(file, fld, f"{where}: {exc.reason}", exc.ref) from None
            if var.shape:
                raise ScenarioError(file, fld, f"{where}: {ref} is an array: a formula reads scalars")
            if var.causality == "independent":
                raise ScenarioError(file, fld, f"{where}: {ref} is the independent variable: use t for the time")
            reads[ref] = (inst, var)
            info[ref] = VarInfo(var.type, unit_of(insts[inst], var) if var.type == "Real" else None)
            if ref not in extra:
                extra.append(ref)
        try:
            checked = check(r.formula, info, step, stop - start, r.node)
        except FormulaError as exc:
            raise ScenarioError(file, fld, f"requirement {r.name!r}: {exc}") from None
        notes += [f"requirement {r.name!r}: {n}" for n in checked.notes]
        out.append(RequirementPlan(r.name, r.formula, r.on_violation, r.description, r.index, checked, reads))
    if extra:   # what a formula names is recorded
        sc.record = (sc.record or ["*.*"]) + [ref for ref in extra if ref not in (sc.record or [])]
    return out


def resolve(sc: Scenario, force: bool | None = None, isolate_all: bool = False) -> Plan:
    """Load every FMU of the scenario and run all the checks (the one preflight that ``check`` and ``run``
    share); returns the executable plan.  ``force`` lifts the limits of steps and recording size;
    ``isolate_all`` hosts every instance in a child process of its own (as if each said ``isolate = true``).

    ``sc`` is left as it is: the plan holds a copy of it with the times the FMUs' default experiments
    give filled in (``plan.scenario``)."""
    sc = _planned_copy(sc, force, isolate_all)
    try:
        return _resolve(sc)
    except MissingVariableError as exc:
        raise every_missing(sc.file, exc, missing_variables(sc)) from None


def _resolve(sc: Scenario) -> Plan:
    """:func:`resolve` of the plan's copy of the scenario."""
    insts, notes = _instance_plans(sc)
    _experiment(sc, {n: ip.model for n, ip in insts.items()}, notes)
    _tolerances(sc, insts, notes)
    _solvers(sc, insts)
    internal = _internal_steps(sc, insts)
    links = clock_links(sc, insts)
    conns, driven = _connection_plans(sc, insts, {lk.index for lk in links})
    _rates(sc, insts, conns)
    feeds = feed_graph(sc.order, conns)
    idle = _workers(sc, insts, feeds, notes)
    coupled = coupling(feeds, insts, conns)
    _check_stepping(sc, insts)
    _scheduled(sc, insts, conns, notes)
    check_clocked(sc, insts, conns, links, notes)
    check_iteration(sc, insts, coupled)
    requirements = _requirements(sc, insts, notes)
    record, not_recorded = _record(sc, insts)
    _live_xy(sc, insts, record, notes)
    _event_rows(sc, insts)
    inputs = _inputs(sc, insts, driven)
    for col in inputs:
        if insts[col.instance].interface == SCHEDULED_EXECUTION:
            raise ScenarioError(sc.file, "inputs", f"{col.column}: tabulated inputs of a scheduled execution instance "
                                                   "are not supported yet")
    start, stop, step = sc.times()
    n_steps, last_step = steps_of(start, stop, step)
    checked = _events(sc, insts, driven, inputs)
    events = sorted((ev for ev in checked if ev.condition is None), key=lambda ev: ev.step)  # stable within a step
    conditions = [ev for ev in checked if ev.condition is not None]
    check_clocked_reads(sc, insts, record, inputs, checked, requirements)
    plan = Plan(sc, {n: insts[n] for n in sc.order}, conns, record, events, n_steps, inputs, not_recorded,
                conditions, notes, internal, sc.archive_limits, coupled, last_step, requirements,
                [idle] if idle else [], feeds, links)
    _check_recording_size(plan)
    return plan


def _live_xy(sc: Scenario, insts: dict[str, InstancePlan], record: list[RecordPlan], notes: list[str]) -> None:
    """``[live] xy``: two variables of their FMUs (MissingVariableError otherwise); the live view draws their
    path from the recorded columns, so where one is not recorded it draws none, and a note says so (a base's
    ``[live]`` must not refuse a file that records less)."""
    columns = {r.column for r in record}
    for i, ref in enumerate(sc.xy):
        inst, name = split_ref(sc.file, f"live.xy[{i}]", ref)
        _element(sc.file, f"live.xy[{i}]", insts[inst], name)
    missing = [ref for ref in sc.xy if ref not in columns]
    if missing:
        notes.append(f"[live] xy: {' and '.join(missing)} {'is' if len(missing) == 1 else 'are'} not recorded: the "
                     "live view draws no path (record.variables names what is recorded)")
        sc.xy = []


@dataclasses.dataclass
class Missing:
    """A variable a scenario names that its FMU lacks: the fields that name it, the suggestion of a near name
    (" (did you mean 'x'?)" or ""), and, in a protocol, the runs that name it."""

    fields: list[str]
    hint: str = ""
    runs: list[str] = dataclasses.field(default_factory=list)


def missing_variables(sc: Scenario, more: dict[str, str] | None = None) -> dict[str, Missing]:
    """Every variable the scenario names that its instance's FMU lacks, {"instance.variable": Missing}, in
    the order of the checks (name maps, parameters, connections, record, events, requirements; then ``more``:
    {field: "instance.variable"}): what :func:`resolve` lists when it finds one (then it looks for them
    all).  An instance whose FMU cannot be loaded is left out (its own error says why); a name map's key is
    the FMU's own name."""
    from ..requirements.formula import variables as formula_variables
    from ..scenario.condition import variables as condition_variables

    found: dict[str, Missing] = {}
    insts: dict[str, InstancePlan] = {}
    for name, spec in sc.instances.items():
        try:
            model = load_model(spec.fmu_path, sc.archive_limits) if spec.fmu_path is not None else None
        except FmuLoadError:
            model = None
        if model is None:
            continue
        insts[name] = InstancePlan(name, spec, model, {o: t for t, o in spec.names.items()}, dict(spec.names))
        for their in spec.names:
            if their not in model.variables:
                found.setdefault(f"{name}.{their}", Missing([], did_you_mean(their, model.variables))).fields.append(
                    f"instances.{name}.names.{their}")

    def look(fld: str, ref: str) -> None:
        inst, _, var = ref.partition(".")
        if inst not in insts:
            return
        try:
            _element(sc.file, fld, insts[inst], var)
        except MissingVariableError as exc:
            hint = exc.reason[exc.reason.find(" (did you mean"):] if " (did you mean" in exc.reason else ""
            found.setdefault(ref, Missing([], hint)).fields.append(fld)
        except ScenarioError:
            pass   # (another fault of an existing variable: its own check reports it)

    for name, spec in sc.instances.items():
        for pname in spec.parameters:
            look(f"instances.{name}.parameters.{pname}", f"{name}.{pname}")
    for c in sc.connections:
        look(f"connections[{c.index}].from", c.src)
        look(f"connections[{c.index}].to", c.dst)
    for i, pat in enumerate(sc.record):
        if "*" not in pat and "?" not in pat:
            look(f"record.variables[{i}]", pat)
    for e in sc.events:
        if e.variable is not None:
            look(f"events[{e.index}].variable", e.variable)
        for ref in condition_variables(e.condition) if e.condition is not None else ():
            look(f"events[{e.index}].when", ref)
    for r in sc.requirements:
        for ref in formula_variables(r.node):
            look(f"requirements[{r.index}].formula", ref)
    for i, ref in enumerate(sc.xy):
        look(f"live.xy[{i}]", ref)
    for fld, ref in (more or {}).items():
        look(fld, ref)
    return found


def every_missing(file: str, first: MissingVariableError, found: dict[str, Missing],
                  runs: list[str] | None = None) -> MissingVariableError:
    """The one error that lists every missing variable ``found`` (``first``, the one the checks met, among
    them): "FILE: 3 variables missing from their FMUs: plant.a (connections[0].from), plant.b
    (runs.foam.parameters...; runs foam), ..."; ``first`` itself when it is the only one.  ``runs``: a
    protocol's runs (a variable that only some of them name says which)."""
    if first.ref not in found:
        found = {first.ref: Missing([first.field]), **found}
    if len(found) == 1:
        return first
    items = []
    for ref, m in found.items():
        where = m.fields[0] + (f" and {len(m.fields) - 1} more" if len(m.fields) > 1 else "")
        named_by_run = len(m.runs) == 1 and m.fields[0].startswith(f"runs.{m.runs[0]}.")
        if runs and m.runs and len(m.runs) < len(runs) and not named_by_run:
            where += f"; {plural(len(m.runs), 'run')} {', '.join(m.runs)}"
        if m.hint:
            where += f"; {m.hint.strip()[1:-1]}"    # (" (did you mean 'x'?)" -> "did you mean 'x'?")
        items.append(f"{ref} ({where})")
    return MissingVariableError(file, "", f"{len(found)} variables missing from their FMUs: {', '.join(items)}",
                                first.ref)


def _event_rows(sc: Scenario, insts: dict[str, InstancePlan]) -> None:
    """``[record] event_rows`` (rows at the instants of the FMU's events, before and after each, as FMPy's
    ``record_events``) is honoured for a run of one instance through model exchange in this process only:
    in a system, the recording is the communication grid of all the instances, and an isolated instance's
    events happen in another process.  ScenarioError where it cannot be honoured."""
    if not sc.event_rows:
        return
    why = None
    if len(insts) != 1:
        why = f"the run has {len(insts)} instances (the recording of a system is its communication grid)"
    else:
        name, ip = next(iter(insts.items()))
        if ip.interface != MODEL_EXCHANGE:
            why = f"instance {name} runs through {ip.interface} (its events are the FMU's own, inside its steps)"
        elif ip.spec.isolate:
            why = f"instance {name} is isolated (its events happen in a process of its own)"
    if why is not None:
        raise ScenarioError(sc.file, "record.event_rows", "rows at the events are recorded for a run of one "
                            f"instance through model exchange in this process only: {why}")


def _workers(sc: Scenario, insts: dict[str, InstancePlan], feeds: FeedGraph, notes: list[str]) -> str:
    """Stepping instances at once: Jacobi's every instance, Gauss-Seidel's each level (the instances that
    do not feed each other: the plan's graph's :attr:`~..stepping.graph.FeedGraph.levels`), at one rate; a
    note says which step at once, how, and when there are more workers than instances that can step at once.
    Returns why nothing steps at once ("" where something does, or workers = 1): what ``run`` says too."""
    if sc.workers == 1:
        return ""
    if not algorithms.row(sc.algorithm).workers:
        able = " or ".join(algorithms.quoted(n) for n in algorithms.names_where("workers"))
        raise ScenarioError(sc.file, "experiment.workers", f"{sc.workers}: stepping instances at once is "
                                                           f"algorithm {able}'s, not {sc.algorithm!r}")
    slow = [n for n, ip in insts.items() if ip.decimation > 1]
    if slow:
        raise ScenarioError(sc.file, "experiment.workers", f"{sc.workers}: {slow[0]} steps at its own rate; "
                                                           "instances at their own rates step one at a time")
    order = list(sc.order)
    by_levels = None
    if not algorithms.row(sc.algorithm).simultaneous:   # Gauss-Seidel: by levels
        by_levels = feeds.named(feeds.levels)
    ordered = [(n, insts[n]) for n in order]
    notes.append(workers_note(sc.workers, ordered, by_levels))
    return workers_idle(sc.workers, ordered, by_levels)


@dataclasses.dataclass
class _AtOnce:
    """How the instances can step at once: the isolated ones (in their processes), why each other one
    steps alone on the master's thread ("" where it can step in a thread), the groups that step at once
    (Gauss-Seidel's levels, or Jacobi's one), and the most instances of one group that can step at once."""

    apart: list[str]
    alone: dict[str, str]
    groups: list[list[str]]
    able: int

    @property
    def threaded(self) -> list[str]:
        return [n for n, why in self.alone.items() if not why]


def _at_once(insts: list[tuple[str, InstancePlan]], levels_: list[list[str]] | None) -> _AtOnce:
    apart = [n for n, ip in insts if ip.spec.isolate]
    alone = {n: alone_because(ip) for n, ip in insts if not ip.spec.isolate}
    groups = levels_ if levels_ is not None else [[n for n, _ in insts]]
    able = max(sum(n in apart or (n in alone and not alone[n]) for n in g) for g in groups)
    return _AtOnce(apart, alone, groups, able)


def workers_idle(workers: int, insts: list[tuple[str, InstancePlan]], levels_: list[list[str]] | None = None) -> str:
    """Why ``workers`` > 1 step nothing at once, in one line ("" where two instances or more can step at
    once): the instances that step alone on the master's thread and why, or Gauss-Seidel's levels of one
    instance that could (``levels_``: as for :func:`workers_note`)."""
    at = _at_once(insts, levels_)
    if workers == 1 or at.able > 1:
        return ""
    whys: dict[str, list[str]] = {}
    for n, why in at.alone.items():
        if why:
            whys.setdefault(why, []).append(n)
    parts = [f"{', '.join(names)} on the master's thread alone ({why})" for why, names in whys.items()]
    if levels_ is not None and (at.apart or at.threaded):
        parts.append("under Gauss-Seidel the instances of a level step at once, and no level has two that can: "
                     + " | ".join(", ".join(g) for g in levels_))
    return f"workers = {workers}, but nothing steps in parallel: " + "; ".join(parts)


def workers_note(workers: int, insts: list[tuple[str, InstancePlan]], levels_: list[list[str]] | None = None) -> str:
    """Which instances step at once, and how (as :mod:`~..stepping.parallel` steps them): the isolated ones
    in their processes, the C FMUs in this process in lanes of threads, and the others on the master's
    thread alone, each with why; ``levels_``: Gauss-Seidel's levels (None: Jacobi, one group)."""
    at = _at_once(insts, levels_)
    apart, alone, threaded = at.apart, at.alone, at.threaded
    lanes = max(min(workers, sum(n in threaded for n in g)) for g in at.groups)
    parts = []
    if levels_ is not None:
        parts.append("Gauss-Seidel by levels, the instances of a level (they do not feed each other) at once: "
                     + " | ".join(", ".join(g) for g in levels_))
    parts.append(f"{', '.join(apart)} (isolated) step at once, up to {workers} together" if apart
                 else "no instance is isolated")
    if lanes > 1:
        parts.append(f"{', '.join(threaded)} (C FMUs in this process) in {lanes} lanes, the master's thread and "
                     f"{count(lanes - 1, 'thread')}")
    elif threaded:
        parts.append(f"{', '.join(threaded)} (in this process) on the master's thread")
    parts += [f"{n} on the master's thread alone ({why})" for n, why in alone.items() if why]
    if workers > max(at.able, 1):
        parts.append(f"more workers than instances that can step at once ({at.able}): "
                     f"{count(max(at.able, 1), 'worker')} will be busy at most")
    return f"workers = {workers}: " + "; ".join(parts)


def alone_because(ip: InstancePlan) -> str:
    """Why an instance in this process cannot step in a thread beside others ("" where it can)."""
    if ip.solver is not None:
        return ME_ALONE
    try:
        with zipfile.ZipFile(ip.model.path) as zf:
            python = runs_python(zf.namelist())
    except (OSError, zipfile.BadZipFile):
        python = False
    return PYTHON_FMU if python else ""


def _rates(sc: Scenario, insts: dict[str, InstancePlan], conns: list[ConnectionPlan]) -> None:
    """Each instance's own step: a whole multiple d of the experiment's step (its decimation), the run a
    whole number of its steps; two connected instances' rates divide one another (then every value
    exchanged is the latest at the receiver's step points, as libcosim exchanges them); only the fixed-step
    one-pass algorithms step instances at their own rates."""
    start, stop, base = sc.times()
    n_steps, last = steps_of(start, stop, base)
    for name, ip in insts.items():
        own = ip.spec.step
        if own is None:
            continue
        fld = f"instances.{name}.step"
        d = own / base
        m = int(round(d))
        if m < 1 or abs(d - m) > 1e-9 * max(1.0, d):
            raise ScenarioError(sc.file, fld, f"{own!r} s is not a whole multiple of the experiment's step "
                                              f"{base!r} s")
        if n_steps % m or (last is not None and m > 1):
            raise ScenarioError(sc.file, fld, f"{own!r} s does not divide the run {start!r}..{stop!r} s "
                                              f"({n_steps} steps of {base!r} s) into whole steps")
        if m > 1 and not algorithms.row(sc.algorithm).one_pass:
            able = " or ".join(algorithms.quoted(n) for n in algorithms.names_where("one_pass"))
            raise ScenarioError(sc.file, fld, f"algorithm {sc.algorithm!r} steps every instance at every step; "
                                              f"instances at their own rates run under {able}")
        ip.decimation = m
    for c in conns:
        a, b = insts[c.src].decimation, insts[c.dst].decimation
        if a % b and b % a:
            raise ScenarioError(sc.file, f"connections[{c.spec.index}]",
                                f"{c.src} steps every {a} and {c.dst} every {b} of the experiment's steps: "
                                f"connected instances' rates must divide one another")


def _check_stepping(sc: Scenario, insts: dict[str, InstancePlan]) -> None:
    """The step-size control, and a short last step (a step that does not divide the run), vary an
    instance's communication step: refused, naming the instance, where a co-simulation FMU declares it
    cannot take steps of varying length (canHandleVariableCommunicationStepSize false: a sampled-data block
    whose sample period is its step); then the step-size control's bounds against the output interval
    (known only now, when the FMUs' default experiments may give the step)."""
    start, stop, step = sc.times()
    last = steps_of(start, stop, step)[1]
    for name in sc.order:
        ip = insts[name]
        if ip.interface != CO_SIMULATION or ip.model.can_vary_step:
            continue
        cannot = (f"{ip.model.path.name} declares canHandleVariableCommunicationStepSize = false (it takes steps "
                  "of one length only)")
        if algorithms.row(sc.algorithm).varies_step:
            raise ScenarioError(sc.file, f"instances.{name}",
                                f"{cannot}, and the step-size control (algorithm = {algorithms.quoted(sc.algorithm)}) "
                                "varies every instance's step: run it under a fixed-step algorithm")
        if last is not None:
            raise ScenarioError(sc.file, "experiment.stop",
                                f"the step {step!r} s does not divide the run {start!r}..{stop!r} s, which would "
                                f"end with a short step of {last:.6g} s; {name}: {cannot}: give a stop time on "
                                "the step's grid")
    if sc.adaptive is None:
        return
    try:
        check_adaptive(sc.adaptive, sc.times()[2])
    except SpecError as exc:
        raise ScenarioError(sc.file, exc.key, exc.reason) from None


def _planned_copy(sc: Scenario, force: bool | None, isolate_all: bool) -> Scenario:
    """The copy of ``sc`` the plan holds, with copies of its instances (so that neither resolving nor a
    change to the plan changes ``sc``): forced if ``force`` says so, every instance isolated if
    ``isolate_all``."""
    sc = copy.copy(sc)
    if force is not None:
        sc.force = force
    sc.instances = {n: dataclasses.replace(spec, isolate=spec.isolate or isolate_all)
                    for n, spec in sc.instances.items()}
    return sc


def _instance_plans(sc: Scenario) -> tuple[dict[str, InstancePlan], list[str]]:
    """Every instance's FMU loaded, its name map, units and parameters checked; with the notes of units
    that override declared ones."""
    insts: dict[str, InstancePlan] = {}
    notes: list[str] = []
    for name, spec in sc.instances.items():
        insts[name] = _instance_plan(sc, name, spec, notes)
    return insts, notes


def _instance_plan(sc: Scenario, name: str, spec: InstanceSpec, notes: list[str]) -> InstancePlan:
    """One instance: its FMU loaded (its archive within the scenario's limits), its name map, units and
    parameters checked (a note added to ``notes`` for each unit that overrides a declared one)."""
    file = sc.file
    if spec.fmu_path is None:   # (parse gives every instance a file or refuses it)
        raise ScenarioError(file, f"instances.{name}.fmu", f"no FMU file for {spec.fmu!r}")
    try:
        model = load_model(spec.fmu_path, sc.archive_limits)
    except FmuLoadError as exc:
        raise ScenarioError(file, f"instances.{name}.fmu", str(exc)) from None
    ip = InstancePlan(name, spec, model, {o: t for t, o in spec.names.items()}, dict(spec.names),
                      interface=_interface(file, name, spec, model))
    for their, ours in spec.names.items():
        if their not in model.variables:
            raise MissingVariableError(file, f"instances.{name}.names.{their}",
                                       f"{model.path.name} has no variable {their!r}", f"{name}.{their}")
        if ours != their and ours in model.variables and ours not in spec.names:
            raise ScenarioError(file, f"instances.{name}.names.{their}",
                                f"{ours!r} is already the name of another variable of {model.path.name}")
    for var_name, unit_name in spec.units.items():
        note = _declared_unit(file, f"instances.{name}.units.{var_name}", ip, var_name, unit_name)
        if note:
            notes.append(note)
    for pname, value in spec.parameters.items():
        fld = f"instances.{name}.parameters.{pname}"
        var = variable(file, fld, ip, pname, PARAMETERS)
        reason = var.settable()
        if reason:
            raise ScenarioError(file, fld, reason)
        ip.parameters.append((var, checked_value(file, fld, var, value)))
    return ip


def _interface(file: str, name: str, spec: InstanceSpec, model: FmuModel) -> str:
    """The interface an instance runs: the one it names; else model exchange if it gives an integrator
    setting or the FMU has no co-simulation interface; else co-simulation (an FMU with both runs as
    co-simulation unless asked).  ScenarioError (naming the field that asked for it) when the FMU lacks that
    interface or its binary for this platform."""
    asked_by = [k for k in SOLVER_KEYS if getattr(spec, k) is not None]
    if spec.interface is not None:
        wanted, fld, why = spec.interface, f"instances.{name}.interface", ""
    elif asked_by:
        wanted, fld = MODEL_EXCHANGE, f"instances.{name}.{asked_by[0]}"
        why = " (an integrator setting runs it as model exchange)"
    else:
        wanted = CO_SIMULATION if model.has_cs else MODEL_EXCHANGE if model.has_me else SCHEDULED_EXECUTION
        fld, why = f"instances.{name}.fmu", ""
    if wanted not in model.interfaces:
        has = " and ".join(INTERFACE_NAMES[i] for i in model.interfaces)
        raise ScenarioError(file, fld, f"{model.path.name} has no {INTERFACE_NAMES[wanted]} interface (it has "
                                       f"{has} only){why}")
    try:
        model.check_binary(wanted)
    except FmuLoadError as exc:
        raise ScenarioError(file, fld, f"{INTERFACE_NAMES[wanted]}: {exc}") from None
    return wanted


def _scheduled(sc: Scenario, insts: dict[str, InstancePlan], conns: list[ConnectionPlan], notes: list[str]) -> None:
    """What the master's scheduler of a scheduled execution instance honours exactly, else ScenarioError in
    one line: the default algorithm at the experiment's step, in this process, nothing connected to it or
    from it (clocked variables are not exchanged yet); each periodic input clock with its interval (and
    shift) declared and a whole number of steps; each triggered input clock ticked by ``clock_ticks`` at
    times on the grid; no tunable or changing clock.  ``clock_ticks`` only for the triggered input clocks
    of such an instance.  An output clock, which feeds nothing yet, is a note."""
    for name, ip in insts.items():
        fld = f"instances.{name}"
        if ip.interface != SCHEDULED_EXECUTION:
            continue   # (an instance with clocks in co-simulation: plan.clocked.check_clocked)
        if sc.algorithm != algorithms.DEFAULT:
            raise ScenarioError(sc.file, "experiment.algorithm", f"{sc.algorithm}: a scheduled execution instance "
                                f"({name}) runs under {algorithms.DEFAULT} only")
        for key in ("isolate", "step"):
            if getattr(ip.spec, key):
                raise ScenarioError(sc.file, f"{fld}.{key}", "not supported for a scheduled execution instance "
                                                             "(its partitions run in the master's process, on its grid)")
        for cp in conns:
            if name in (cp.src, cp.dst):
                raise ScenarioError(sc.file, "connections", f"{cp.src}.{cp.src_var.name} -> {cp.dst}.{cp.dst_var.name}: "
                                    "connections of a scheduled execution instance are not supported yet")
        for ev in sc.events:   # (its variables change at its clocks' ticks: the scheduler sets nothing between)
            if ev.variable is not None and ev.variable.split(".", 1)[0] == name:
                raise ScenarioError(sc.file, f"events[{ev.index}].variable", f"{ev.variable}: events on a scheduled "
                                                                             "execution instance are not supported yet")
        ticks_named(sc, name, ip)
        _scheduled_clocks(sc, name, ip, notes)


def _scheduled_clocks(sc: Scenario, name: str, ip: InstancePlan, notes: list[str]) -> None:
    """:func:`_scheduled` for the clocks of one scheduled execution instance ``name``: each input clock
    periodic with its interval (and shift) a whole number of steps, or triggered with ``clock_ticks`` on the
    grid, or countdown; an output clock a note."""
    for c in ip.model.clocks:
        cf = f"instances.{name}.fmu"
        if c.causality == "output":
            notes.append(f"{name}: output clock {c.name} is raised by the FMU and feeds nothing (output "
                         "clocks are not connected yet)")
        elif c.causality != "input":
            continue
        elif c.variability in ("tunable", "changing"):
            raise ScenarioError(sc.file, cf, f"clock {c.name}: intervalVariability {c.variability!r} is not "
                                             "supported yet (the FMU may change its interval)")
        elif c.periodic:
            periodic_on_grid(sc, name, c)
        elif c.variability == "triggered":
            triggered_on_grid(sc, name, ip, c, None)
        elif c.variability != "countdown":
            raise ScenarioError(sc.file, cf, f"clock {c.name}: intervalVariability {c.variability!r} is not "
                                             "supported")


def _solvers(sc: Scenario, insts: dict[str, InstancePlan]) -> None:
    """Each model exchange instance's integrator: its solver (CVODE by default), the tolerance it resolved
    to (:func:`_tolerances`), its largest step and event tolerance."""
    for ip in insts.values():
        if ip.interface != MODEL_EXCHANGE:
            continue
        spec = ip.spec
        ip.solver = SolverSpec(spec.solver or "cvode", ip.tolerance, spec.max_step,
                               spec.event_tolerance if spec.event_tolerance is not None else DEFAULT_EVENT_TOLERANCE)


def _connection_plans(sc: Scenario, insts: dict[str, InstancePlan], between_clocks: set[int] = set()
                      ) -> tuple[list[ConnectionPlan], dict[tuple[str, str], int]]:
    """The connections checked, and the inputs they drive ((instance, variable) -> connection index); the
    connections between clocks (their indices ``between_clocks``) are not among them."""
    conns: list[ConnectionPlan] = []
    driven: dict[tuple[str, str], int] = {}
    for c in sc.connections:
        if c.index in between_clocks:
            continue
        conns.append(_connection_plan(sc.file, c, insts, driven))
    return conns, driven


def _connection_plan(file: str, c: ConnectionSpec, insts: dict[str, InstancePlan],
                     driven: dict[tuple[str, str], int]) -> ConnectionPlan:
    """One connection: its ends exist, an output drives an input no other connection drives (added to
    ``driven``), sizes, types and units agree."""
    fld = f"connections[{c.index}]"
    si, sv = split_ref(file, f"{fld}.from", c.src)
    di, dv = split_ref(file, f"{fld}.to", c.dst)
    svar, src_elem = _element(file, f"{fld}.from", insts[si], sv, OUTPUTS)
    dvar, dst_elem = _element(file, f"{fld}.to", insts[di], dv, INPUTS)
    if dst_elem is not None:
        raise ScenarioError(file, f"{fld}.to", f"{c.dst}: an element of an input array cannot be a target "
                                               f"(connect the whole array {dvar.name})")
    if src_elem is not None and (dvar.size != 1 or not svar.is_float64):
        raise ScenarioError(file, fld, f"{c.src} -> {c.dst}: an element of a Float64 array goes to a scalar")
    if src_elem is None and svar.size != dvar.size:
        raise ScenarioError(file, fld, f"{c.src} has {svar.size} values, {c.dst} {dvar.size}: arrays connect "
                                       "whole, of one size (or one element to a scalar)")
    if svar.causality != "output":
        raise ScenarioError(file, f"{fld}.from", f"{c.src} is {svar.causality}, not an output")
    if dvar.causality != "input":
        raise ScenarioError(file, f"{fld}.to", f"{c.dst} is {dvar.causality}, not an input: it cannot be a target")
    key = (di, dvar.name)
    if key in driven:
        raise ScenarioError(file, f"{fld}.to", f"{c.dst} is already driven by connections[{driven[key]}]")
    driven[key] = c.index
    f, o = _connection_types(file, fld, c, svar, dvar, insts[si], insts[di])
    return ConnectionPlan(si, svar, di, dvar, c.factor * f, c.factor * o + c.offset, c, src_elem)


def _check_recording_size(plan: Plan) -> None:
    """A recording expected larger than ``max_bytes`` is refused (unless forced)."""
    sc = plan.scenario
    if plan.output_bytes > sc.max_bytes and not sc.force:
        raise ScenarioError(sc.file, "record", f"the recording would take about {plan.output_bytes / 2 ** 20:.0f} MiB "
                                               f"(more than max_bytes = {sc.max_bytes}): record fewer variables, "
                                               f"decimate, raise record.max_bytes, or --force")
