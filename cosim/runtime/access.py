"""The system's variables by our names between steps: looked up once (``"instance.variable"``, through the
instance's name map), read from the row buffer where the loop keeps them or asked of the FMU, and changed
through the script's manipulator (:class:`.manipulators.ScriptChanges`)."""
from __future__ import annotations

from typing import Any, Callable

from ..instances.contract import FmuInstance
from ..messages.errors import ScenarioError
from ..model.description import Variable
from ..plan.records import Plan
from ..plan.resolution import checked_value, variable
from ..plan.wiring import RowLayout
from ..scenario.document import split_ref
from .manipulators import ScriptChanges


class VariableAccess:
    """Get, set and release variables of a running system by reference."""

    def __init__(self, plan: Plan, instances: dict[str, FmuInstance], layout: RowLayout,
                 script: ScriptChanges) -> None:
        self.plan, self.instances, self.layout, self.script = plan, instances, layout, script
        self._vars: dict[str, tuple[str, Variable]] = {}
        self._readers: dict[str, Callable[[], Any]] = {}

    def variable(self, ref: str) -> tuple[str, Variable]:
        """(instance, variable) of ``"instance.variable"`` (our name of it), or ScenarioError."""
        got = self._vars.get(ref)
        if got is None:
            file = self.plan.scenario.file
            inst, name = split_ref(file, ref, ref)
            if inst not in self.plan.instances:
                raise ScenarioError(file, ref, f"unknown instance {inst!r}")
            got = self._vars[ref] = (inst, variable(file, ref, self.plan.instances[inst], name))
        return got

    def reader(self, inst: str, var: Variable) -> Callable[[], Any]:
        """A function returning a variable's current value: from the row buffer for a Float64 output it
        holds (written by the loop at every step), else through an FMI get."""
        lay = self.layout
        if var.is_float64 and var.causality == "output" and any(vr == var.vr for vr, _ in lay.reals[inst]):
            row, slot = lay.row, lay.offset[inst] + lay.index(inst, var.vr)
            return lambda: row[slot]
        instance = self.instances[inst]
        return lambda: instance.get_value(var)

    def get(self, ref: str) -> Any:
        """The current value of ``"instance.variable"`` (see :meth:`.execution.Execution.get`)."""
        read = self._readers.get(ref)
        if read is None:
            read = self._readers[ref] = self.reader(*self.variable(ref))
        return read()

    def set(self, ref: str, value: Any) -> None:
        """Change ``"instance.variable"`` from the next step on, the value checked against its type and range."""
        inst, var = self.variable(ref)
        self.script.set(inst, var, checked_value(self.plan.scenario.file, ref, var, value))

    def bias(self, ref: str, value: float) -> None:
        """Add ``value`` to what reaches a connected Real input or what an output feeds its connections."""
        inst, var = self.variable(ref)
        self.script.bias(inst, var, checked_value(self.plan.scenario.file, ref, var, float(value), check_range=False))

    def release(self, ref: str) -> None:
        """End an override :meth:`set` or a :meth:`bias` put on a connected input or an output."""
        self.script.release(*self.variable(ref))
