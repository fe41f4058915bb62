"""The fixed-step algorithms whose loop is generated: Gauss-Seidel and Jacobi.

Their loop is generated for one plan as straight-line Python: every array, function, index and number is
bound as a local of the generated function (never formatted into its source), and the FMI functions are
raw ctypes calls without per-argument conversion.
Measured on the G1 system, this is faster than a plain loop over the instances making the same calls
(docs/architecture.md).  They differ only in the order of work in a step:

  * Gauss-Seidel, in the plan's order: for each instance, set its inputs from the current values of the
    outputs connected to them (an instance later in the order sees the outputs its predecessors produced
    in this step), do the step, get its outputs.
  * Jacobi: set every instance's inputs from the outputs of the previous step, step all, get all.
"""
from __future__ import annotations

import ctypes
from abc import abstractmethod
from typing import Any, Callable

from ..instances.failure import Call, Failure
from .algorithm import Algorithm, Clock, InstanceIO, Row, StepDone


class GeneratedLoop(Algorithm):
    """A fixed-step algorithm whose loop is generated (see the module's docstring); a subclass says the
    order of work in a step in :meth:`body`, and whether every instance sees the previous step's outputs
    (``simultaneous``).  Where the compiled loop can be built (:mod:`.native`), it runs the same steps in
    C; else the generated Python loop does (``loop_used`` says which, and why)."""

    simultaneous = False
    native = True                  # False: the Python loop (a test's, or an algorithm's own)
    loop_used = ""                 # the loop that ran: "compiled (C)", or "Python (why)"

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        self.ios, self.clock, self.layout, self.done, self.check_inputs = ios, clock, layout, done, check_inputs
        self.loop: Callable[[int, int], Failure | None] | None = None
        self.loop_used = ""

    def inputs_changed(self) -> None:
        self.loop = None

    def advance(self, k0: int, k1: int) -> Failure | None:
        if self.loop is None:
            self.loop = self.compile()
        return self.loop(k0, k1)

    def compile(self) -> Callable[[int, int], Failure | None]:
        """The loop for the instances' copies as they are now: the compiled one where it can be built."""
        from . import native

        lib, why = native.library() if self.native else (None, "asked for")
        if lib is not None:
            self.loop_used = native.NATIVE
            return native.NativeLoop(lib, self.ios, self.simultaneous, self.clock, self.done, self.check_inputs)
        self.loop_used = f"{native.PYTHON} ({why})"
        return compile_loop(self.ios, self.body, self.clock, self.done, self.check_inputs)

    def summary(self) -> dict[str, Any] | None:
        return {"loop": self.loop_used} if self.loop_used else None

    @abstractmethod
    def body(self, s: "LoopSource", ios: list[InstanceIO], ind: str) -> None:
        """Write one step's work over the instances (:meth:`LoopSource.inputs`, ``.step``, ``.outputs``)."""


class GaussSeidel(GeneratedLoop):
    """Each instance in the plan's order: its inputs, its step, its outputs."""

    def body(self, s: "LoopSource", ios: list[InstanceIO], ind: str) -> None:
        for i, io in enumerate(ios):
            s.inputs(i, io, ind)
            s.step(i, io, ind)
            s.outputs(i, io, ind)


