"""The kinds of instance and the class that hosts each, in one table: read by the start-up (an instance in
this process) and by the isolation child (an isolated instance, in its own process), so that an instance is
hosted by the same class wherever it runs.

An instance's kind is the interface it runs through (co-simulation, or model exchange with one of the
master's integrators) and its FMU's FMI major version.  Isolation is no kind of its own: an isolated
instance (:class:`.isolation.IsolatedInstance`) is the master's side of a child process that hosts the
instance by this table."""
from __future__ import annotations

from typing import Any, Callable

from ..model.description import CO_SIMULATION, MODEL_EXCHANGE, SCHEDULED_EXECUTION, fmi_of
from .contract import FmuInstance
from .in_process import Instance, Instance3
from .integrators import SolverSpec
from .model_exchange import ModelExchange2, ModelExchange3
from .scheduled import ScheduledExecution3

#: An instance's kind: (its interface, "co-simulation" | "model-exchange" | "scheduled-execution"; its FMU's FMI
#: major version, 2 | 3).
Kind = tuple[str, int]

#: Each kind of instance -> the class that hosts it in a process.
HOSTS: dict[Kind, type[FmuInstance]] = {
    (CO_SIMULATION, 2): Instance,
    (CO_SIMULATION, 3): Instance3,
    (MODEL_EXCHANGE, 2): ModelExchange2,
    (MODEL_EXCHANGE, 3): ModelExchange3,
    (SCHEDULED_EXECUTION, 3): ScheduledExecution3,
}


def kind_of(fmi: int, solver: SolverSpec | None) -> Kind:
    """The kind of an instance of an FMU of FMI major version ``fmi``: model exchange where it has an
    integrator (``solver``), else co-simulation."""
    return (CO_SIMULATION if solver is None else MODEL_EXCHANGE, fmi)


def host(name: str, md: Any, fmi: int, unzipdir: str, log_path: Any, logging: str,
         solver: SolverSpec | None, interface: str | None = None) -> FmuInstance:
    """Instance ``name`` of the FMU extracted in ``unzipdir`` (FMPy's model description ``md``, FMI major
    version ``fmi``), loaded in this process by the class of its kind (:data:`HOSTS`): model exchange with
    ``solver``'s integrator where one is given, else co-simulation; its log written to ``log_path`` (None:
    kept in memory only) at the level ``logging``; ``interface`` "scheduled-execution": by the scheduled
    execution host."""
    kind = (SCHEDULED_EXECUTION, fmi) if interface == SCHEDULED_EXECUTION else kind_of(fmi, solver)
    make: Callable[..., FmuInstance] = HOSTS[kind]
    if solver is None:
        return make(name, md, unzipdir, log_path, logging)
    return make(name, md, unzipdir, log_path, logging, solver)


def model_exchange(name: str, md: Any, unzipdir: str, log_path: Any = None, logging: str = "warning",
                   solver: SolverSpec = SolverSpec()) -> ModelExchange2 | ModelExchange3:
    """The Model Exchange instance of an FMU (FMI 2.0 or 3.0 by its model description), the class of its
    kind."""
    inst = host(name, md, fmi_of(md), unzipdir, log_path, logging, solver)
    assert isinstance(inst, (ModelExchange2, ModelExchange3))
    return inst
