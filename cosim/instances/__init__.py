"""The instance contract (what the execution and its algorithms may ask of one FMU instance) and its
implementations: FMI 2.0 and 3.0 co-simulation in this process, Model Exchange with the master's
integrators, either in a child process."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .contract import FastPath, FmuInstance
    from .failure import Call, Failure, FmiStatus, InstanceLost
    from .in_process import Instance, Instance3
    from .integrators import SOLVERS, SolverSpec
    from .isolation import IsolatedInstance
    from .kinds import HOSTS, host, model_exchange
    from .model_exchange import ModelExchange

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "contract": ["FastPath", "FmuInstance"],
    "failure": ["Call", "Failure", "FmiStatus", "InstanceLost"],
    "in_process": ["Instance", "Instance3"],
    "integrators": ["SOLVERS", "SolverSpec"],
    "isolation": ["IsolatedInstance"],
    "kinds": ["HOSTS", "host", "model_exchange"],
    "model_exchange": ["ModelExchange"],
})