class Jacobi(GeneratedLoop):
    """Every instance's inputs, then every step, then every output."""

    simultaneous = True

    def body(self, s: "LoopSource", ios: list[InstanceIO], ind: str) -> None:
        for i, io in enumerate(ios):
            s.inputs(i, io, ind)
        for i, io in enumerate(ios):
            s.step(i, io, ind)
        for i, io in enumerate(ios):
            s.outputs(i, io, ind)


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

    def instance(self, i: int, io: InstanceIO) -> None:
        """Instance i's calls and arrays bound as locals (``name_i``, ``c_i``, ``setr_i``, ...)."""
        f = io.fast
        self.env.update({f"name_{i}": io.name, f"c_{i}": f.c, f"setr_{i}": f.set_real, f"dostep_{i}": f.do_step,
                         f"getr_{i}": f.get_real, f"invr_{i}": io.in_vr, f"in_{i}": f.in_val, f"nin_{i}": io.n_in,
                         f"outvr_{i}": io.out_vr, f"out_{i}": io.out_val, f"nout_{i}": io.n_out})

    def inputs(self, i: int, io: InstanceIO, ind: str, when: str = "", given: bool = False) -> None:
        """Step k's inputs of instance i: tables, copies (checked), the set, the other connections.
        ``when``: what a failure carries after the status (", t": the time, off the grid); ``given``: a
        dict ``given`` (position -> value) replaces copies' values where it has one."""
        if io.feed is not None:
            self.w(f"{ind}s = {self.bind(f'feed_{i}', io.feed)}(k)")
            self.w(f"{ind}if s: return Failure(k, name_{i}, Call.TABLE_INPUTS, s{when})")
        names = []
        for j, (pos, arr, idx, f, o) in enumerate(io.copies):
            a, x = self.bind(f"src_{i}_{j}", arr), self.bind(f"idx_{i}_{j}", idx)
            if f == 1.0 and o == 0.0:
                self.w(f"{ind}v{j} = {a}[{x}]")
            else:
                self.w(f"{ind}v{j} = {a}[{x}] * {self.bind(f'f_{i}_{j}', f)} + {self.bind(f'o_{i}_{j}', o)}")
            names.append(f"v{j}")
        if names and given:
            self.w(f"{ind}if given is not None:")
            for j, (pos, *_rest) in enumerate(io.copies):
                self.w(f"{ind}    v{j} = given.get({self.bind(f'pos_{i}_{j}', pos)}, v{j})")
        if names and self.check_inputs:  # one test for all: a sum is non-finite if any term is (or it overflows)
            self.w(f"{ind}x = {' + '.join(names)}")
            self.w(f"{ind}if x - x != 0.0: return Failure(k, name_{i}, Call.NON_FINITE_INPUT, x{when})")
        for j, (pos, *_rest) in enumerate(io.copies):
            self.w(f"{ind}in_{i}[{self.bind(f'pos_{i}_{j}', pos)}] = v{j}")
        if io.copies:
            self.w(f"{ind}s = setr_{i}(c_{i}, invr_{i}, nin_{i}, in_{i}{self.args('sa', i, io.fast.set_tail)})")
            self.w(f"{ind}if s: return Failure(k, name_{i}, Call.SET_REAL, s{when})")
        for j, fn in enumerate(io.other):
            self.w(f"{ind}s = {self.bind(f'other_{i}_{j}', fn)}()")
            self.w(f"{ind}if s: return Failure(k, name_{i}, Call.CONNECTION, s{when})")

    def step(self, i: int, io: InstanceIO, ind: str, when: str = "", note_end: bool = True) -> None:
        """The step of instance i from ``Tv`` over ``H``; an FMU that ended the simulation in it is noted
        (``note_end``: in ``ended``)."""
        self.w(f"{ind}s = dostep_{i}(c_{i}, Tv, H{self.args('da', i, io.fast.step_tail)})")
        self.w(f"{ind}if s: return Failure(k, name_{i}, Call.DO_STEP, s{when})")
        if note_end and io.fast.terminated is not None:
            term, last = self.bind(f"term_{i}", io.fast.terminated), self.bind(f"last_{i}", io.fast.last_time)
            self.w(f"{ind}if {term}.value: ended = (name_{i}, {last}.value)")

    def outputs(self, i: int, io: InstanceIO, ind: str, when: str = "") -> None:
        """Instance i's Float64 outputs at t_{k+1} into the row."""
        if io.n_out.value:
            self.w(f"{ind}s = getr_{i}(c_{i}, outvr_{i}, nout_{i}, out_{i}{self.args('ga', i, io.fast.get_tail)})")
            self.w(f"{ind}if s: return Failure(k + 1, name_{i}, Call.GET_REAL, s{when})")

    def take(self) -> list[str]:
        """The lines written so far, the source left empty."""
        lines, self.lines = self.lines, []
        return lines

    def function(self, head: str, body: list[str]) -> None:
        """``def NAME(ARGS, *, <every bound value>=...)``: the bound values become keyword defaults, fast
        locals inside it."""
        self.w(f"def {head}, *, {', '.join(f'{n}={n}' for n in self.env)}):")
        self.lines += body
        self.w("    return None")

    def compiled(self, *names: str) -> list[Callable[..., Any]]:
        """The functions written, compiled (each keeps the whole source as ``source``)."""
        src = "\n".join(self.lines)
        env = dict(self.env)
        exec(compile(src, "<cosim-loop>", "exec"), env)
        out = [env[n] for n in names]
        for fn in out:
            fn.source = src   # (a function object takes attributes: the source, for reading and tests)
        return out

    def done(self, ios: list[InstanceIO]) -> None:
        """The run told that t_{k+1} is reached (the recording takes its row there); then the end of a
        simulation an FMU ended in the step."""
        if not any(io.fast.terminated is not None for io in ios):
            self.w("        s = done(k + 1, False)")
            self.w("        if s is not None: return s")
            return
        self.w("        s = done(k + 1, ended is not None)")
        self.w("        if s is not None: return s")
        self.w("        if ended is not None: return Failure(k + 1, ended[0], Call.TERMINATED, ended[1])")


