"""How a communication step is taken: the algorithm contract, the table of algorithms (names, classes,
what each can do and needs), the generated fixed-step loops, the plain-Python macro step and the
algorithms built on it (iterated, adaptive, multi-rate, parallel), their settings."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .adaptive import Adaptive
    from .algorithm import Algorithm, Clock, Copy, InstanceIO, Row
    from .generated import GaussSeidel, Jacobi
    from .iterated import Iterated
    from .multirate import MultiRate
    from .parallel import ParallelJacobi
    from .settings import AdaptiveSpec, IterationSpec, SpecError, iteration_spec
    from .stepper import Stepper
    from .table import NAMES, ROWS, AlgorithmRow, adaptive_spec, describe_settings, make, row

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
