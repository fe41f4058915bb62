"""The plan as one FMI 2.0 (or, ``fmi=3``, FMI 3.0) co-simulation FMU (a container): its FMUs unpacked under
resources/, the system as data (resources/system.txt: the wiring the master's loop takes, parameters, start values, the container's
variables), and a binary built from the master's own compiled loop (``stepping/container.c``, which includes
``stepping/native_loop.c``) with the same compiler flags, so that a host running the container gets what
``run`` of the plan gives, bit for bit.

Its binary is built for linux64, and for win64 (MinGW-w64, the same C: the inner FMUs' DLLs loaded with
LoadLibrary) where the cross compiler is on PATH and every inner FMU has a win64 binary.

What this export takes (everything else is refused before anything is written, one line naming it): FMI 2.0
and FMI 3.0 co-simulation FMUs with a binary for this platform (C, or pythonfmu's behind our loader, which
finds its Python as when a host loads the FMU alone; an FMI 3.0 one called as the master calls it:
``stepping/container_inner3.c``), FMI 2.0 Model Exchange FMUs integrated as the master
integrates them (``stepping/container_me.c``: Euler, RK4, and CVODE from FMPy's SUNDIALS libraries shipped in
resources/sundials/), Gauss-Seidel or Jacobi (instances at their own rates too, as the master's
multi-rate passes), the iterated coupling (``stepping/container_iter.c``: the coupling loops rolled back
through the inner FMUs' fmi2GetFMUstate / fmi2SetFMUstate), connections of numbers and booleans (Float64 ones as the master's copies, the others as
its get-and-set copiers, with their conversions: :func:`_other`), recorded Real (Float64), Integer (FMI 2.0
Integer and Enumeration, FMI 3.0 Int32) and Boolean outputs, timed events and input tables (the exporter
replays the events through the master's wiring and writes what each one changes at its step:
``stepping/container_actions.c`` applies it), no events on conditions, requirements or rows at events.  The container's
variables: the recorded outputs (named as their columns), the open inputs and the parameters of the inner FMUs
of type Real, Integer or Boolean (FMI 3.0: scalar Float64, Int32, Boolean; ``instance.variable``, the
scenario's value as start), in the plan's order.

The FMI 3.0 face (``stepping/container3.c`` around the same runtime, binaries/x86_64-linux): the same
variables as Float64, Int32 and Boolean with the same value references, the GUID as instantiation token.
"""
from __future__ import annotations

import hashlib
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from ..instances.in_process import ACCESS
from ..instances.integrators import DEFAULT_RTOL
from ..messages.errors import CosimError, ScenarioError
from ..model.archive import safe_extract
from ..model.description import CO_SIMULATION, MODEL_EXCHANGE
from ..model.types import FLOAT64_TYPES
from ..stepping import native
from ..stepping.settings import IterationSpec
from ..stepping.table import GAUSS_SEIDEL, ITERATED, JACOBI
from .records import InstancePlan, Plan
from .wiring import RowLayout, Wiring, discrete_event_value

SOURCE = native.SOURCE.with_name("container.c")
SOURCE3 = native.SOURCE.with_name("container3.c")   # the FMI 3.0 face: includes container.c
#: The files container.c includes beside native_loop.c (shipped in the container's sources/ with it): timed
#: events and input tables; inner FMI 3.0 FMUs and the connections that are not Float64; Model Exchange
#: instances (the master's integrators and event handling); the iterated coupling.
INCLUDED = tuple(native.SOURCE.with_name(f) for f in ("container_actions.c", "container_inner3.c", "container_me.c",
                                                             "container_iter.c"))
#: The FMI 3.0 standard's headers container3.c includes (FMPy's copy: :func:`native.fmi_headers`).
HEADERS3 = ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")
FORMAT = "wmr-container 7"   # the first line of system.txt (container.c's VERSION_TAG)


#: The FMI 2.0 types of the container's variables, and their letters in system.txt.
TYPES = {"Real": "R", "Integer": "I", "Boolean": "B"}
#: Their FMI 3.0 types (the FMI 3.0 face of the container).
TYPES3 = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
#: The FMI 3.0 types of an inner FMU's scalar variables that are the container's variables, as their FMI 2.0 types.
FMI3_VARS = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean"}
#: The FMI 3.0 types a scenario's value is set as by the container's own setters (the others: "param T").
FMI3_SCALARS = ("Float64", "Int32", "Boolean", "String")
#: The most connections that are not Float64 to Float64 a container holds (container_inner3.c's OTHER_MAX).
OTHER_MAX = 256
#: The FMI versions the container can be written for, and the binaries' folder of each platform in each.
PLATFORM_FOLDERS = {2: {"linux64": "linux64", "win64": "win64"}, 3: {"linux64": "x86_64-linux", "win64": "x86_64-windows"}}


@dataclass
class ContainerVar:
    """One variable of the container: ``kind`` "o" (a recorded output: ``ref`` its row slot for a Real, the
    inner FMU's value reference for an Integer or a Boolean, read from it when the host asks), "i" (an open
    input) or "p" (a parameter; ``ref`` the inner FMU's value reference), ``inst`` its instance's index,
    ``type`` its FMI 2.0 type (a key of :data:`TYPES`), ``start`` its value as a float (an Integer's or a
    Boolean's exactly: 0.0 or 1.0 for false or true)."""

    name: str
    kind: str
    inst: int
    ref: int
    start: float
    variability: str
    unit: str | None
    description: str
    type: str = "Real"


def _hex(text: str) -> str:
    return "x" + text.encode().hex()


