"""The instance interface: what the execution and its algorithms may ask of one FMU instance, whatever
hosts it (FMI 2.0 or 3.0 co-simulation in this process, either of them in a child process; a Model
Exchange FMU with an integrator is one more implementation).

The contract, for an implementation (a subclass of :class:`FmuInstance`):

1. The life cycle is called in this order, each call at most once: :meth:`~FmuInstance.instantiate`,
   :meth:`~FmuInstance.setup_experiment`, :meth:`~FmuInstance.set_values` (any number of times from
   here on), :meth:`~FmuInstance.enter_initialization`, :meth:`~FmuInstance.exit_initialization`, the
   steps, :meth:`~FmuInstance.shutdown`.  ``shutdown`` may come at any point, also after a failure, and
   is the only call after one.
2. A call that fails raises :class:`~.errors.RunError` naming the instance, the FMI call and the time
   (:meth:`~FmuInstance.fail_status` builds it), and a Fatal status marks the instance ``fatal``: from
   then on ``shutdown`` makes no FMI call at all.
3. :meth:`~FmuInstance.fast_path` hands the stepping loop the raw entry points of one communication step
   (set the Float64 inputs, do the step, get the Float64 outputs) as a :class:`FastPath`: callables with
   no argument conversion and the extra arguments each takes, so that the loop calls every
   implementation the same way and knows nothing of FMI versions.  The input values live in
   ``FastPath.in_val``, which the loop writes before the set.
4. :meth:`~FmuInstance.accessor` gives the same kind of raw call for any other FMI type (the tabulated
   inputs, discrete connections and recorded outputs use it).
5. After a ``do_step`` that returned Discard, :meth:`~FmuInstance.terminated_at` says whether the FMU
   ended the simulation itself (its last successful time) or not (None).  An implementation that learns
   it from the step itself sets ``FastPath.terminated`` (and ``FastPath.last_time``) instead.
6. :meth:`~FmuInstance.get_state` / :meth:`~FmuInstance.set_state` / :meth:`~FmuInstance.free_state`
   save and restore the whole instance (FMI ``fmi2GetFMUstate`` and its kin) where
   ``can_get_and_set_state`` is true, for the algorithms that roll steps back; elsewhere they raise
   RunError.  Such an algorithm calls :meth:`~FmuInstance.allow_rollback` first, and may give the
   inputs' derivatives over a step (:meth:`~FmuInstance.set_input_derivatives`) where
   ``can_interpolate_inputs`` is true, and ask the partial derivatives of outputs with respect to inputs
   at the current point (:meth:`~FmuInstance.directional_derivative`) where
   ``provides_directional_derivative`` is true.
7. ``n_errors`` counts the messages of status Discard or worse the FMU has logged; ``log_lines`` and
   ``received`` the lines kept and received; :meth:`~FmuInstance.last_log` the last few, for messages.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
import ctypes
from typing import TYPE_CHECKING, Any, Callable

from ..messages.errors import RunError
from ..model.description import Variable, declares_state
from .failure import Call, FmiStatus

if TYPE_CHECKING:   # (FMPy has no type information: to mypy this is Any)
    from fmpy.model_description import ModelDescription


@dataclass
class FastPath:
    """The raw entry points of one instance's communication step, called by the generated loop as
    ``set_real(c, in_vr, n_in, in_val, *set_tail)``, ``do_step(c, t, h, *step_tail)`` (``t`` and ``h``
    c_double) and ``get_real(c, out_vr, n_out, out_val, *get_tail)``, each returning an FMI status."""

    c: ctypes.c_void_p                     # the instance's handle
    set_real: Callable[..., int]
    do_step: Callable[..., int]
    get_real: Callable[..., int]
    in_val: ctypes.Array[ctypes.c_double]  # the input values the loop writes
    set_tail: tuple[Any, ...] = ()
    step_tail: tuple[Any, ...] = ()
    get_tail: tuple[Any, ...] = ()
    terminated: ctypes.c_bool | None = None   # set by a step after which the FMU ended the simulation
    last_time: ctypes.c_double | None = None  # its last successful time [s] (with ``terminated``)
    # a step in two halves, for stepping several instances at once (an isolated instance: the request
    # written, then the answer awaited): ``start_step(c, t, h)``, then ``finish_step(spin)`` -> the status
    # (``spin`` False: wait without polling)
    start_step: Callable[..., None] | None = None
    finish_step: Callable[[bool], int] | None = None
    # the step through a view of the library that lets go of the GIL for the call, so that instances in
    # this process step at once in threads (None: the step needs this process's Python, or the instance
    # steps in a child process; ``alone`` says why for the first: a pythonfmu FMU, a Model Exchange
    # instance's integrator)
    threaded_step: Callable[..., int] | None = None
    alone: str = ""
    # 2 or 3: those of set_real, do_step and get_real that are the library's own functions take FMI 2.0's
    # or FMI 3.0's arguments (the tails as given), so that a loop in C may call them directly; 0: none is
    abi: int = 0


class FmuInstance(ABC):
    """One FMU instance as the execution sees it (see the module's contract)."""

    name: str
    md: "ModelDescription"                 # the FMU's model description (FMPy)
    fmi_version: int = 2                   # 2 or 3: for the names of calls in messages
    fatal: bool = False
    n_errors: int = 0
    log_lines: int = 0
    received: int = 0

    # ------------------------------------------------------------------ life cycle
    @abstractmethod
    def instantiate(self) -> None: ...

    @abstractmethod
    def setup_experiment(self, start: float, stop: float | None, tolerance: float | None) -> None:
        """Start and stop time [s] and the relative tolerance of the FMU's own integrator."""

    @abstractmethod
    def set_values(self, pairs: list[tuple[Variable, Any]]) -> None:
        """Set parameters, start values or inputs, each as a Python value of its type."""

    @abstractmethod
    def get_value(self, var: Variable) -> Any:
        """The current value of one scalar variable."""

    @abstractmethod
    def enter_initialization(self) -> None: ...

    @abstractmethod
    def exit_initialization(self) -> None: ...

    @abstractmethod
    def shutdown(self) -> None:
        """Terminate (if initialised) and free, exactly once; no FMI call after a Fatal."""

    # ------------------------------------------------------------------ the step's fast path
    @abstractmethod
    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int) -> FastPath:
        """The raw step calls for these Float64 inputs and outputs (value references; ``n_in`` and
        ``n_out`` count values, which differ from the references for FMI 3.0 arrays)."""

    @abstractmethod
    def accessor(self, fmi_type: str, op: str) -> tuple[Callable[[Any, Any, Any, Any], int], Any]:
        """(call, ctype): ``call(vrs, n, buf, n_values)`` gets (``op`` "Get") or sets ("Set") values of
        ``fmi_type`` with one raw call; ``ctype`` is the element type of ``buf``."""

    def terminated_at(self) -> float | None:
        """After a Discard from the step: the FMU's last successful time [s] if it ended the simulation."""
        return None

    def handled_events(self) -> list[tuple[float, str]]:
        """The events handled in this instance so far, (time [s], kind) in order: a model exchange FMU's
        time, state, step and input events (see :mod:`.me_instance`); none for co-simulation."""
        return []

    # ------------------------------------------------------------------ state (rollback)
    @property
    def can_get_and_set_state(self) -> bool:
        """The FMU's co-simulation interface declares it can save and restore its state."""
        return declares_state(self.md.coSimulation)

    def get_state(self) -> Any:
        raise RunError(f"{self.name}: this instance cannot save its state", self.name)

    def set_state(self, state: Any) -> None:
        raise RunError(f"{self.name}: this instance cannot restore a state", self.name)

    def free_state(self, state: Any) -> None:
        raise RunError(f"{self.name}: this instance cannot free a state", self.name)

    def allow_rollback(self) -> None:
        """From now on, step so that a state saved before the current point may still be restored (FMI's
        noSetFMUStatePriorToCurrentPoint false); the fast paths already handed out follow.  Nothing to do
        where the steps never promise it."""

    @property
    def can_interpolate_inputs(self) -> bool:
        """The instance takes the derivatives of its Real inputs over a step (:meth:`set_input_derivatives`)."""
        return False

    def set_input_derivatives(self, vrs: list[int], values: list[float]) -> int:
        """The first derivatives [unit/s] of these Float64 inputs over the next step (fmi2SetRealInputDerivatives,
        order 1): the FMI status."""
        raise RunError(f"{self.name}: this instance cannot interpolate its inputs", self.name)

    @property
    def provides_directional_derivative(self) -> bool:
        """The instance gives partial derivatives of its outputs by its inputs (:meth:`directional_derivative`)."""
        return False

    def directional_derivative(self, unknowns: list[int], knowns: list[int], seed: list[float]) -> tuple[int, list[float]]:
        """(the FMI status, d unknowns = J seed): the directional derivative at the current point of the
        outputs ``unknowns`` by the inputs ``knowns`` (value references) along ``seed``
        (fmi2GetDirectionalDerivative)."""
        raise RunError(f"{self.name}: this instance gives no directional derivatives", self.name)

    # ------------------------------------------------------------------ log and failures
    @abstractmethod
    def last_log(self, n: int = 3) -> str: ...

    def call_name(self, call: Call) -> str:
        """A call of the stepping loop as this instance's FMI version names it (``fmi3DoStep``)."""
        return call.name_for(self.fmi_version)

    def fail_status(self, what: str, status: int, t: float | None) -> RunError:
        """The error for a call that returned ``status`` (a Fatal marks the instance)."""
        if status == FmiStatus.FATAL:
            self.fatal = True
        at = f" at t = {t:.6g} s" if t is not None else ""
        return RunError(f"{self.name}: {what} returned {status_label(status)}{at}; last log: {self.last_log()}",
                        self.name, t)


def status_label(status: int) -> str:
    """The FMI name of a status ("OK" ... "Pending"), or its number when it is none of them."""
    try:
        return FmiStatus(status).label
    except ValueError:
        return str(status)
