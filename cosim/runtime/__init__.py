"""Running a plan: the execution (libcosim's), its observers and manipulators and the views they get,
start-up, real-time pacing, protocols of several runs."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .execution import Execution, run
    from .manipulators import Manipulator
    from .observers import Observer
    from .protocol import Protocol, check_protocol, plan_runs, read_protocol, run_protocol
    from .views import Manipulable, ManipulatedRun, Observable, ObservedRun

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "execution": ["Execution", "run"],
    "manipulators": ["Manipulator"],
    "observers": ["Observer"],
    "protocol": ["Protocol", "check_protocol", "plan_runs", "read_protocol", "run_protocol"],
    "views": ["Manipulable", "ManipulatedRun", "Observable", "ObservedRun"],
})