def _num(x: float) -> str:
    return float(x).hex()


def refuse(plan: Plan, out: Path, name: str) -> None:
    """ScenarioError, one line, for what this container cannot hold (nothing is written before)."""
    sc = plan.scenario

    def no(field: str, reason: str) -> None:
        raise ScenarioError(sc.file, field, f"{reason}: it cannot be exported as an FMU container yet")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        raise ScenarioError(sc.file, "--name", f"{name!r}: a model identifier is a C name (letters, digits, _)")
    if sys.platform != "linux":
        raise CosimError("export-fmu builds the container's linux64 binary: run it on Linux")
    if sc.algorithm not in (GAUSS_SEIDEL, JACOBI, ITERATED):
        no("experiment.algorithm", f"{sc.algorithm!r} (only gauss-seidel, jacobi and iterated)")
    for n, ip in plan.instances.items():
        _refuse_instance(plan, n, ip, out, no)
    if sc.algorithm == ITERATED:   # (container_iter.c rolls back FMI 2.0 co-simulation FMUs on Float64 copies)
        _refuse_iterated(plan, no)
    if plan.last_step is not None:   # a host steps the container by whole steps of the scenario's
        no("experiment.stop", f"stop = {sc.stop!r} s is not on the grid of step = {sc.step!r} s (the run's last step "
                              f"is {plan.last_step!r} s; the container takes whole steps)")
    if plan.conditions:
        no("events", f"events[{plan.conditions[0].index}] acts on a condition (timed events only)")
    if plan.inputs and any(plan.instances[n].decimation > 1 for n in plan.order):
        no("inputs", "input tables with instances at their own rates")
    for ev in plan.events:   # (the values an event or a table sets go through the FMI 2.0 types' setters)
        if ev.var is not None and ev.instance is not None and not _settable(plan, ev.instance, ev.var):
            no("events", f"events[{ev.index}] acts on {ev.ref}, an FMI 3.0 {ev.var.fmi_type}"
                         f"{' array' if ev.var.shape else ''} (only scalar Float64, Int32, Boolean and String)")
    for ev in plan.events:   # (a Model Exchange instance takes values through its integrator's set: copies)
        if ev.instance is not None and ev.var is not None and plan.instances[ev.instance].interface == MODEL_EXCHANGE \
                and (ev.action == "set" or ev.var.type != "Real"):
            no("events", f"events[{ev.index}] sets {ev.ref} on a Model Exchange instance (only the overrides, "
                         "biases and resets of its Real inputs)")
    for col in plan.inputs:
        if plan.instances[col.instance].interface == MODEL_EXCHANGE and not col.var.is_float64:
            no("inputs", f"{col.column}: a column that is not Float64 for a Model Exchange instance")
        if not _settable(plan, col.instance, col.var):
            no("inputs", f"{col.column} is an FMI 3.0 {col.var.fmi_type}{' array' if col.var.shape else ''} "
                         "(only scalar Float64, Int32, Boolean and String)")
    if plan.requirements:
        no("requirements", "requirements")
    if sc.event_rows:
        no("record.event_rows", "rows at the events of a Model Exchange instance")
    others = [c for c in plan.connections if not c.is_float64]
    for c in others:
        for var in (c.src_var, c.dst_var):
            if var.type in ("String", "Binary", "Clock"):
                no("connections", f"{c.src}.{c.src_var.name} -> {c.dst}.{c.dst_var.name} is {var.fmi_type} "
                                  "(only numbers and booleans)")
    if len(others) > OTHER_MAX:
        no("connections", f"{len(others)} connections that are not Float64 to Float64 (at most {OTHER_MAX})")
    for c in others:   # (a Model Exchange instance's inputs go through its integrator's set: Float64 copies)
        if plan.instances[c.dst].interface == MODEL_EXCHANGE:
            no("connections", f"{c.src}.{c.src_var.name} -> {c.dst}.{c.dst_var.name}: a connection that is not "
                              "Float64 to a Model Exchange instance")
    for r in plan.record:
        if _record_type(plan, r) is None:
            only = "Float64, Int32 and Boolean outputs of an FMI 3.0 FMU" if plan.instances[r.instance].model.fmi == 3 \
                else "Real, Integer, Enumeration and Boolean outputs"
            no("record", f"{r.column} is {r.var.fmi_type}{list(r.var.shape) if r.var.shape else ''} (only {only})")


def _refuse_iterated(plan: Plan, no: Any) -> None:
    """What the container's iterated coupling does not hold yet: FMI 3.0 FMUs, Model Exchange instances,
    connections that are not Float64, timed events and input tables."""
    why = "with the iterated coupling"
    for n, ip in plan.instances.items():
        if ip.model.fmi != 2:
            no(f"instances.{n}", f"{ip.model.path.name} is an FMI {ip.model.fmi}.0 FMU {why} (only FMI 2.0)")
        if ip.interface == MODEL_EXCHANGE:
            no(f"instances.{n}", f"{ip.model.path.name} runs as Model Exchange {why} (only co-simulation)")
    for c in plan.connections:
        if not c.is_float64:
            no("connections", f"{c.src}.{c.src_var.name} -> {c.dst}.{c.dst_var.name} is not Float64 to Float64 {why}")
    if plan.events:
        no("events", f"timed events {why}")
    if plan.inputs:
        no("inputs", f"input tables {why}")


def _settable(plan: Plan, inst: str, var: Any) -> bool:
    """Whether an event or a table can set ``var`` of ``inst`` (an FMI 2.0 variable, or a scalar FMI 3.0
    one of the types the FMI 2.0 setters reach)."""
    return plan.instances[inst].model.fmi == 2 or (not var.shape and var.fmi_type in FMI3_SCALARS)


