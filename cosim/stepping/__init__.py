"""How a communication step is taken: the algorithm contract, the table of algorithms (names, classes,
what each can do and needs), the generated fixed-step loops, the plain-Python macro step and the
algorithms built on it (iterated, adaptive, multi-rate, parallel), their settings."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .adaptive import Adaptive
    from .algorithm import Algorithm, Clock, Copy, InstanceIO, Row
    from .generated import GaussSeidel, Jacobi
    from .iterated import Iterated
    from .multirate import MultiRate
    from .parallel import ParallelJacobi
    from .settings import AdaptiveSpec, IterationSpec, SpecError, iteration_spec
    from .stepper import Stepper
    from .table import NAMES, ROWS, AlgorithmRow, adaptive_spec, describe_settings, make, row

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "adaptive": ["Adaptive"],
    "algorithm": ["Algorithm", "Clock", "Copy", "InstanceIO", "Row"],
    "generated": ["GaussSeidel", "Jacobi"],
    "iterated": ["Iterated"],
    "multirate": ["MultiRate"],
    "parallel": ["ParallelJacobi"],
    "settings": ["AdaptiveSpec", "IterationSpec", "SpecError", "iteration_spec"],
    "stepper": ["Stepper"],
    "table": ["NAMES", "ROWS", "AlgorithmRow", "adaptive_spec", "describe_settings", "make", "row"],
})
