"""The algorithms: how a communication step is taken over the instances (libcosim's ``algorithm``).

An algorithm is an object behind :class:`Algorithm`.  Its contract, for an implementation:

1. :meth:`~Algorithm.setup` is called once, after initialisation, with each instance's
   :class:`InstanceIO` in the plan's order, the :class:`Clock`, the row buffer (:class:`Row`: ``buf``,
   its doubles ``row`` and integers ``irow``, ``n_double``: where the outputs are exchanged) and the
   run's :data:`StepDone`.  Before it, every instance is initialised and every output is in the row.
2. :meth:`~Algorithm.advance` takes the steps ``k0 .. k1 - 1`` (t_k = start + k h, always computed so,
   never accumulated) and returns None, or the :class:`~.failure.Failure` at which it stopped.  After a
   step k it leaves every instance advanced to t_{k+1} and each Float64 output read into its slot of the
   row, then calls ``done(k + 1, ended)`` (the run's observers of every step: the recording takes the
   row there when that point is recorded) and stops at the Failure it returns; a failure that came after
   the step to t_{k+1} (a get) is reported at step k + 1 (:attr:`.failure.Call.after_step`).  An
   algorithm does not record: what is recorded, and when, is the recorder's.  A loop in native code may
   instead copy the row where ``done.native`` (a :class:`NativeRecording`) says, exactly when ``done``
   would take it, and hand the rows over after the segment.
3. Each Real input is set, before the step that uses it, to ``src[idx] * factor + offset`` over the
   instance's copies (``InstanceIO.copies``) as they are when :meth:`~Algorithm.advance` is called; the
   tabulated inputs of step k (``feed(k)``) and the other connections (``other``) are put in place with
   them; with ``check_inputs`` a non-finite value is a failure (``Call.NON_FINITE_INPUT``) before it is set.
4. :meth:`~Algorithm.inputs_changed` is called whenever the copies of some instance changed between
   two segments (events, the script): the algorithm takes the new ones from then on.  Before
   :meth:`~Algorithm.initialize`, and before each call of it, :attr:`~Algorithm.feeds` holds who feeds
   whom (:class:`.graph.FeedGraph`, the instances in the order of ``ios``): the plan's graph, less the
   copies an override holds.
5. An instance whose fast path sets ``terminated`` in a step ends the segment after ``done(k + 1, True)``
   (``Call.TERMINATED``, the FMU's last successful time as the value).
6. An algorithm makes no FMI call but through the instances' fast paths, accessors and closures given
   in the InstanceIO, so that it works on every implementation of the instance interface.

The table of algorithms (the names a scenario gives, what each can do and needs) is
:mod:`.table`; Gauss-Seidel and Jacobi, whose loop is generated, are :mod:`.generated`.
"""
from __future__ import annotations

import ctypes
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Callable, NamedTuple, Protocol

from ..instances.contract import FastPath
from ..instances.failure import Failure
from .graph import FeedGraph


#: ctypes arrays the loop reads and writes: doubles (values), unsigned ints (value references)
Doubles = ctypes.Array[ctypes.c_double]
Refs = ctypes.Array[ctypes.c_uint]


class Row(Protocol):
    """The row buffer as an algorithm sees it (the plan's layout of it is ``plan.wiring.RowLayout``): its
    raw bytes, its doubles (time first, then the instances' Float64 outputs) and its 64-bit integers."""

    buf: ctypes.Array[ctypes.c_byte]
    row: Doubles
    irow: ctypes.Array[ctypes.c_int64]
    n_double: int


#: What an algorithm calls after each step it took, with the point k reached (t_k) and whether an FMU ended
#: the simulation in that step: None, or the Failure that ends the segment there (a recorded value that
#: could not be read).  The execution gives it: the recording's ``take`` (``runtime.observers.Recorder``).
StepDone = Callable[[int, bool], "Failure | None"]


@dataclass
class NativeRecording:
    """What the recording gives a native loop (a :data:`StepDone` may carry it as ``done.native``: the
    recording's does): its
    row (``buf``, ``row_bytes``: the doubles and integers the loop leaves the outputs in), when a row is
    taken (every ``decimation``-th point of ``n_steps``, the last one, an FMU's end), the last point's time
    ``stop`` [s] where the last step is short, ``t0`` and ``h`` [s]; ``read_others(k)`` reads the recorded
    outputs of other types into the row (None: there are none), returning None or the Failure; ``extend``
    takes the rows written (bytes of n whole rows, n); ``records`` (None: none), where the loop may write
    the rows as records instead (:class:`RecordSink`)."""

    buf: Any
    row_bytes: int
    decimation: int
    n_steps: int
    stop: float | None
    t0: float
    h: float
    read_others: Callable[[int], Failure | None] | None
    extend: Callable[[bytes, int], None]
    records: "RecordSink | None" = None