def _refuse_instance(plan: Plan, n: str, ip: InstancePlan, out: Path, no: Any) -> None:
    where = f"instances.{n}"
    if ip.model.fmi not in (2, 3):
        no(where, f"{ip.model.path.name} is an FMI {ip.model.fmi}.0 FMU (only FMI 2.0 and 3.0)")
    if ip.interface == MODEL_EXCHANGE and ip.model.fmi == 3:
        no(where, f"{ip.model.path.name} runs as FMI 3.0 Model Exchange (only FMI 2.0 Model Exchange)")
    if ip.interface not in (CO_SIMULATION, MODEL_EXCHANGE):
        no(where, f"{ip.model.path.name} runs as {ip.interface} (only co-simulation and Model Exchange)")
    if ip.model.clocks:   # (the container's C loop has no event mode)
        no(where, f"{ip.model.path.name} has clocks (its events and clocked variables are run by the master only)")
    if ip.interface == MODEL_EXCHANGE and ip.solver is not None:
        if ip.solver.name not in ME_SOLVERS:
            no(f"{where}.solver", f"solver = {ip.solver.name!r} (a Model Exchange instance inside is integrated by "
                                  f"{', '.join(ME_SOLVERS)} only)")
        missing = [lib for lib in SUNDIALS_LIBS if not (sundials_folder() / f"{lib}.so").is_file()] \
            if ip.solver.name == "cvode" else []
        if missing:
            no(f"{where}.solver", f"solver = 'cvode' needs FMPy's SUNDIALS libraries, and {missing[0]}.so is not in "
                                  f"{sundials_folder()}")
    # (an FMU without a binary for this platform, linux64, has no plan: the master's resolution refuses it)
    for var, value in ip.parameters:
        if ip.model.fmi == 3 and (var.fmi_type == "Binary" or var.fmi_type == "String" and var.shape):
            no(f"{where}.parameters.{var.name}", f"{var.fmi_type}{list(var.shape) if var.shape else ''} (the "
                                                 "container sets numbers, booleans and single strings)")
    if out.resolve() == ip.model.path.resolve():
        raise ScenarioError(plan.scenario.file, "--out", f"{out} is the FMU of instance {n}: write the container "
                                                          "elsewhere")


def variables(plan: Plan, layout: RowLayout) -> list[ContainerVar]:
    """The container's variables: recorded outputs, then open inputs and parameters (Real, Integer, Boolean) by
    instance (``inst``: its index in the plan's order)."""
    cols = plan.columns()
    index = {n: i for i, n in enumerate(plan.order)}
    out = [ContainerVar(r.column, "o", -1 if r.var.is_float64 else index[r.instance],
                        layout.slot(r) if r.var.is_float64 else r.var.vr, 0.0,
                        "continuous" if r.var.variability == "continuous" else "discrete", cols[r.column]["unit"],
                        f"{r.instance}.{plan.instances[r.instance].our_name(r.var)} of {cols[r.column]['fmu']}",
                        _record_type(plan, r) or "Real")
           for r in plan.record]
    # (an input a connection, a table or an event drives is not the host's)
    driven = {(c.dst, c.dst_var.name) for c in plan.connections} | \
        {(ip.instance, ip.var.name) for ip in plan.inputs} | \
        {(ev.instance, ev.var.name) for ev in plan.events if ev.var is not None and ev.var.causality == "input"}
    for i, n in enumerate(plan.order):
        ip = plan.instances[n]
        given = {var.name: value for var, value in ip.parameters}
        for var in ip.model.variables.values():
            open_input = var.causality == "input" and (n, var.name) not in driven
            parameter = var.causality == "parameter" and var.variability in ("fixed", "tunable")
            value = given.get(var.name, var.start)
            typ = _var_type(ip, var)
            if typ is None or not (open_input or parameter) or value is None:
                continue
            unit = var.unit.name if typ == "Real" and var.unit is not None else None
            variability = var.variability if parameter else "continuous" if typ == "Real" else "discrete"
            out.append(ContainerVar(f"{n}.{ip.our_name(var)}", "i" if open_input else "p", i, var.vr,
                                    float(value) if typ == "Real" else float(int(value)), variability, unit,
                                    var.description or f"{var.name} of {ip.model.path.name}", typ))
    seen: dict[str, ContainerVar] = {}
    for v in out:
        if v.name in seen:
            raise ScenarioError(plan.scenario.file, "record", f"{v.name!r} would be the container's variable twice "
                                                              f"(a recorded output and {_A[v.kind]})")
        seen[v.name] = v
    return out


def _var_type(ip: InstancePlan, var: Any) -> str | None:
    """The container's type (a key of :data:`TYPES`) of an inner FMU's input or parameter, None where it
    cannot be the container's variable: FMI 2.0 Real, Integer, Boolean; FMI 3.0 scalar Float64, Int32,
    Boolean."""
    if ip.model.fmi == 3:
        return None if var.shape else FMI3_VARS.get(var.fmi_type)
    return var.type if var.type in TYPES else None


def _record_type(plan: Plan, r: Any) -> str | None:
    """The container's type of a recorded output (None: it cannot be one): a Float64 (of the row) Real; FMI 2.0
    Integer and Enumeration (read with fmi2GetInteger, as the master records it) Integer, Boolean Boolean;
    FMI 3.0 scalar Int32 Integer, Boolean Boolean."""
    if r.var.is_float64:
        return "Real"
    if plan.instances[r.instance].model.fmi == 3:
        return None if r.var.shape else {"Int32": "Integer", "Boolean": "Boolean"}.get(r.var.fmi_type)
    return {"Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean"}.get(r.var.type)


