"""The algorithms: how a communication step is taken over the instances (libcosim's ``algorithm``).

An algorithm is an object behind :class:`Algorithm`.  Its contract, for an implementation:

1. :meth:`~Algorithm.setup` is called once, after initialisation, with each instance's
   :class:`InstanceIO` in the plan's order, the :class:`Clock`, the row buffer's layout
   (``wiring.RowLayout``: ``buf``, its doubles ``row`` and integers ``irow``, ``n_double``) and the list
   the recorded rows go to.  Before it, every instance is initialised and every output is in the row.
2. :meth:`~Algorithm.advance` takes the steps ``k0 .. k1 - 1`` (t_k = start + k h, always computed so,
   never accumulated) and returns None, or the :class:`~.failure.Failure` at which it stopped.  After a
   step k it leaves: every instance advanced to t_{k+1}; each Float64 output read into its slot of the
   row; ``row[0] = t_{k+1}`` and the row's bytes appended to the rows when the step is recorded (every
   ``decimation``-th step, and the last); a failure that came after the step to t_{k+1} (a get) reported
   at step k + 1 (:attr:`.failure.Call.after_step`).
3. Each Real input is set, before the step that uses it, to ``src[idx] * factor + offset`` over the
   instance's copies (``InstanceIO.copies``) as they are when :meth:`~Algorithm.advance` is called; the
   tabulated inputs of step k (``feed(k)``) and the other connections (``other``) are put in place with
   them; with ``check_inputs`` a non-finite value is a failure (``Call.NON_FINITE_INPUT``) before it is set.
4. :meth:`~Algorithm.inputs_changed` is called whenever the copies of some instance changed between
   two segments (events, the script): the algorithm takes the new ones from then on.
5. An instance whose fast path sets ``terminated`` in a step ends the segment after that step is recorded
   (``Call.TERMINATED``, the FMU's last successful time as the value).
6. An algorithm makes no FMI call but through the instances' fast paths, accessors and closures given
   in the InstanceIO, so that it works on every implementation of the instance interface.

Gauss-Seidel and Jacobi are fixed-step algorithms whose loop is generated for one plan as straight-line
Python: every array, function, index and number is bound as a local of the generated function (never
formatted into its source), and the FMI functions are raw ctypes calls without per-argument conversion.
Measured on the G1 system, this is faster than a plain loop over the instances making the same calls
(docs/architecture.md).  They differ only in the order of work in a step:

  * Gauss-Seidel, in the plan's order: for each instance, set its inputs from the current values of the
    outputs connected to them (an instance later in the order sees the outputs its predecessors produced
    in this step), do the step, get its outputs.
  * Jacobi: set every instance's inputs from the outputs of the previous step, step all, get all.
"""
from __future__ import annotations

import ctypes
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, NamedTuple

from .coupling_spec import AdaptiveSpec, IterationSpec
from .failure import Call, Failure
from .fmu_instance import FastPath

if TYPE_CHECKING:
    from .wiring import RowLayout

