"""The algorithm: the order of work in a communication step (Gauss-Seidel or Jacobi), nothing else.

Per step k (t_k = start + k h; time is always computed as start + k h, never accumulated):
  * Gauss-Seidel, in the plan's order: for each instance, set its inputs from the current values of the
    outputs connected to them (an instance later in the order sees the outputs its predecessors produced
    in this step), do the step, get its outputs.
  * Jacobi: set every instance's inputs from the outputs of the previous step, step all, get all.

The loop is generated for one plan as straight-line Python: every array, function, index and number is
bound as a local of the generated function (never formatted into its source), and the FMI functions are
raw ctypes calls without per-argument conversion.  Measured on the G1 system, this is faster than a plain
loop over the instances making the same calls (see docs/architecture.md).

``loop(k0, k1)`` advances the system from step k0 to k1 and returns None, or a tuple
(k, instance, what, status_or_value) at the first non-OK status or non-finite connected value.  It
appends one row (``bytes`` of the row buffer) per recorded step to ``chunk``.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import Any, Callable

from .failure import Call, Failure


@dataclass
class InstanceIO:
    """What the loop does with one instance each step."""

    name: str
    c: Any                                  # c_void_p of the instance
    set_real: Any                           # raw fmi2SetReal / fmi3SetFloat64 (no argtypes)
    do_step: Any                            # raw fmi2DoStep / fmi3DoStep
    get_real: Any                           # raw fmi2GetReal / fmi3GetFloat64
    in_vr: Any                              # c_uint array
    in_val: Any                             # c_double array
    n_in: Any                               # c_size_t: value references
    out_vr: Any
    out_val: Any                            # a view into the row buffer
    n_out: Any
    copies: list[tuple[int, Any, int, float, float]] = field(default_factory=list)  # (pos, src array, idx, f, o)
    extras: list[tuple[Any, Any, Any, Any, Any, list[tuple[int, int]]]] = field(default_factory=list)
    # recorded outputs other than Float64: (get(vrs, n, buf, nv), vrs, n, buf, nv, [(index in buf, slot)])
    other: list[Callable[[], int]] = field(default_factory=list)  # connections other than Float64 -> Float64
    feed: Callable[[int], int] | None = None       # tabulated inputs of step k (wiring.table_feeder)
    fmi: int = 2
    nv_in: Any = None                       # c_size_t: values (FMI 3.0 arrays)
    nv_out: Any = None


class _Source:
    """The generated function's source and the values it binds as locals."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.env: dict[str, Any] = {}

    def bind(self, name: str, value: Any) -> str:
        self.env[name] = value
        return name

    def w(self, line: str) -> None:
        self.lines.append(line)


def _copies(s: _Source, i: int, io: InstanceIO, ind: str, check_inputs: bool) -> None:
    if io.feed is not None:
        s.w(f"{ind}s = {s.bind(f'feed_{i}', io.feed)}(k)")
        s.w(f"{ind}if s: return Failure(k, name_{i}, Call.TABLE_INPUTS, s, {io.fmi})")
    names = []
    for j, (pos, arr, idx, f, o) in enumerate(io.copies):
        a, x = s.bind(f"src_{i}_{j}", arr), s.bind(f"idx_{i}_{j}", idx)
        if f == 1.0 and o == 0.0:
            s.w(f"{ind}v{j} = {a}[{x}]")
        else:
            s.w(f"{ind}v{j} = {a}[{x}] * {s.bind(f'f_{i}_{j}', f)} + {s.bind(f'o_{i}_{j}', o)}")
        names.append(f"v{j}")
    if names and check_inputs:  # one test for all: a sum is non-finite if any term is (or it overflows)
        s.w(f"{ind}x = {' + '.join(names)}")
        s.w(f"{ind}if x - x != 0.0: return Failure(k, name_{i}, Call.NON_FINITE_INPUT, x, {io.fmi})")
    for j, (pos, *_rest) in enumerate(io.copies):
        s.w(f"{ind}in_{i}[{s.bind(f'pos_{i}_{j}', pos)}] = v{j}")
    if io.copies:
        nv = f", nvin_{i}" if io.fmi == 3 else ""
        s.w(f"{ind}s = setr_{i}(c_{i}, invr_{i}, nin_{i}, in_{i}{nv})")
        s.w(f"{ind}if s: return Failure(k, name_{i}, Call.SET_REAL, s, {io.fmi})")
    for j, fn in enumerate(io.other):
        s.w(f"{ind}s = {s.bind(f'other_{i}_{j}', fn)}()")
        s.w(f"{ind}if s: return Failure(k, name_{i}, Call.CONNECTION, s, {io.fmi})")