#: The integrators of a Model Exchange instance the container runs (stepping/container_me.c): the master's
#: fixed-step ones, and CVODE from FMPy's SUNDIALS libraries shipped in resources/sundials/.
ME_SOLVERS = ("euler", "rk4", "cvode")
#: FMPy's SUNDIALS libraries container_me.c loads, in its order.
SUNDIALS_LIBS = ("sundials_core", "sundials_nvecserial", "sundials_sunmatrixdense", "sundials_sunlinsoldense",
                 "sundials_cvode")


def uses_cvode(plan: Plan) -> bool:
    """Whether some Model Exchange instance of the plan is integrated by CVODE."""
    return any(ip.interface == MODEL_EXCHANGE and ip.solver is not None and ip.solver.name == "cvode"
               for ip in plan.instances.values())


def sundials_folder() -> Path:
    """FMPy's SUNDIALS libraries for linux64 (the ones the master's CVODE runs)."""
    import fmpy

    return Path(fmpy.__file__).parent / "sundials" / "x86_64-linux"


def _ship_sundials(resources: Path) -> None:
    """FMPy's SUNDIALS libraries into ``resources/sundials/``, with FMPy's licence text (which holds
    SUNDIALS' notice, as its binary redistribution asks)."""
    from importlib import metadata

    dest = resources / "sundials"
    dest.mkdir(parents=True)
    for lib in SUNDIALS_LIBS:
        shutil.copyfile(sundials_folder() / f"{lib}.so", dest / f"{lib}.so")
    for f in metadata.distribution("fmpy").files or []:
        if f.name == "LICENSE.txt":
            shutil.copyfile(Path(str(f.locate())), dest / "LICENSE-FMPy.txt")
            break


def me_line(ip: InstancePlan, in_vrs: list[int], span: float) -> str:
    """The "me" line of a Model Exchange instance in system.txt (container_me.c's me_read): its integrator
    (method, whether it has a largest step, that step [s], the event tolerance [s], CVODE's relative
    tolerance), its numbers of continuous states and event indicators, whether it needs
    fmi2CompletedIntegratorStep, whether a Real input it is set each step is discrete (set in event mode
    only: the master's ``_discrete_inputs``).  CVODE's largest step and tolerance as the master's
    ``make_integrator`` resolves them (its default largest step ``span`` / 50, ``span`` = stop - start [s])."""
    sv, md = ip.solver, ip.model.md
    assert sv is not None and sv.name in ME_SOLVERS, ip   # (refused before)
    max_step, rtol = sv.max_step, 0.0
    if sv.name == "cvode":
        max_step = sv.max_step if sv.max_step is not None else (span / 50.0 if math.isfinite(span) and span > 0
                                                                else math.inf)
        rtol = sv.tolerance if sv.tolerance is not None else DEFAULT_RTOL
    wanted = set(in_vrs)
    discrete = any(v.variability == "discrete" and v.causality == "input" and int(v.valueReference) in wanted
                   and v.type in FLOAT64_TYPES for v in md.modelVariables)
    needs = not bool(getattr(md.modelExchange, "completedIntegratorStepNotNeeded", False))
    return (f"me {sv.name} {int(max_step is not None)} {_num(max_step or 0.0)} {_num(sv.event_tolerance)} "
            f"{_num(rtol)} {int(md.numberOfContinuousStates or 0)} {int(md.numberOfEventIndicators or 0)} {int(needs)} "
            f"{int(discrete)}")


_KIND = {"o": "output", "i": "input", "p": "parameter"}
_A = {"o": "a recorded output", "i": "an open input", "p": "a parameter"}


class _Slots:
    """Where each copy reads: an instance's outputs in the row (its offset), or an array of the master's wiring
    that is not the row (an override's or an event-driven input's held value, a table's values of the step),
    given slots after the row's, in the order first met."""

    def __init__(self, plan: Plan, layout: RowLayout) -> None:
        self.plan, self.layout = plan, layout
        self.n = layout.n_double
        self.extra: dict[int, tuple[int, Any]] = {}   # id(array) -> (its first slot, the array: kept alive)

    def of(self, arr: Any, i: int) -> int:
        for m in self.plan.order:
            if arr is self.layout.out_arr[m]:
                return self.layout.offset[m] + i
        if id(arr) not in self.extra:
            self.extra[id(arr)] = (self.n, arr)
            self.n += len(arr)
        return self.extra[id(arr)][0] + i

    def held(self, tables: set[int]) -> list[str]:
        """A ``put`` line of every held value now (the arrays that are not tables')."""
        return [f"put {slot} {_num(arr[0])}" for key, (slot, arr) in self.extra.items() if key not in tables]


def _copies(n: str, wiring: Wiring, slots: _Slots) -> list[str]:
    """The ``copy`` lines of instance ``n`` as the master's wiring gives its copies now."""
    return [f"copy {c.pos} {slots.of(c.src, c.slot)} {_num(c.factor)} {_num(c.offset)}" for c in wiring.copies(n)]


