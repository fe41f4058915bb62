"""The instance contract (what the execution and its algorithms may ask of one FMU instance) and its
implementations: FMI 2.0 and 3.0 co-simulation in this process, Model Exchange with the master's
integrators, either in a child process."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .contract import FastPath, FmuInstance
    from .failure import Call, Failure, FmiStatus, InstanceLost
    from .in_process import Instance, Instance3
    from .integrators import SOLVERS, SolverSpec
    from .isolation import IsolatedInstance
    from .kinds import HOSTS, host, model_exchange
    from .model_exchange import ModelExchange

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
