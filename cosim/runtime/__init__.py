"""Running a plan: the execution (libcosim's), its observers and manipulators and the views they get,
start-up, real-time pacing, protocols of several runs."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .execution import Execution, run
    from .manipulators import Manipulator
    from .observers import Observer
    from .protocol import Protocol, check_protocol, plan_runs, read_protocol, run_protocol
    from .views import Manipulable, ManipulatedRun, Observable, ObservedRun

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
