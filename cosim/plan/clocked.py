"""The checks of the FMI 3.0 co-simulation instances with clocks (run with event mode:
:mod:`..instances.clocked`) and of the connections between clocks, each refusal one line (ScenarioError).

A connection whose ends are clocks links an output clock to an input clock (:class:`.records.ClockLink`,
the same ``from``/``to`` syntax as variables).  What the master runs exactly, and so what is checked here:

- the instance runs as co-simulation and its FMU declares ``hasEventMode``, in the master's process, at
  the experiment's step, under the default algorithm (Gauss-Seidel: the instances step in the plan's order
  and an instance's events at a communication point, at the end of its step that ends there, come after
  those of the instances before it);
- each periodic input clock (constant, fixed, tunable) declares its interval (and shift) as a whole number
  of steps; each triggered input clock has a source: an output clock connected to it, or ``clock_ticks``
  at times on the grid; countdown and changing clocks are refused;
- an output clock connected to an input clock, and a clocked output connected to a clocked input, step
  before them in the plan's order (``experiment.order``);
  a clock connected to a variable, or a variable to a clock, is refused;
- notes: an output clock that feeds nothing; a clocked output connected to an input that is not clocked
  (its value is defined at its clock's ticks only: the input holds the value of the last tick).
"""
from __future__ import annotations

from fractions import Fraction
from typing import Any

from ..messages.errors import ScenarioError
from ..model.clocks import Clock, grid_multiple
from ..model.description import CO_SIMULATION, SCHEDULED_EXECUTION
from ..scenario.document import Scenario, split_ref
from ..scenario.inputs import InputPlan
from ..stepping import table as algorithms
from .records import ClockLink, ConnectionPlan, EventPlan, InstancePlan, RecordPlan, RequirementPlan


def _clock(insts: dict[str, InstancePlan], inst: str, name: str) -> Clock | None:
    ip = insts.get(inst)
    if ip is None:
        return None
    return next((c for c in ip.model.clocks if c.name == name), None)


def clock_links(sc: Scenario, insts: dict[str, InstancePlan]) -> list[ClockLink]:
    """The connections whose ends are clocks, checked: an output clock to an input clock; a clock to a
    variable or a variable to a clock is a ScenarioError."""
    links = []
    for c in sc.connections:
        fld = f"connections[{c.index}]"
        si, sv = split_ref(sc.file, f"{fld}.from", c.src)
        di, dv = split_ref(sc.file, f"{fld}.to", c.dst)
        sc_, dc = _clock(insts, si, sv), _clock(insts, di, dv)
        if sc_ is None and dc is None:
            continue
        if sc_ is not None and sc_.causality != "output":
            raise ScenarioError(sc.file, f"{fld}.from", f"{c.src} is an input clock, not an output clock")
        if dc is not None and dc.causality != "input":
            raise ScenarioError(sc.file, f"{fld}.to", f"{c.dst} is an output clock, not an input clock")
        if dc is None:
            raise ScenarioError(sc.file, fld, f"{c.src} -> {c.dst}: an output clock connects to an input clock "
                                              f"only ({c.dst} is not a clock)")
        if sc_ is None:
            raise ScenarioError(sc.file, fld, f"{c.src} -> {c.dst}: an input clock is ticked by an output clock "
                                              f"only ({c.src} is not a clock)")
        if dc.variability != "triggered":
            raise ScenarioError(sc.file, f"{fld}.to", f"{c.dst} is a {dc.variability} clock: an output clock "
                                                      "ticks a triggered input clock only")
        if c.factor != 1.0 or c.offset != 0.0 or c.convert:
            raise ScenarioError(sc.file, fld, f"{c.src} -> {c.dst}: a connection between clocks takes no "
                                              "factor, offset, convert or threshold")
        links.append(ClockLink(si, sv, di, dv, c.index))
    return links


def check_clocked(sc: Scenario, insts: dict[str, InstancePlan], conns: list[ConnectionPlan],
                  links: list[ClockLink], notes: list[str]) -> None:
    """The instances with clocks that are not scheduled execution, and the connections of clocks and
    clocked variables (see the module's docstring)."""
    _links(sc, insts, links)
    linked_in = {(lk.dst, lk.dst_clock) for lk in links}
    linked_out = {(lk.src, lk.src_clock) for lk in links}
    for name, ip in insts.items():
        if ip.interface == SCHEDULED_EXECUTION or not ip.model.clocks:
            if ip.spec.clock_ticks and ip.interface != SCHEDULED_EXECUTION:
                raise ScenarioError(sc.file, f"instances.{name}.clock_ticks", "ticks are for the input clocks of "
                                                                              "an FMU that has clocks")
            continue
        _instance(sc, name, ip)
        for c in ip.model.clocks:
            if c.causality == "output" and (name, c.name) not in linked_out:
                notes.append(f"{name}: output clock {c.name} is raised by the FMU and feeds nothing")
            elif c.causality == "input":
                _input_clock(sc, name, ip, c, (name, c.name) in linked_in)
    for cp in conns:
        s_clock = clock_of(insts[cp.src], cp.src_var.name)
        d_clock = clock_of(insts[cp.dst], cp.dst_var.name)
        if s_clock is not None and d_clock is None:
            notes.append(f"{cp.src}.{cp.src_var.name} -> {cp.dst}.{cp.dst_var.name}: the output is clocked by "
                         f"{s_clock}, defined at its ticks only; the input holds the value of the last tick")
        if s_clock is not None and d_clock is not None and sc.order.index(cp.src) > sc.order.index(cp.dst):
            raise ScenarioError(sc.file, "experiment.order", f"{cp.src}.{cp.src_var.name} -> "
                                f"{cp.dst}.{cp.dst_var.name}: {cp.src} must step before {cp.dst} (a clocked value reaches the clocked partitions "
                                "of the instances after it at the same instant)")
        for end, var, clock in ((cp.src, cp.src_var, s_clock), (cp.dst, cp.dst_var, d_clock)):
            if clock is not None and not cp.src_var.is_float64:
                raise ScenarioError(sc.file, f"connections[{cp.spec.index}]", f"{end}.{var.name}: clocked "
                                    f"{cp.src_var.fmi_type} variables are not exchanged yet (Float64 ones are)")