#: ctypes arrays the loop reads and writes: doubles (values), unsigned ints (value references)
Doubles = ctypes.Array[ctypes.c_double]
Refs = ctypes.Array[ctypes.c_uint]

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
class RecordedGetter:
    """The recorded outputs of one instance of one FMI type other than Float64: ``get(vrs, n, buf, nv)``
    reads them into ``buf``; ``slots`` maps an index in ``buf`` to the row's slot."""

    get: Callable[[Any, Any, Any, Any], int]
    vrs: Refs
    n: ctypes.c_size_t                       # value references
    buf: ctypes.Array[Any]                   # of the type's ctypes element
    nv: ctypes.c_size_t                      # values
    slots: list[tuple[int, int]]


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
    extras: list[RecordedGetter] = field(default_factory=list)
    other: list[Callable[[], int]] = field(default_factory=list)  # connections other than Float64 -> Float64
    feed: Callable[[int], int] | None = None       # tabulated inputs of step k (wiring.table_feeder)
    # the instance's state and input derivatives, for the algorithms that roll steps back and iterate
    # (cosim.fmu_instance: get_state, set_state, free_state, allow_rollback, set_input_derivatives,
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

    name = "?"

    @abstractmethod
    def setup(self, ios: list[InstanceIO], clock: Clock, layout: "RowLayout", chunk: list[bytes],
              check_inputs: bool = True) -> None: ...

    @abstractmethod
    def inputs_changed(self) -> None: ...

    @abstractmethod
    def advance(self, k0: int, k1: int) -> Failure | None: ...

    def initialize(self, ios: list[InstanceIO], t0: float, check_inputs: bool = True) -> None:
        """In initialisation mode, after the initial exchange of outputs to inputs: an algorithm that
        solves coupling loops solves them here (raising RunError when it cannot); the others do nothing."""

    def summary(self) -> dict[str, Any] | None:
        """The algorithm's own counts for summary.json ("stepping"): None when it has none."""
        return None


class GeneratedLoop(Algorithm):
    """A fixed-step algorithm whose loop is generated (see the module's docstring); a subclass says the
    order of work in a step in :meth:`body`."""

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: "RowLayout", chunk: list[bytes],
              check_inputs: bool = True) -> None:
        self.ios, self.clock, self.layout, self.chunk, self.check_inputs = ios, clock, layout, chunk, check_inputs
        self.loop: Callable[[int, int], Failure | None] | None = None

    def inputs_changed(self) -> None:
        self.loop = None

    def advance(self, k0: int, k1: int) -> Failure | None:
        if self.loop is None:
            self.loop = self.compile()
        return self.loop(k0, k1)

    def compile(self) -> Callable[[int, int], Failure | None]:
        """The loop for the instances' copies as they are now."""
        return compile_loop(self.ios, self.body, self.clock, self.layout, self.chunk, self.check_inputs)

    @abstractmethod
    def body(self, s: "LoopSource", ios: list[InstanceIO], ind: str) -> None:
        """Write one step's work over the instances (:meth:`LoopSource.inputs`, ``.step``, ``.outputs``)."""


class GaussSeidel(GeneratedLoop):
    name = "gauss-seidel"

    def body(self, s: "LoopSource", ios: list[InstanceIO], ind: str) -> None:
        for i, io in enumerate(ios):
            s.inputs(i, io, ind)
            s.step(i, io, ind)
            s.outputs(i, io, ind)


class Jacobi(GeneratedLoop):
    name = "jacobi"

    def body(self, s: "LoopSource", ios: list[InstanceIO], ind: str) -> None:
        for i, io in enumerate(ios):
            s.inputs(i, io, ind)
        for i, io in enumerate(ios):
            s.step(i, io, ind)
        for i, io in enumerate(ios):
            s.outputs(i, io, ind)


#: The algorithms a scenario names (``[experiment] algorithm``).
ALGORITHMS: dict[str, type[Algorithm]] = {"gauss-seidel": GaussSeidel, "jacobi": Jacobi}


def algorithm_for(name: str, iteration: "IterationSpec | None" = None,
                  adaptive: "AdaptiveSpec | None" = None) -> Algorithm:
    """A new algorithm object for the name a scenario gives, with its settings (``[experiment.iteration]``,
    ``[experiment.adaptive]``; None: the defaults)."""
    if name == "iterated":
        from .iterated import Iterated
        return Iterated(iteration or IterationSpec())
    if name == "adaptive":
        from .adaptive import Adaptive
        return Adaptive(adaptive or AdaptiveSpec(), iteration)
    return ALGORITHMS[name]()