def _tables(plan: Plan, wiring: Wiring, slots: _Slots) -> list[str]:
    """Each instance's input table: the slots its Real columns are written to before each step (the copies
    read them there, as the master's table array), its other columns by FMI type in the master's order (one
    set per type), and one row per step."""
    lines = []
    for i, n in enumerate(plan.order):
        table = wiring.tables.get(n)
        discrete = [ip for ip in plan.inputs if ip.instance == n and not ip.var.is_float64]
        if table is None and not discrete:
            continue
        reals = table[1] if table is not None else np.zeros((plan.n_steps, 0))
        groups = [[ip for ip in discrete if ip.var.fmi_type == t] for t in sorted({ip.var.fmi_type for ip in discrete})]
        lines.append(f"table {i} {plan.n_steps} {reals.shape[1]} {len(groups)}")
        lines.append(" ".join(["tslots", *(str(slots.of(table[0], j)) for j in range(reals.shape[1]))]) if table else "tslots")
        for g in groups:
            lines.append(" ".join(["tgroup", _LETTER[g[0].var.type], str(len(g)), *(str(ip.var.vr) for ip in g)]))
        for k in range(plan.n_steps):
            row = [_num(x) for x in reals[k]]
            for g in groups:
                row += [_value(ip.var.type, ip.values[k]) for ip in g]
            lines.append(" ".join(["trow", *row]))
    return lines


def _events(plan: Plan, wiring: Wiring, slots: _Slots, tables: set[int]) -> list[str]:
    """The timed events as what they do before the step from their communication point, step by step, as
    the master's actuator does it: the values set on an FMU (a tunable parameter, an input of another type
    than Real, held as :func:`discrete_event_value` says), each instance's copies where the overrides and
    biases in force change them, the held values, and a stop."""
    index = {n: i for i, n in enumerate(plan.order)}
    before = {n: _copies(n, wiring, slots) for n in plan.order}
    held: dict[tuple[str, int], Any] = {}
    lines = []
    events = plan.events
    j = 0
    while j < len(events):
        k = events[j].step
        items: list[str] = []
        while j < len(events) and events[j].step == k:
            ev = events[j]
            j += 1
            if ev.action == "stop":
                items.append(f"stop {ev.index}")
                j = len(events)   # (the run ends: nothing after it acts)
                break
            assert ev.instance is not None and ev.var is not None
            where = index[ev.instance]
            fmi = plan.instances[ev.instance].model.fmi
            if ev.action == "set":
                items.append(f"set {where} {_param(ev.var, ev.value, fmi)}")
            elif ev.var.type == "Real":
                wiring.apply(ev)
            else:
                value = discrete_event_value(plan, held, ev)
                if value is not None:
                    items.append(f"set {where} {_param(ev.var, value, fmi)}")
        for n in plan.order:
            now = _copies(n, wiring, slots)
            if now != before[n]:
                items.append("\n".join([f"copies {index[n]} {len(now)}", *now]))   # (one item: its copies)
                before[n] = now
        items += slots.held(tables)
        lines += [f"at {k} {len(items)}", *items]
    return lines


_LETTER = {"Real": "R", "Integer": "I", "Enumeration": "I", "Boolean": "B", "String": "S"}


def _value(type_: str, value: Any) -> str:
    """A value of the type in system.txt (a Real hexadecimal, an Integer's or Boolean's decimal, a String
    hexadecimal bytes)."""
    if type_ == "Real":
        return _num(float(value))
    if type_ == "String":
        return _hex(str(value))
    return str(int(bool(value))) if type_ == "Boolean" else str(int(value))


def system_text(plan: Plan, layout: RowLayout, wiring: Wiring, cvars: list[ContainerVar],
                dirs: dict[str, str]) -> str:
    """resources/system.txt (read by container.c)."""
    index = {(v.inst, v.type, v.ref): j for j, v in enumerate(cvars) if v.kind != "o"}
    own_rates = any(plan.instances[n].decimation > 1 for n in plan.order)   # (the master's MultiRate)
    slots = _Slots(plan, layout)
    body = []
    for i, n in enumerate(plan.order):
        ip = plan.instances[n]
        copies = _copies(n, wiring, slots)
        others = [c for c in plan.connections if c.dst == n and not c.is_float64]   # (the master's order)
        me = ip.interface == MODEL_EXCHANGE
        body.append(" ".join(["inst", _hex(n), _hex(dirs[n]), _hex(ip.model.identifier_of(ip.interface)),
                              _hex(ip.model.md.guid), str(int(ip.tolerance is not None)), _num(ip.tolerance or 0.0),
                              str(len(wiring.vrs[n])), str(len(layout.reals[n])), str(layout.offset[n]),
                              str(len(copies)), str(len(ip.parameters)), str(ip.decimation), str(ip.model.fmi),
                              str(len(wiring.values[n])), str(sum(size for _, size in layout.reals[n])),
                              str(len(others)), str(int(me))]))
        body.append(" ".join(str(vr) for vr in wiring.vrs[n]) or "")
        body.append(" ".join(str(vr) for vr, _ in layout.reals[n]) or "")
        body += copies
        for var, value in ip.parameters:
            typ = _var_type(ip, var) or var.type
            body.append(f"param {_param(var, value, ip.model.fmi)} {index.get((i, typ, var.vr), -1)}")
        body += [_other(plan, o) for o in others]
        if me:
            body.append(me_line(ip, wiring.vrs[n], (plan.scenario.stop or 0.0) - (plan.scenario.start or 0.0)))
    for v in cvars:
        body.append(f"var {v.kind} {TYPES[v.type]} {v.inst} {v.ref} {_num(v.start)} "
                    f"{int(v.variability == 'tunable' or v.kind == 'i')}")
    tables = _tables(plan, wiring, slots)
    table_arrays = {id(t[0]) for t in wiring.tables.values()}
    held = slots.held(table_arrays)       # (the event-driven inputs' start values, before any event)
    events = _events(plan, wiring, slots, table_arrays)
    head = [FORMAT, f"system {len(plan.order)} {slots.n} {int(plan.scenario.algorithm == JACOBI)} 1 "
                    f"{_num(plan.scenario.step or 0.0)} {len(cvars)} {int(own_rates)}"]
    return "\n".join([*head, *body, *iteration_text(plan, layout, wiring), f"holds {len(held)}", *held,
                      f"tables {sum(ln.startswith('table ') for ln in tables)}", *tables,
                      f"events {sum(ln.startswith('at ') for ln in events)}", *events, "end"]) + "\n"


