"""What the stepping loop reports when it stops before the end of a segment: a record of where and why,
made once where it is detected, and the FMI statuses by name."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum
from typing import Any

from ..messages.errors import RunError


class FmiStatus(IntEnum):
    """fmi2Status / fmi3Status."""

    OK = 0
    WARNING = 1
    DISCARD = 2
    ERROR = 3
    FATAL = 4
    PENDING = 5   # (FMI 2.0 only)

    @property
    def label(self) -> str:
        """The name the standard gives it: "OK", "Warning", "Discard", "Error", "Fatal", "Pending"."""
        return "OK" if self is FmiStatus.OK else self.name.capitalize()


class Call(Enum):
    """The call, or check, of the stepping loop that stopped a segment.  ``after_step``: it came after the
    step to t_k was taken, so that step's row is not recorded (the steps done are k - 1)."""

    TABLE_INPUTS = "fmi2Set (tabulated inputs)"
    NON_FINITE_INPUT = "inputs"
    SET_REAL = "SetReal"                     # named for its FMI version: fmi2SetReal, fmi3SetFloat64
    CONNECTION = "fmi2Get/Set (a connection)"
    DO_STEP = "DoStep"                       # fmi2DoStep, fmi3DoStep
    GET_REAL = "GetReal"                     # fmi2GetReal, fmi3GetFloat64
    GET_RECORDED = "Get (recorded)"
    TERMINATED = "fmi3Terminated"            # an FMI 3.0 FMU ended the simulation in its step
    COUPLING = "coupling"                    # the algorithm's own failure (a loop that did not converge, the
                                             # step-size control at its smallest step): the value is the message

    @property
    def after_step(self) -> bool:
        return self in (Call.GET_REAL, Call.GET_RECORDED)

    def name_for(self, fmi: int) -> str:
        """The call as the FMI version names it (``fmi3SetFloat64``), for messages."""
        if self is Call.SET_REAL:
            return "fmi2SetReal" if fmi == 2 else "fmi3SetFloat64"
        if self is Call.GET_REAL:
            return "fmi2GetReal" if fmi == 2 else "fmi3GetFloat64"
        if self is Call.DO_STEP:
            return f"fmi{fmi}DoStep"
        if self is Call.GET_RECORDED:
            return f"fmi{fmi}Get (recorded)"
        return self.value


@dataclass(frozen=True)
class Failure:
    """The loop stopped at step ``step`` (the step from t_{step}, or, for a call after the step, to it) in
    ``instance``'s ``call``; ``value`` is the FMI status it returned, the non-finite input value, or (for
    TERMINATED) the FMU's last successful time [s], or (for COUPLING) the message; ``time`` [s]: where it
    happened when that is not a communication point (the variable steps of the step-size control)."""

    step: int
    instance: str
    call: Call
    value: Any
    time: float | None = None


class InstanceLost(RunError):
    """An instance's host process ended (crash, abort, exit) or was ended after a hang, at ``time``: the
    steps up to there are recorded, the other instances are terminated and freed."""