def _links(sc: Scenario, insts: dict[str, InstancePlan], links: list[ClockLink]) -> None:
    """Each connection between clocks: not of a scheduled execution instance, its output clock's instance
    stepping first (each clock's connections noted for ``check``)."""
    order = {n: i for i, n in enumerate(sc.order)}
    for lk in links:
        for end in (lk.src, lk.dst):
            if insts[end].interface == SCHEDULED_EXECUTION:
                raise ScenarioError(sc.file, f"connections[{lk.index}]", f"{lk}: clocks of a scheduled execution "
                                                                         "instance are not connected yet")
        insts[lk.src].clock_words.setdefault(lk.src_clock, []).append(f"ticks {lk.dst}.{lk.dst_clock}")
        insts[lk.dst].clock_words.setdefault(lk.dst_clock, []).append(f"ticked by {lk.src}.{lk.src_clock}")
        if order[lk.src] > order[lk.dst]:
            raise ScenarioError(sc.file, "experiment.order", f"{lk}: {lk.src} must step before {lk.dst} (an output "
                                                             "clock ticks the input clocks of the instances after it)")


def _instance(sc: Scenario, name: str, ip: InstancePlan) -> None:
    """An instance with clocks: event mode in co-simulation, the default algorithm, one worker, in this
    process, at the experiment's step; ``clock_ticks`` for its triggered input clocks only."""
    fld, file = f"instances.{name}", ip.model.path.name
    if ip.interface == CO_SIMULATION and not ip.model.has_event_mode:
        raise ScenarioError(sc.file, f"{fld}.fmu", f"{file} has clocks but its co-simulation interface does not "
                                                   "declare hasEventMode (the master ticks clocks in event mode)")
    if sc.algorithm != algorithms.DEFAULT:
        raise ScenarioError(sc.file, "experiment.algorithm", f"{sc.algorithm}: an instance with clocks ({name}) "
                            f"runs under {algorithms.DEFAULT} only (its events follow the plan's order)")
    if sc.workers > 1:
        raise ScenarioError(sc.file, "experiment.workers", f"{sc.workers}: an instance with clocks ({name}) "
                                                           "steps in the plan's order, one instance at a time")
    if sc.event_rows:
        raise ScenarioError(sc.file, "record.event_rows", f"rows at the events are not recorded for an instance "
                                                          f"with clocks ({name})")
    for key in ("isolate", "step"):
        if getattr(ip.spec, key):
            raise ScenarioError(sc.file, f"{fld}.{key}", "not supported for an instance with clocks (its events "
                                                         "run in the master's process, at every communication point)")
    ticks_named(sc, name, ip)


def ticks_named(sc: Scenario, name: str, ip: InstancePlan) -> None:
    """Each clock ``clock_ticks`` of instance ``name`` names is a triggered input clock of its FMU, else
    ScenarioError (one line)."""
    by_name = {c.name: c for c in ip.model.clocks}
    for cname in ip.spec.clock_ticks:
        c = by_name.get(cname)
        if c is None or c.causality != "input" or c.variability != "triggered":
            raise ScenarioError(sc.file, f"instances.{name}.clock_ticks.{cname}", f"{ip.model.path.name} has no "
                                                                                 f"triggered input clock {cname!r}")


def periodic_on_grid(sc: Scenario, name: str, c: Clock) -> None:
    """A periodic input clock of instance ``name``: its intervalDecimal (and shiftDecimal) [s] declared and
    a whole number of the scenario's steps, else ScenarioError (one line)."""
    step = sc.times()[2]
    if c.interval is None:
        raise ScenarioError(sc.file, f"instances.{name}.fmu", f"clock {c.name}: a {c.variability} clock with "
                            "no intervalDecimal is not supported yet (its interval is known only at run time)")
    if c.grid(step) is None:
        raise ScenarioError(sc.file, "experiment.step", f"{step:g} s: clock {name}.{c.name} ticks every "
                            f"{c.interval} s" + (f" from {c.shift} s" if c.shift else "") +
                            ", not a whole number of steps")


