"""What the observers and manipulators see of a running execution: narrow views, not the execution.

An observer gets an :class:`ObservedRun` (an :class:`Observable`: the communication grid, the current time,
values by reference); a manipulator a :class:`ManipulatedRun` (a :class:`Manipulable`:
that, a reader of any variable for its conditions, and the changes: set, release, stop).  An observer
changes nothing (a script's step callback acts through the Python API's run, which it holds).  The views
are small objects over the execution (which is both kinds), so a part reaches nothing else of it.
"""
from __future__ import annotations

from typing import Any, Callable, Protocol

from ..model.description import Variable
from ..results.status import RunStatus
from ..stepping.algorithm import Clock


class Observable(Protocol):
    """What an observer may read: the grid, the current communication point, a variable's value."""

    @property
    def clock(self) -> Clock: ...

    @property
    def time(self) -> float: ...

    def get(self, ref: str) -> Any: ...


class Manipulable(Observable, Protocol):
    """What a manipulator may do besides: read a variable through a function (what its conditions are
    compiled over), change a variable from the next step on, end an override, end the run."""

    def reader(self, inst: str, var: Variable) -> Callable[[], Any]: ...

    def set(self, ref: str, value: Any) -> None: ...

    def release(self, ref: str) -> None: ...

    def stop(self, message: str | None = None, status: RunStatus = RunStatus.STOPPED) -> None: ...


class ObservedRun:
    """The read-only view of a run an observer is given (:class:`Observable`)."""

    __slots__ = ("_run",)

    def __init__(self, run: Manipulable) -> None:
        self._run = run

    @property
    def clock(self) -> Clock:
        return self._run.clock

    @property
    def time(self) -> float:
        """The current communication point [s]."""
        return self._run.time

    def get(self, ref: str) -> Any:
        return self._run.get(ref)


class ManipulatedRun(ObservedRun):
    """The view of a run a manipulator is given (:class:`Manipulable`)."""

    __slots__ = ()

    def reader(self, inst: str, var: Variable) -> Callable[[], Any]:
        return self._run.reader(inst, var)

    def set(self, ref: str, value: Any) -> None:
        self._run.set(ref, value)

    def release(self, ref: str) -> None:
        self._run.release(ref)

    def stop(self, message: str | None = None, status: RunStatus = RunStatus.STOPPED) -> None:
        self._run.stop(message, status)