class LoopSource:
    """The generated function's source and the values it binds as locals."""

    def __init__(self, check_inputs: bool) -> None:
        self.lines: list[str] = []
        self.env: dict[str, Any] = {}
        self.check_inputs = check_inputs

    def bind(self, name: str, value: Any) -> str:
        self.env[name] = value
        return name

    def w(self, line: str) -> None:
        self.lines.append(line)

    def args(self, prefix: str, i: int, tail: tuple[Any, ...]) -> str:
        """The extra arguments of a call, bound as locals: ``", a0_1, a1_1"``."""
        return "".join(f", {self.bind(f'{prefix}{j}_{i}', v)}" for j, v in enumerate(tail))

    def inputs(self, i: int, io: InstanceIO, ind: str) -> None:
        """Step k's inputs of instance i: tables, copies (checked), the set, the other connections."""
        if io.feed is not None:
            self.w(f"{ind}s = {self.bind(f'feed_{i}', io.feed)}(k)")
            self.w(f"{ind}if s: return Failure(k, name_{i}, Call.TABLE_INPUTS, s)")
        names = []
        for j, (pos, arr, idx, f, o) in enumerate(io.copies):
            a, x = self.bind(f"src_{i}_{j}", arr), self.bind(f"idx_{i}_{j}", idx)
            if f == 1.0 and o == 0.0:
                self.w(f"{ind}v{j} = {a}[{x}]")
            else:
                self.w(f"{ind}v{j} = {a}[{x}] * {self.bind(f'f_{i}_{j}', f)} + {self.bind(f'o_{i}_{j}', o)}")
            names.append(f"v{j}")
        if names and self.check_inputs:  # one test for all: a sum is non-finite if any term is (or it overflows)
            self.w(f"{ind}x = {' + '.join(names)}")
            self.w(f"{ind}if x - x != 0.0: return Failure(k, name_{i}, Call.NON_FINITE_INPUT, x)")
        for j, (pos, *_rest) in enumerate(io.copies):
            self.w(f"{ind}in_{i}[{self.bind(f'pos_{i}_{j}', pos)}] = v{j}")
        if io.copies:
            self.w(f"{ind}s = setr_{i}(c_{i}, invr_{i}, nin_{i}, in_{i}{self.args('sa', i, io.fast.set_tail)})")
            self.w(f"{ind}if s: return Failure(k, name_{i}, Call.SET_REAL, s)")
        for j, fn in enumerate(io.other):
            self.w(f"{ind}s = {self.bind(f'other_{i}_{j}', fn)}()")
            self.w(f"{ind}if s: return Failure(k, name_{i}, Call.CONNECTION, s)")

    def step(self, i: int, io: InstanceIO, ind: str) -> None:
        """The step of instance i from t_k; an FMU that ended the simulation in it is noted."""
        self.w(f"{ind}s = dostep_{i}(c_{i}, Tv, H{self.args('da', i, io.fast.step_tail)})")
        self.w(f"{ind}if s: return Failure(k, name_{i}, Call.DO_STEP, s)")
        if io.fast.terminated is not None:
            term, last = self.bind(f"term_{i}", io.fast.terminated), self.bind(f"last_{i}", io.fast.last_time)
            self.w(f"{ind}if {term}.value: ended = (name_{i}, {last}.value)")

    def outputs(self, i: int, io: InstanceIO, ind: str) -> None:
        """Instance i's Float64 outputs at t_{k+1} into the row."""
        if io.n_out.value:
            self.w(f"{ind}s = getr_{i}(c_{i}, outvr_{i}, nout_{i}, out_{i}{self.args('ga', i, io.fast.get_tail)})")
            self.w(f"{ind}if s: return Failure(k + 1, name_{i}, Call.GET_REAL, s)")

    def record(self, ios: list[InstanceIO], dec: int, n_double: int, short: bool = False) -> None:
        """The row of t_{k+1}, when the step is recorded (``short``: the last step is short, its row at the
        stop time); then the end of a simulation an FMU ended."""
        ends = any(io.fast.terminated is not None for io in ios)
        if dec > 1:
            self.w(f"        if (k + 1) % dec == 0 or k + 1 == n_steps{' or ended is not None' if ends else ''}:")
        else:
            self.w("        if True:")
        self.w("            row[0] = " + ("t_stop if k == k_last else t0 + (k + 1) * h" if short else "t0 + (k + 1) * h"))
        for i, io in enumerate(ios):
            for j, x in enumerate(io.extras):
                names = [self.bind(f"x{w}_{i}_{j}", v) for w, v in zip("gvnbc", (x.get, x.vrs, x.n, x.buf, x.nv))]
                self.w(f"            s = {names[0]}({', '.join(names[1:])})")
                self.w(f"            if s: return Failure(k + 1, name_{i}, Call.GET_RECORDED, s)")
                for e, slot in x.slots:
                    target = f"row[{self.bind(f'xs_{i}_{j}_{e}', slot)}]" if slot < n_double else \
                        f"irow[{self.bind(f'xs_{i}_{j}_{e}', slot - n_double)}]"
                    self.w(f"            {target} = {names[3]}[{self.bind(f'xe_{i}_{j}_{e}', e)}]")
        self.w("            append(bytes(buf))")
        if ends:  # an FMU ended the simulation in this step: its row is recorded, then stop
            self.w("        if ended is not None: return Failure(k + 1, ended[0], Call.TERMINATED, ended[1])")


