"""The plan's records: a scenario resolved against its FMUs (:class:`Plan`), its instances, connections,
recorded variables and events as the checks left them, and its coupling structure; what the run reads."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..instances.integrators import DEFAULT_RTOL, SolverSpec
from ..model.archive import DEFAULT_LIMITS, ArchiveLimits
from ..model.description import CO_SIMULATION, INTERFACE_NAMES, FmuModel, Variable
from ..model.units import lookup, units_of
from ..scenario.document import ConnectionSpec, InstanceSpec, Scenario
from ..scenario.inputs import InputPlan
from ..stepping.graph import FeedGraph


@dataclass
class Coupling:
    """The coupling loops (instance names, in the plan's order) and the algebraic loops (each a cycle of
    "instance.variable", outputs and inputs alternating, its first element repeated at its end)."""

    loops: list[list[str]] = field(default_factory=list)
    algebraic: list[list[str]] = field(default_factory=list)

    def loop_of(self, name: str) -> list[str] | None:
        return next((lp for lp in self.loops if name in lp), None)


@dataclass
class InstancePlan:
    """One instance, its FMU, and the name map between the scenario's names and the FMU's."""

    name: str
    spec: InstanceSpec
    model: FmuModel
    ours_to_theirs: dict[str, str] = field(default_factory=dict)
    theirs_to_ours: dict[str, str] = field(default_factory=dict)
    parameters: list[tuple[Variable, Any]] = field(default_factory=list)
    tolerance: float | None = None   # what its set-up gets: the instance's, else the experiment's, else the FMU's own
    interface: str = CO_SIMULATION    # the FMU's interface the run uses ("co-simulation" | "model-exchange")
    solver: SolverSpec | None = None  # model exchange: the master's integrator of it (None for co-simulation)
    decimation: int = 1               # it steps every this many of the experiment's steps (its own ``step``)
    clock_words: dict[str, list[str]] = field(default_factory=dict)   # clock -> its connections ("ticks X.c")

    def our_name(self, var: Variable) -> str:
        return self.theirs_to_ours.get(var.name, var.name)

    def describe(self) -> str:
        """How it runs, in words (``check`` prints it): "co-simulation", or "model exchange, cvode, rtol
        1e-05" with the integrator's settings (largest step [s]; Euler's and RK4's event tolerance [s]);
        then its own rate where it has one ("steps of 0.008 s, every 4 base steps")."""
        text = self._interface_words()
        if self.decimation > 1:
            text += f"; steps of {self.spec.step:g} s, every {self.decimation} base steps"
        for c in self.model.clocks:   # (scheduled execution: each clock on a line of its own)
            ticks = self.spec.clock_ticks.get(c.name)
            text += f"\n    {c.describe()}" + (f"; ticked at {', '.join(f'{t:g}' for t in ticks)} s" if ticks else "")
            text += "".join(f"; {w}" for w in self.clock_words.get(c.name, ()))
        return text

    def _interface_words(self) -> str:
        if self.solver is None:
            if self.model.clocks and self.interface == CO_SIMULATION:
                return f"{INTERFACE_NAMES[self.interface]} with event mode"
            return INTERFACE_NAMES[self.interface]
        sv = self.solver
        parts = [INTERFACE_NAMES[self.interface], sv.name]
        if sv.name == "cvode":
            parts.append(f"rtol {sv.tolerance if sv.tolerance is not None else DEFAULT_RTOL:g}")
        if sv.max_step is not None:
            parts.append(f"max step {sv.max_step:g} s")
        elif sv.name != "cvode":
            parts.append("one step per communication step")
        if sv.name != "cvode":
            parts.append(f"events located to {sv.event_tolerance:g} s")
        return ", ".join(parts)


@dataclass
class ConnectionPlan:
    """output -> input, value_in = factor * value_out + offset (unit conversion folded in)."""

    src: str
    src_var: Variable
    dst: str
    dst_var: Variable
    factor: float
    offset: float
    spec: ConnectionSpec
    src_elem: int | None = None   # one element of an FMI 3.0 array output (row-major), None for all

    @property
    def is_float64(self) -> bool:
        """Float64 -> Float64 (a copy in the generated loop; the others are copied by closures)."""
        return self.src_var.is_float64 and self.dst_var.is_float64


@dataclass(frozen=True)
class ClockLink:
    """An output clock -> an input clock (a connection between clocks): ``dst_clock`` of instance ``dst``
    ticks when ``src`` raises ``src_clock``."""

    src: str
    src_clock: str
    dst: str
    dst_clock: str
    index: int          # the connection's index in the scenario (``connections[i]``)

    def __str__(self) -> str:
        return f"{self.src}.{self.src_clock} -> {self.dst}.{self.dst_clock}"


@dataclass
class RecordPlan:
    instance: str
    var: Variable
    column: str
    elem: int = 0      # the element of an FMI 3.0 array (row-major), 0 for a scalar


@dataclass
class EventPlan:
    """A checked event.  A timed one acts before the step starting at t = start + step * h; a condition
    event (``condition`` not None) acts ``delay`` [s] after its condition becomes true (``step`` unused).
    A stop has no variable (``instance``, ``var`` and ``ref`` are None)."""

    time: float | None
    step: int
    instance: str | None
    var: Variable | None
    action: str
    value: Any
    ref: str | None
    index: int = 0                       # its place in the scenario's [[events]]
    when: str | None = None
    condition: Any = None                # the syntax tree (cosim.scenario.condition)
    trigger: str = "once"
    delay: float = 0.0
    reads: dict[str, tuple[str, Variable]] = field(default_factory=dict)  # condition name -> (instance, var)


@dataclass
class RequirementPlan:
    """A checked requirement: the scenario's (name, formula, what a violation does, description), the
    formula as checked against its variables (``checked``: :class:`cosim.requirements.formula.Checked`)
    and what it reads (its name -> (instance, variable))."""

    name: str
    formula: str
    on_violation: str
    description: str
    index: int
    checked: Any
    reads: dict[str, tuple[str, Variable]] = field(default_factory=dict)


@dataclass
class Plan:
    scenario: Scenario
    instances: dict[str, InstancePlan]
    connections: list[ConnectionPlan]
    record: list[RecordPlan]
    events: list[EventPlan]
    n_steps: int
    inputs: list[InputPlan] = field(default_factory=list)
    not_recorded: list[str] = field(default_factory=list)   # String outputs a pattern matched
    conditions: list[EventPlan] = field(default_factory=list)  # events on conditions, evaluated between steps
    notes: list[str] = field(default_factory=list)   # what check prints beside its verdict (declared units overridden)
    internal_steps: dict[str, int] = field(default_factory=dict)   # instance -> its fixed internal steps over the run
    archive_limits: ArchiveLimits = DEFAULT_LIMITS   # the scenario's: what extracting its FMUs may unpack
    coupling: Coupling = field(default_factory=Coupling)   # its coupling loops and algebraic loops
    last_step: float | None = None   # [s] a short last step, where the step does not divide the run
    requirements: list[RequirementPlan] = field(default_factory=list)   # monitored at every communication point
    run_notes: list[str] = field(default_factory=list)   # what run says too before it starts (workers left idle)
    feeds: FeedGraph = field(default_factory=FeedGraph)   # who feeds whom: the coupling loops', the levels', the run's
    clock_links: list[ClockLink] = field(default_factory=list)   # output clocks -> input clocks

    @property
    def watched(self) -> list[tuple[str, Variable]]:
        """The variables the conditions and the requirements read (the Float64 outputs among them are kept
        in the row buffer)."""
        out: list[tuple[str, Variable]] = []
        for reads in [ev.reads for ev in self.conditions] + [r.reads for r in self.requirements]:
            for pair in reads.values():
                if pair not in out:
                    out.append(pair)
        return out

    @property
    def output_bytes(self) -> int:
        """The expected size of signals.npy (the CSV, when written, is about three times larger)."""
        rows = self.n_steps // self.scenario.decimation + 2
        return rows * 8 * (1 + len(self.record))

    @property
    def order(self) -> list[str]:
        return self.scenario.order

    def unconnected_inputs(self) -> list[tuple[str, Any, list[int]]]:
        """The inputs of the system that neither a connection nor the input table drives, each as
        ("instance.variable" in the scenario's names, the value it keeps: the start value the scenario sets,
        else the model description's; the indices of the [[events]] that act on it), in the order of the
        instances and their variables."""
        driven = {(c.dst, c.dst_var.name) for c in self.connections}
        driven |= {(ip.instance, ip.var.name) for ip in self.inputs}
        out: list[tuple[str, Any, list[int]]] = []
        for name, ip in self.instances.items():
            set_here = {var.name: value for var, value in ip.parameters}
            for var in ip.model.variables.values():
                if var.causality == "input" and (name, var.name) not in driven:
                    events = sorted(ev.index for ev in [*self.events, *self.conditions]
                                    if ev.instance == name and ev.var is not None and ev.var.name == var.name)
                    out.append((f"{name}.{ip.our_name(var)}", set_here.get(var.name, var.start), events))
        return out

    def columns(self) -> dict[str, dict[str, Any]]:
        """What each recorded column holds: its unit (as the model description declares it, or the
        scenario's ``units``; None where neither gives one), the instance, that instance's FMU file and the
        FMU's own name of the variable (before the name map; with the element of an array)."""
        out: dict[str, dict[str, Any]] = {"time": {"unit": "s", "instance": None, "fmu": None, "variable": "time"}}
        for r in self.record:
            ip = self.instances[r.instance]
            unit = unit_of(ip, r.var) if r.var.type == "Real" else None
            own = r.var.element_names()[r.elem] if r.var.shape else r.var.name
            out[r.column] = {"unit": unit.name if unit is not None else None, "instance": r.instance,
                             "fmu": ip.model.path.name, "variable": own}
        return out




def unit_of(inst: InstancePlan, var: Variable):
    """The unit of a variable as the scenario declares it (``units``), else as its FMU does (None if none)."""
    declared = inst.spec.units.get(inst.our_name(var)) or inst.spec.units.get(var.name)
    if declared:
        return lookup(declared, units_of(inst.model.md))
    return var.unit