def iteration_text(plan: Plan, layout: RowLayout, wiring: Wiring) -> list[str]:
    """The iterated coupling's lines of system.txt (read by container_iter.c): ``iteration 0`` where the
    algorithm is another; else the settings (method 0 fixed point, 1 Newton; tolerance; max_iterations;
    relaxation; inputs linear 0/1; Jacobian from directional derivatives 0/1) and the components of the
    plan's graph of copies in stepping order (FeedGraph.components, as the master's Iterated steps them):
    ``comp LOOP N members...`` and, for a loop, ``unknown`` lines, one per coupling input in the master's
    order (its members in order, each one's copies in order that read an output of the loop: instance,
    input position, input value reference, the row slot it reads, the instance and value reference of that
    output, factor, offset)."""
    sc = plan.scenario
    if sc.algorithm != ITERATED:
        return ["iteration 0"]
    spec = sc.iteration or IterationSpec()
    graph = plan.feeds
    lines = [f"iteration 1 {int(spec.method == 'newton')} {_num(spec.tolerance)} {spec.max_iterations} "
             f"{_num(spec.relaxation)} {int(spec.inputs == 'linear')} {int(spec.jacobian == 'directional')} "
             f"{len(graph.components)}"]
    for comp in graph.components:
        loop = graph.is_loop(comp)
        unknowns = []
        if loop:
            mine = {plan.order[i] for i in comp}
            for i in comp:
                n = plan.order[i]
                for c in wiring.copies(n):
                    src = next((m for m in plan.order if c.src is layout.out_arr[m]), None)
                    if src is None or src not in mine:
                        continue
                    unknowns.append(f"unknown {i} {c.pos} {wiring.vrs[n][c.pos]} {layout.offset[src] + c.slot} "
                                    f"{plan.order.index(src)} {layout.reals[src][c.slot][0]} {_num(c.factor)} "
                                    f"{_num(c.offset)}")
        lines.append(f"comp {int(loop)} {len(comp)} {' '.join(map(str, comp))} {len(unknowns)}")
        lines += unknowns
    return lines


def _param(var: Any, value: Any, fmi: int = 2) -> str:
    """A parameter or start value as container.c sets it: R, I, B, S through the FMI 2.0 setters (of an FMI
    3.0 FMU: fmi3SetFloat64, Int32, Boolean, String); T (FMI 3.0, another type or an array) through
    fmi3Set<TYPE> with the values as FMPy gives them (an Enumeration as Int64)."""
    if fmi == 3 and (var.shape or var.fmi_type not in FMI3_SCALARS):
        values = list(value) if isinstance(value, (list, tuple)) else [value]
        if var.type == "Real":
            text = [_num(float(v)) for v in values]
        else:
            text = [str(int(bool(v))) if var.type == "Boolean" else str(int(v)) for v in values]
        call_type = "Int64" if var.fmi_type == "Enumeration" else var.fmi_type
        return f"T {var.vr} {call_type} {len(values)} {' '.join(text)}"
    if var.type == "Real":
        return f"R {var.vr} {_num(float(value))}"
    if var.type == "String":
        return f"S {var.vr} {_hex(str(value))}"
    if var.type == "Boolean":
        return f"B {var.vr} {int(bool(value))}"
    return f"I {var.vr} {int(value)}"


def _other(plan: Plan, c: Any) -> str:
    """A connection that is not Float64 to Float64, as the master's copier makes it
    (:func:`.wiring.discrete_copier`): the output's values (all of an array's) got and set with the FMI
    functions of their types, converted as it converts them: c the same C type (as they are), r real to real
    (float(x) * factor + offset), b Boolean to Real ((1.0 if x else 0.0) * factor + offset), t Real to
    Boolean (x > threshold), i the others (integers, enumerations and booleans, to the input's C type)."""
    index = {n: i for i, n in enumerate(plan.order)}
    sf, df = plan.instances[c.src].model.fmi, plan.instances[c.dst].model.fmi
    gt, gname = ACCESS[sf][c.src_var.fmi_type]
    pt, pname = ACCESS[df][c.dst_var.fmi_type]
    sk, dk = c.src_var.type, c.dst_var.type
    if sk == dk and sk != "Real" and gt is pt:
        mode = "c"
    elif dk == "Real":
        mode = "r" if sk == "Real" else "b"
    else:
        mode = "t" if dk == "Boolean" and sk == "Real" else "i"
    return (f"other {index[c.src]} {sf} {gname} {c.src_var.vr} {pname} {c.dst_var.vr} {c.src_var.size} {mode} "
            f"{_num(c.factor)} {_num(c.offset)} {_num(c.spec.threshold)}")