def compile_loop(ios: list[InstanceIO], body: Callable[[LoopSource, list[InstanceIO], str], None], clock: Clock,
                 layout: "RowLayout", chunk: list[bytes], check_inputs: bool = True
                 ) -> Callable[[int, int], Failure | None]:
    """Generate and compile the loop ``loop(k0, k1)`` whose step is what ``body`` writes."""
    s = LoopSource(check_inputs)
    s.env.update({"row": layout.row, "irow": layout.irow, "buf": layout.buf, "append": chunk.append,
                  "bytes": bytes, "T": ctypes.c_double(0.0), "Failure": Failure, "Call": Call,
                  "H": ctypes.c_double(clock.step), "t0": float(clock.start), "h": float(clock.step),
                  "dec": int(clock.decimation), "n_steps": int(clock.n_steps)})
    for i, io in enumerate(ios):
        f = io.fast
        s.env.update({f"name_{i}": io.name, f"c_{i}": f.c, f"setr_{i}": f.set_real, f"dostep_{i}": f.do_step,
                      f"getr_{i}": f.get_real, f"invr_{i}": io.in_vr, f"in_{i}": f.in_val, f"nin_{i}": io.n_in,
                      f"outvr_{i}": io.out_vr, f"out_{i}": io.out_val, f"nout_{i}": io.n_out})
    head = s.lines
    s.lines = []
    body(s, ios, "        ")
    short = clock.stop is not None
    if short:   # the last step is short (only then is this compared at every step)
        s.env.update({"k_last": clock.n_steps - 1, "h_last": float(clock.length(clock.n_steps - 1)),
                      "t_stop": float(clock.time(clock.n_steps))})
    s.record(ios, clock.decimation, layout.n_double, short)
    step_lines, s.lines = s.lines, head
    # every bound value becomes a keyword default: a fast local inside the loop
    s.w(f"def loop(k0, k1, *, {', '.join(f'{n}={n}' for n in s.env)}):")
    s.w("    Tv = T")
    s.w("    ended = None")
    s.w("    for k in range(k0, k1):")
    s.w("        Tv.value = t0 + k * h")
    if short:
        s.w("        H.value = h_last if k == k_last else h")
    s.lines += step_lines
    s.w("    return None")
    src = "\n".join(s.lines)
    env = dict(s.env)
    exec(compile(src, "<cosim-loop>", "exec"), env)
    loop = env["loop"]
    loop.source = src   # (a function object takes attributes: the source, for reading and tests)
    return loop