def compile_loop(ios: list[InstanceIO], body: Callable[[LoopSource, list[InstanceIO], str], None], clock: Clock,
                 done: StepDone, check_inputs: bool = True) -> Callable[[int, int], Failure | None]:
    """Generate and compile the loop ``loop(k0, k1)`` whose step is what ``body`` writes."""
    s = LoopSource(check_inputs)
    s.env.update({"done": done, "T": ctypes.c_double(0.0), "Failure": Failure, "Call": Call,
                  "H": ctypes.c_double(clock.step), "t0": float(clock.start), "h": float(clock.step)})
    for i, io in enumerate(ios):
        s.instance(i, io)
    body(s, ios, "        ")
    short = clock.stop is not None
    if short:   # the last step is short (only then is this compared at every step)
        s.env.update({"k_last": clock.n_steps - 1, "h_last": float(clock.length(clock.n_steps - 1))})
    s.done(ios)
    step_lines = s.take()
    s.function("loop(k0, k1", ["    Tv = T", "    ended = None", "    for k in range(k0, k1):",
                               "        Tv.value = t0 + k * h"]
               + (["        H.value = h_last if k == k_last else h"] if short else []) + step_lines)
    loop, = s.compiled("loop")
    return loop


def compile_instance(i: int, io: InstanceIO, T: ctypes.c_double, H: ctypes.c_double, check_inputs: bool = True
                     ) -> tuple[Callable[..., Failure | None], Callable[..., Failure | None],
                                Callable[..., Failure | None]]:
    """One instance's part of a step, written as the generated loop writes it (:class:`LoopSource`: the one
    definition of a step's work), as three functions for the algorithms that take steps one instance at a
    time, at any time and step size: ``inputs(k, t, given=None)``, ``step(k, t, h)`` (through the shared
    ``T``, ``H``) and ``outputs(k, t)``; a failure carries the time t [s] it came at."""
    s = LoopSource(check_inputs)
    s.env.update({"Failure": Failure, "Call": Call, "Tv": T, "H": H})
    s.instance(i, io)
    s.inputs(i, io, "    ", ", t", given=True)
    inputs = s.take()
    s.w("    Tv.value = t")
    s.w("    H.value = h")
    s.step(i, io, "    ", ", t", note_end=False)
    step = s.take()
    s.outputs(i, io, "    ", ", t")
    outputs = s.take()
    # (the bodies first, then the functions: each binds every value bound while any body was written)
    s.function("inputs(k, t, given=None", inputs)
    s.function("step(k, t, h", step)
    s.function("outputs(k, t", outputs)
    fn_inputs, fn_step, fn_outputs = s.compiled("inputs", "step", "outputs")
    return fn_inputs, fn_step, fn_outputs
