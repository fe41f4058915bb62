"""The integrators that advance a Model Exchange FMU between communication points.

:class:`SolverSpec` is what a scenario (``[instances.X] solver, tolerance, max_step, event_tolerance``) and
the Python API say of one Model Exchange instance's integrator.
"""
from __future__ import annotations

from dataclasses import dataclass

#: The integrators a scenario may name.
SOLVERS = ("cvode", "euler", "rk4")
#: CVODE's relative tolerance when neither the instance, the experiment nor the FMU gives one (FMPy's).
DEFAULT_RTOL = 1e-5
#: The time tolerance [s] to which a fixed-step integrator locates a state event.
DEFAULT_EVENT_TOLERANCE = 1e-10


@dataclass(frozen=True)
class SolverSpec:
    """One Model Exchange instance's integrator: ``name`` one of :data:`SOLVERS`; ``tolerance`` CVODE's
    relative tolerance (None: :data:`DEFAULT_RTOL`; the absolute one is it times each state's nominal);
    ``max_step`` [s] the largest internal step (None: CVODE takes (stop - start) / 50 as FMPy does, Euler and
    RK4 one step per communication step); ``event_tolerance`` [s] the width to which Euler and RK4 locate a
    state event (CVODE locates its roots to its own, tighter, tolerance)."""

    name: str = "cvode"
    tolerance: float | None = None
    max_step: float | None = None
    event_tolerance: float = DEFAULT_EVENT_TOLERANCE