class RecordSink(Protocol):
    """Where a native loop may write the recorded rows as they are kept (the records of signals.npy) in
    place of copying the row: ``columns`` (per recorded column: the byte offset of its value in the row,
    its conversion, native_loop.c's REC_*, and its byte offset in the record), ``record_bytes`` (a
    record's size); ``reserve(n)``: the address where up to n records may be written next; ``took(n,
    bad_row, bad_col)``: n records were written there, the first non-finite value of a real column in
    record ``bad_row`` of them (-1: none), column ``bad_col``."""

    columns: list[tuple[int, int, int]]
    record_bytes: int

    def reserve(self, n: int) -> int: ...

    def took(self, n: int, bad_row: int, bad_col: int) -> None: ...


class Copy(NamedTuple):
    """How one Real input takes its value each step: ``in_val[pos] = src[slot] * factor + offset``."""

    pos: int                 # position in the instance's input array
    src: Doubles             # the source array: the row's outputs, a table's values, a held value
    slot: int                # the index in it
    factor: float
    offset: float


@dataclass(frozen=True)
class Clock:
    """The communication grid: t_k = start + k step [s] for k = 0 .. n_steps; every ``decimation``-th
    step (and the last) is recorded.  Where the step does not divide the run, ``stop`` [s] is given: the
    last point, reached by a short step from t_{n_steps - 1}."""

    start: float
    step: float
    n_steps: int
    decimation: int = 1
    stop: float | None = None   # [s] the last point when the last step is short (None: every step is ``step``)

    def time(self, k: int) -> float:
        """t_k [s]."""
        if self.stop is not None and k == self.n_steps:
            return self.stop
        return self.start + k * self.step

    def length(self, k: int) -> float:
        """The length [s] of step k (from t_k to t_{k+1})."""
        if self.stop is not None and k == self.n_steps - 1:
            return self.stop - self.time(k)
        return self.step

    def step_of(self, t: float) -> int:
        """The point k nearest to the time t [s] (the last point for a time within a millionth of a step of
        it)."""
        if self.stop is not None and abs(t - self.stop) <= 1e-6 * self.step:
            return self.n_steps
        return int(round((t - self.start) / self.step))

    def steps_before(self, t: float) -> int:
        """How many steps end at or before the time t [s]."""
        if self.stop is not None and t >= self.stop - 1e-9 * self.step:
            return self.n_steps
        return min(self.n_steps, int(math.floor((t - self.start) / self.step + 1e-9)))


@dataclass
class InstanceIO:
    """What an algorithm does with one instance each step."""

    name: str
    fast: FastPath                           # the raw step calls (fmu_instance.FastPath)
    in_vr: Refs                              # the Float64 inputs' value references
    n_in: ctypes.c_size_t                    # their number
    out_vr: Refs                             # the Float64 outputs'
    out_val: Doubles                         # a view into the row buffer
    n_out: ctypes.c_size_t
    copies: list[Copy] = field(default_factory=list)
    other: list[Callable[[], int]] = field(default_factory=list)  # connections other than Float64 -> Float64
    reads: tuple[str, ...] = ()                    # the instances whose outputs ``other`` reads (FMI gets)
    feed: Callable[[int], int] | None = None       # tabulated inputs of step k (wiring.table_feeder)
    # the instance's state and input derivatives, for the algorithms that roll steps back and iterate
    # (cosim.instances.contract: get_state, set_state, free_state, allow_rollback, set_input_derivatives,
    # directional_derivative)
    can_roll_back: bool = False
    get_state: Callable[[], Any] | None = None
    set_state: Callable[[Any], None] | None = None
    free_state: Callable[[Any], None] | None = None
    allow_rollback: Callable[[], None] | None = None
    set_input_derivatives: Callable[[list[int], list[float]], int] | None = None
    decimation: int = 1                            # it steps every this many base steps (its own step)
    directional_derivative: Callable[[list[int], list[int], list[float]], tuple[int, list[float]]] | None = None

    @property
    def in_val(self) -> Doubles:
        return self.fast.in_val

    def set_inputs(self) -> int:
        """fmi2SetReal / fmi3SetFloat64 of the input array now (outside the loop: initialisation)."""
        f = self.fast
        return f.set_real(f.c, self.in_vr, self.n_in, f.in_val, *f.set_tail)

    def get_outputs(self) -> int:
        """The Float64 outputs into the row now (outside the loop)."""
        f = self.fast
        return f.get_real(f.c, self.out_vr, self.n_out, self.out_val, *f.get_tail)


class Algorithm(ABC):
    """How a communication step is taken (see the module's contract)."""

    name = ""   # the table's name of it (stepping.table.make sets it)
    feeds: FeedGraph | None = None   # who feeds whom now (the execution sets it: the contract, item 4)

    @abstractmethod
    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None: ...

    @abstractmethod
    def inputs_changed(self) -> None: ...

    @abstractmethod
    def advance(self, k0: int, k1: int) -> Failure | None: ...

    def initialize(self, ios: list[InstanceIO], t0: float, check_inputs: bool = True) -> None:
        """In initialisation mode, after the initial exchange of outputs to inputs: an algorithm that
        solves coupling loops solves them here (raising RunError when it cannot); the others do nothing."""

    def finish(self) -> None:
        """After the run's last step: let go of what the algorithm keeps for the run (threads); it may
        still be asked for its :meth:`summary`."""

    def summary(self) -> dict[str, Any] | None:
        """The algorithm's own counts for summary.json ("stepping"): None when it has none."""
        return None