def _attributes(j: int, v: ContainerVar) -> str:
    """The attributes of the container's variable ``v`` (its value reference ``j + 1``) common to its FMI 2.0
    and 3.0 descriptions: name, value reference, causality, variability, initial."""
    initial = ' initial="exact"' if v.kind == "p" else ' initial="calculated"' if v.kind == "o" else ""
    return (f'name={quoteattr(v.name)} valueReference="{j + 1}" causality="{_KIND[v.kind]}" '
            f'variability="{v.variability}"{initial}')


def _typed(v: ContainerVar) -> str:
    """The attributes of a variable's type element: a Real's unit, the start value of an input or parameter."""
    unit = f' unit={quoteattr(v.unit)}' if v.unit and v.type == "Real" else ""
    if v.kind == "o":
        return unit
    start = repr(v.start) if v.type == "Real" else str(int(v.start)) if v.type == "Integer" else \
        ("true" if v.start else "false")
    return f'{unit} start="{start}"'


def model_description(plan: Plan, name: str, guid: str, cvars: list[ContainerVar]) -> str:
    """The container's modelDescription.xml (FMI 2.0 co-simulation)."""
    sc = plan.scenario
    rows = []
    for j, v in enumerate(cvars):
        rows.append(f'    <ScalarVariable {_attributes(j, v)} description={quoteattr(v.description)}><{v.type}{_typed(v)}/>'
                    "</ScalarVariable>")
    outs = "".join(f'<Unknown index="{j + 1}"/>' for j, v in enumerate(cvars) if v.kind == "o")
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(name)} '
            f'guid="{guid}" generationTool="wmr-cosim export-fmu" variableNamingConvention="flat" '
            f'numberOfEventIndicators="0"\n  description={quoteattr(f"the system of {Path(sc.file).name} as one FMU")}>\n'
            f'  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="false" '
            'canNotUseMemoryManagementFunctions="true"/>\n' + _shared_elements(plan, cvars, set()) +
            "  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            f"  <ModelStructure><Outputs>{outs}</Outputs><InitialUnknowns>{outs}</InitialUnknowns></ModelStructure>\n"
            "</fmiModelDescription>\n")


def _shared_elements(plan: Plan, cvars: list[ContainerVar], units: set[str]) -> str:
    """The elements both descriptions hold between CoSimulation and ModelVariables: the units (of the Real
    variables, and ``units``), the log categories, the default experiment (the scenario's start, stop, step)."""
    sc = plan.scenario
    names = sorted(units | {v.unit for v in cvars if v.unit and v.type == "Real"})
    unit_defs = ("  <UnitDefinitions>" + "".join(f"<Unit name={quoteattr(u)}/>" for u in names) +
                 "</UnitDefinitions>\n") if names else ""
    return (unit_defs + '  <LogCategories><Category name="logEvents"/><Category name="logStatusError"/></LogCategories>\n'
            f'  <DefaultExperiment startTime="{sc.start!r}" stopTime="{sc.stop!r}" stepSize="{sc.step!r}"/>\n')


#: The platforms a container is built for: linux64 always, win64 where it can be (:func:`platforms`).
PLATFORMS = ("linux64", "win64")
_LIB = {"linux64": "so", "win64": "dll"}


def platforms(plan: Plan, asked: list[str] | None = None, fmi: int = 2) -> tuple[list[str], str | None]:
    """The platforms to build the container for, and a note saying why win64 is not among them (None where it
    is, or where ``asked`` leaves it out).  ``asked`` None: linux64, and win64 where MinGW-w64 is on PATH and
    every inner FMU has a win64 binary; else those named, refused (one line) where one cannot be built.  The
    FMI 3.0 face (``fmi`` 3) is built for Linux only, so far."""
    want = list(PLATFORMS) if asked is None else asked
    for p in want:
        if p not in PLATFORMS:
            raise ScenarioError(plan.scenario.file, "--platforms", f"{p!r}: the platforms are {', '.join(PLATFORMS)}")
    if "linux64" not in want:
        raise ScenarioError(plan.scenario.file, "--platforms", "linux64 is always built (the export runs on Linux)")
    if "win64" not in want:
        return ["linux64"], None
    why = "the FMI 3.0 face is built for x86_64-linux only, so far" if fmi == 3 else None
    if why is None and uses_cvode(plan):
        why = "CVODE inside (FMPy's SUNDIALS libraries) is shipped for linux64 only, so far"
    for n in plan.order if why is None else ():
        ip = plan.instances[n]
        binary = f"binaries/{PLATFORM_FOLDERS[ip.model.fmi]['win64']}/{ip.model.identifier_of(ip.interface)}.dll"
        with zipfile.ZipFile(ip.model.path) as zf:
            if binary not in zf.namelist():
                why = f"instances.{n}: {ip.model.path.name} has no {binary}"
                break
    if why is None and shutil.which(native.MINGW_CC) is None:
        why = f"no {native.MINGW_CC} on PATH (Debian: gcc-mingw-w64-x86-64)"
    if why is None:
        return ["linux64", "win64"], None
    if asked is not None:
        raise ScenarioError(plan.scenario.file, "--platforms", f"win64 cannot be built: {why}")
    return ["linux64"], f"linux64 only, no win64 binary: {why}"


