"""Running a plan: the execution (libcosim's), its observers and manipulators and the views they get,
start-up, real-time pacing, protocols of several runs."""
from __future__ import annotations

from .execution import Execution, run
from .manipulators import Manipulator
from .observers import Observer
from .protocol import Protocol, check_protocol, plan_runs, read_protocol, run_protocol
from .views import Manipulable, ManipulatedRun, Observable, ObservedRun

__all__ = ["check_protocol", "Execution", "Manipulable", "ManipulatedRun", "Manipulator", "Observable", "ObservedRun", "Observer", "plan_runs", "Protocol", "read_protocol", "run", "run_protocol"]