def _step(s: _Source, i: int, io: InstanceIO, ind: str) -> None:
    if io.fmi == 2:
        s.w(f"{ind}s = dostep_{i}(c_{i}, Tv, H, 1)")
        s.w(f"{ind}if s: return Failure(k, name_{i}, Call.DO_STEP, s, 2)")
        return
    # FMI 3.0: event (unused: no event mode), terminateSimulation, earlyReturn (not allowed), lastSuccessfulTime
    flags = [ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()]
    s.bind(f"term_{i}", flags[1]), s.bind(f"last_{i}", flags[3])
    refs = ", ".join(s.bind(f"ref{j}_{i}", ctypes.byref(f)) for j, f in enumerate(flags))
    s.w(f"{ind}s = dostep_{i}(c_{i}, Tv, H, True, {refs})")
    s.w(f"{ind}if s: return Failure(k, name_{i}, Call.DO_STEP, s, 3)")
    s.w(f"{ind}if term_{i}.value: ended = (name_{i}, last_{i}.value)")


def _get(s: _Source, i: int, io: InstanceIO, ind: str) -> None:
    if io.n_out.value:
        nv = f", nvout_{i}" if io.fmi == 3 else ""
        s.w(f"{ind}s = getr_{i}(c_{i}, outvr_{i}, nout_{i}, out_{i}{nv})")
        s.w(f"{ind}if s: return Failure(k + 1, name_{i}, Call.GET_REAL, s, {io.fmi})")


def _record(s: _Source, ios: list[InstanceIO], dec: int, n_double: int) -> None:
    fmi3 = any(io.fmi == 3 for io in ios)
    if dec > 1:
        s.w(f"        if (k + 1) % dec == 0 or k + 1 == n_steps{' or ended is not None' if fmi3 else ''}:")
    else:
        s.w("        if True:")
    s.w("            row[0] = t0 + (k + 1) * h")
    for i, io in enumerate(ios):
        for j, (get, vrs, n, buf, nv, slots) in enumerate(io.extras):
            names = [s.bind(f"x{w}_{i}_{j}", x) for w, x in zip("gvnbc", (get, vrs, n, buf, nv))]
            s.w(f"            s = {names[0]}({', '.join(names[1:])})")
            s.w(f"            if s: return Failure(k + 1, name_{i}, Call.GET_RECORDED, s, {io.fmi})")
            for e, slot in slots:
                target = f"row[{s.bind(f'xs_{i}_{j}_{e}', slot)}]" if slot < n_double else \
                    f"irow[{s.bind(f'xs_{i}_{j}_{e}', slot - n_double)}]"
                s.w(f"            {target} = {names[3]}[{s.bind(f'xe_{i}_{j}_{e}', e)}]")
    s.w("            append(bytes(buf))")
    if fmi3:  # an FMI 3.0 FMU ended the simulation in this step: its row is recorded, then stop
        s.w("        if ended is not None: return Failure(k + 1, ended[0], Call.TERMINATED, ended[1], 3)")


def compile_loop(ios: list[InstanceIO], algorithm: str, t0: float, h: float, dec: int, n_steps: int, layout: Any,
                 chunk: list[bytes], check_inputs: bool = True) -> Callable[[int, int], Any]:
    """Generate and compile the loop for the instances in order; ``layout`` is the row buffer's
    (wiring.RowLayout: ``buf``, its doubles ``row`` and integers ``irow``, ``n_double``)."""
    s = _Source()
    s.env.update({"row": layout.row, "irow": layout.irow, "buf": layout.buf, "append": chunk.append,
                  "bytes": bytes, "T": ctypes.c_double(0.0), "Failure": Failure, "Call": Call,
                  "H": ctypes.c_double(h), "t0": float(t0), "h": float(h), "dec": int(dec), "n_steps": int(n_steps)})
    for i, io in enumerate(ios):
        s.env.update({f"name_{i}": io.name, f"c_{i}": io.c, f"setr_{i}": io.set_real, f"dostep_{i}": io.do_step,
                      f"getr_{i}": io.get_real, f"invr_{i}": io.in_vr, f"in_{i}": io.in_val, f"nin_{i}": io.n_in,
                      f"outvr_{i}": io.out_vr, f"out_{i}": io.out_val, f"nout_{i}": io.n_out,
                      f"nvin_{i}": io.nv_in, f"nvout_{i}": io.nv_out})
    ind = "        "
    body = _Source()
    body.env = s.env
    if algorithm == "jacobi":
        for i, io in enumerate(ios):
            _copies(body, i, io, ind, check_inputs)
        for i, io in enumerate(ios):
            _step(body, i, io, ind)
        for i, io in enumerate(ios):
            _get(body, i, io, ind)
    else:
        for i, io in enumerate(ios):
            _copies(body, i, io, ind, check_inputs)
            _step(body, i, io, ind)
            _get(body, i, io, ind)
    _record(body, ios, dec, layout.n_double)
    # every bound value becomes a keyword default: a fast local inside the loop
    s.w(f"def loop(k0, k1, *, {', '.join(f'{n}={n}' for n in s.env)}):")
    s.w("    Tv = T")
    s.w("    ended = None")
    s.w("    for k in range(k0, k1):")
    s.w("        Tv.value = t0 + k * h")
    s.lines += body.lines
    s.w("    return None")
    src = "\n".join(s.lines)
    env = dict(s.env)
    exec(compile(src, "<cosim-loop>", "exec"), env)
    loop = env["loop"]
    loop.source = src  # type: ignore[attr-defined]
    return loop