def triggered_on_grid(sc: Scenario, name: str, ip: InstancePlan, c: Clock, linked: bool | None) -> None:
    """A triggered input clock of instance ``name``: a source (``linked``: an output clock connected to it;
    None where no clock can be connected to it, as in scheduled execution) or ``clock_ticks``, each time [s]
    on the grid from the start; else ScenarioError (one line)."""
    start, _, step = sc.times()
    fld = f"instances.{name}"
    times = ip.spec.clock_ticks.get(c.name)
    if not times and not linked:
        how = "give its times" if linked is None else "connect an output clock to it, or give its times"
        raise ScenarioError(sc.file, f"{fld}.clock_ticks", f"triggered input clock {c.name} has no source: {how}, "
                            f"clock_ticks = {{ {c.name} = [...] }}")
    for t in times or ():
        if t < start or grid_multiple(Fraction(repr(t)) - Fraction(repr(start)), step) is None:
            raise ScenarioError(sc.file, f"{fld}.clock_ticks.{c.name}", f"{t:g} s is not on the grid "
                                                                       f"of {step:g} s steps from {start:g} s")


def _input_clock(sc: Scenario, name: str, ip: InstancePlan, c: Clock, linked: bool) -> None:
    """One input clock: periodic with its interval (and shift) a whole number of steps, or triggered with a
    source (``linked``: an output clock connected to it; or ``clock_ticks`` on the grid)."""
    fld = f"instances.{name}"
    if c.periodic:
        periodic_on_grid(sc, name, c)
    elif c.variability == "triggered":
        triggered_on_grid(sc, name, ip, c, linked)
    else:
        raise ScenarioError(sc.file, f"{fld}.fmu", f"clock {c.name}: a {c.variability} input clock is not "
                            "supported in co-simulation and model exchange yet (the master ticks periodic and "
                            "triggered clocks)")


def clock_of(ip: InstancePlan, var: str) -> str | None:
    """The clock that clocks variable ``var`` of an instance (None: it is not clocked)."""
    return next((c.name for c in ip.model.clocks if var in c.clocked), None)


def check_clocked_reads(sc: Scenario, insts: dict[str, InstancePlan], record: list[RecordPlan],
                        inputs: list[InputPlan], events: list[EventPlan],
                        requirements: list[RequirementPlan]) -> None:
    """What reads or sets a clocked variable of an instance with clocks in co-simulation between its
    ticks, ScenarioError in one line: an event on it (a clocked input is set at its clock's ticks only), a
    tabulated input of it that is not Float64 (a Float64 one is held for the tick), a record or requirement
    of a clocked output that is not Float64 (a Float64 one reads the value of its last tick, which the
    master keeps)."""
    def clocked(inst: str | None, var: Any) -> str | None:
        if inst is None or var is None:
            return None
        ip = insts[inst]
        if ip.interface == SCHEDULED_EXECUTION:
            return None
        return clock_of(ip, var.name)

    for ev in events:
        if clocked(ev.instance, ev.var):
            raise ScenarioError(sc.file, f"events[{ev.index}].variable", f"{ev.ref}: clocked by "
                                f"{clocked(ev.instance, ev.var)}, set at its ticks only: events on it are not supported")
    for col in inputs:
        if clocked(col.instance, col.var) and not col.var.is_float64:
            raise ScenarioError(sc.file, "inputs", f"{col.column}: a clocked {col.var.fmi_type} input takes no table "
                                                   "yet (Float64 ones do)")
    reads = [("record", r.instance, r.var, sc.decimation) for r in record]
    reads += [(f"requirements[{q.index}]", i, v, 1) for q in requirements for i, v in q.reads.values()]
    for fld, inst, var, every in reads:
        clock = clocked(inst, var)
        if clock and not var.is_float64 and not ticks_at_every(sc, insts[inst], clock, every):
            raise ScenarioError(sc.file, fld, f"{inst}.{var.name}: a clocked {var.fmi_type} output is defined at its "
                                              f"clock's ticks only and cannot be read between them yet: {clock} does "
                                              f"not tick at every {'recorded ' if fld == 'record' else ''}communication "
                                              "point (Float64 ones keep the value of their last tick)")


def ticks_at_every(sc: Scenario, ip: InstancePlan, clock: str, every: int) -> bool:
    """Whether the periodic input clock ``clock`` of an instance ticks at every ``every``-th communication
    point from the start time and at the stop time: what a clocked output of a type other than Float64 needs
    to be read there (the master reads it at its ticks and holds it to the next communication point)."""
    c = next(k for k in ip.model.clocks if k.name == clock)
    if not (c.periodic and c.causality == "input" and c.interval is not None and Fraction(c.shift or "0") == 0):
        return False
    start, stop, step = sc.times()
    k, n = grid_multiple(c.interval, step), grid_multiple(Fraction(repr(stop)) - Fraction(repr(start)), step)
    return k is not None and k > 0 and every % k == 0 and n is not None and n % k == 0
