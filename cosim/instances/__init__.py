"""The instance contract (what the execution and its algorithms may ask of one FMU instance) and its
implementations: FMI 2.0 and 3.0 co-simulation in this process, Model Exchange with the master's
integrators, either in a child process."""
from __future__ import annotations

from .contract import FastPath, FmuInstance
from .failure import Call, Failure, FmiStatus, InstanceLost
from .in_process import Instance, Instance3
from .integrators import SOLVERS, SolverSpec
from .isolation import IsolatedInstance
from .model_exchange import ModelExchange, model_exchange

__all__ = ["Call", "Failure", "FastPath", "FmiStatus", "FmuInstance", "Instance", "Instance3", "InstanceLost", "IsolatedInstance", "model_exchange", "ModelExchange", "SOLVERS", "SolverSpec"]