def model_description3(plan: Plan, name: str, token: str, cvars: list[ContainerVar]) -> str:
    """The container's modelDescription.xml as FMI 3.0 co-simulation (its variables Float64, Int32 and Boolean,
    with the value references of the FMI 2.0 description, and time, the independent variable, at value
    reference 0; ``token`` its instantiation token)."""
    sc = plan.scenario
    rows = [('    <Float64 name="time" valueReference="0" causality="independent" variability="continuous" unit="s" '
             'description="the time of the system"/>')]
    for j, v in enumerate(cvars):
        rows.append(f"    <{TYPES3[v.type]} {_attributes(j, v)} description={quoteattr(v.description)}{_typed(v)}/>")
    outs = [j + 1 for j, v in enumerate(cvars) if v.kind == "o"]
    structure = "".join(f'<Output valueReference="{r}"/>' for r in outs) + \
        "".join(f'<InitialUnknown valueReference="{r}"/>' for r in outs)
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="3.0" modelName={quoteattr(name)} '
            f'instantiationToken="{token}" generationTool="wmr-cosim export-fmu" variableNamingConvention="flat"\n'
            f'  description={quoteattr(f"the system of {Path(sc.file).name} as one FMU")}>\n'
            f'  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="false" '
            f'fixedInternalStepSize="{sc.step!r}"/>\n' + _shared_elements(plan, cvars, {"s"}) +
            "  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            f"  <ModelStructure>{structure}</ModelStructure>\n"
            "</fmiModelDescription>\n")


def build_binary(guid: str, dest: Path, platform: str = "linux64", fmi: int = 2) -> None:
    """container.c (with native_loop.c; for ``fmi`` 3, container3.c around it) compiled with the compiled
    loop's flags into ``dest``: for linux64 by the system's C compiler (``CC``, else cc), for win64 by
    MinGW-w64."""
    cc = (os.environ.get("CC") or "cc") if platform == "linux64" else native.MINGW_CC
    path = shutil.which(cc)
    if path is None:
        raise CosimError(f"export-fmu needs a C compiler: no {cc} on PATH")
    source = SOURCE3 if fmi == 3 else SOURCE
    includes = [f"-I{native.fmi_headers(3)}"] if fmi == 3 else []
    flags = native.FLAGS if platform == "linux64" else [f for f in native.FLAGS if f != "-fPIC"]
    libs = ["-ldl", "-lm"] if platform == "linux64" else native.WIN64_LDFLAGS.split()
    p = subprocess.run([path, *flags, *includes, f'-DCONTAINER_GUID="{guid}"', str(source), "-o", str(dest), *libs],
                       capture_output=True, text=True, timeout=300, check=False)
    if p.returncode:
        raise CosimError(f"the C compiler {path} failed on {source.name}: {p.stderr.strip()[:300]}")


def export_fmu(plan: Plan, out: str | os.PathLike, name: str | None = None, fmi: int = 2, *,
               platforms_asked: list[str] | None = None, notes: list[str] | None = None) -> Path:
    """Write the resolved ``plan`` as one co-simulation FMU ``out`` (see the module); returns its path.
    ``name``: its model name and identifier (default: the scenario file's stem, as a C name); ``fmi``: the
    FMI version of its interface, 2 or 3 (whatever its inner FMUs' versions); ``platforms_asked``: the platforms to
    build (default: each that can be, :func:`platforms`); ``notes``: a list the note on a platform not built
    is appended to."""
    if fmi not in PLATFORM_FOLDERS:
        raise CosimError(f"export-fmu writes an FMI 2.0 or 3.0 FMU, not FMI {fmi!r}")
    out = Path(out)
    if name is None:
        name = re.sub(r"\W", "_", Path(plan.scenario.file).stem) or "system"
        name = "_" + name if name[0].isdigit() else name
    refuse(plan, out, name)
    built, note = platforms(plan, platforms_asked, fmi)
    if note is not None and notes is not None:
        notes.append(note)
    layout = RowLayout.of(plan)
    wiring = Wiring(plan, layout)
    cvars = variables(plan, layout)
    tmp = Path(tempfile.mkdtemp(prefix="wmr-cosim-fmu-"))
    try:
        dirs = _unpack(plan, tmp / "resources")
        if uses_cvode(plan):
            _ship_sundials(tmp / "resources")
        text = system_text(plan, layout, wiring, cvars, dirs)
        guid = "{" + str(uuid.UUID(hashlib.sha256((text + name).encode()).hexdigest()[:32])) + "}"
        (tmp / "resources" / "system.txt").write_text(text)
        describe = model_description3 if fmi == 3 else model_description
        (tmp / "modelDescription.xml").write_text(describe(plan, name, guid, cvars))
        for platform in built:
            folder = tmp / "binaries" / PLATFORM_FOLDERS[fmi][platform]
            folder.mkdir(parents=True)
            build_binary(guid, folder / f"{name}.{_LIB[platform]}", platform, fmi)
        (tmp / "sources").mkdir()   # (for fmi 3, the FMI 3.0 face and the standard's headers beside it)
        for src in (SOURCE, native.SOURCE, *INCLUDED, *((SOURCE3, *(native.fmi_headers(3) / h for h in HEADERS3)) if fmi == 3 else ())):
            shutil.copyfile(src, tmp / "sources" / src.name)
        out.parent.mkdir(parents=True, exist_ok=True)
        part = out.with_name(out.name + ".part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
            for f in sorted(tmp.rglob("*")):
                if f.is_file():
                    zf.write(f, f.relative_to(tmp).as_posix())
        part.replace(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _unpack(plan: Plan, resources: Path) -> dict[str, str]:
    """Each FMU unpacked once under ``resources/fmuN``; instance -> its folder's name."""
    folders: dict[Path, str] = {}
    dirs = {}
    for n, ip in plan.instances.items():
        p = ip.model.path.resolve()
        if p not in folders:
            folders[p] = f"fmu{len(folders)}"
            safe_extract(p, resources / folders[p], plan.archive_limits)
        dirs[n] = folders[p]
    return dirs
