"""Linear models of FMUs and of the co-simulated system around a point of its run: the Jacobian of a Model
Exchange FMU (jacobian.py), blocks closed through the connections (interconnection.py), a discrete-time
model realised from pulse responses taken with rollback (realisation.py), a loop broken at a connection
and its margins (loop.py), a continuous loop beside the loop the co-simulation realises at its step
(cosimulated.py), the request checked and taken around a run (operating_point.py), the model
itself with its names, units and files (model.py).  python-control and scipy are imported where used."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .cosimulated import CouplingCost, cosimulated_loop, coupling_cost
    from .interconnection import Link, close
    from .jacobian import CUBE_ROOT_EPS, Signal, fd_step, jacobian
    from .loop import LoopAnalysis, analyse
    from .model import MAT_FILE, NPZ_FILE, LinearModel, control_name
    from .operating_point import DEFAULT_STEPS, Linearisation, Linearizer, Request, memoryless
    from .realisation import Injection, pulse_responses, realise

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
