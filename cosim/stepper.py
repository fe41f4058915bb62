"""The stepping loop, generated for one plan: straight-line Python with every array, function and
index bound as a local, raw ctypes calls without per-argument conversion.

The generated function ``loop(k0, k1)`` advances the system from step k0 to k1 and returns None, or a
tuple (k, instance, what, status_or_value) at the first non-OK status or non-finite connected value.
It appends one row (``bytes`` of the row buffer) per recorded step to ``chunk``.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import Any, Callable


@dataclass
class InstanceIO:
    """What the loop does with one instance each step."""

    name: str
    c: Any                                  # c_void_p of the instance
    set_real: Any                           # raw fmi2SetReal (no argtypes)
    do_step: Any
    get_real: Any
    get_integer: Any
    get_boolean: Any
    in_vr: Any                              # c_uint array
    in_val: Any                             # c_double array
    n_in: Any                               # c_size_t
    out_vr: Any
    out_val: Any                            # a view into the row buffer
    n_out: Any
    copies: list[tuple[int, Any, int, float, float]] = field(default_factory=list)  # (pos, src array, idx, f, o)
    rec_int: tuple[Any, Any, Any, list[int]] | None = None   # (vr array, int buffer, n, row slots)
    rec_bool: tuple[Any, Any, Any, list[int]] | None = None
    other: list[Callable[[], int]] = field(default_factory=list)  # Integer/Boolean connections


def raw(dll: Any, name: str) -> Any:
    """A fresh ctypes function for ``name`` without argtypes (FMPy's copy carries converting argtypes)."""
    f = dll[name]
    f.restype = ctypes.c_int
    return f


def compile_loop(ios: list[InstanceIO], algorithm: str, t0: float, h: float, dec: int, n_steps: int, row: Any,
                 chunk: list[bytes], check_inputs: bool = True) -> Callable[[int, int], Any]:
    """Generate and compile the loop for the instances in order."""
    env: dict[str, Any] = {"row": row, "append": chunk.append, "bytes": bytes, "c_double": ctypes.c_double,
                           "T": ctypes.c_double(0.0), "H": ctypes.c_double(h)}
    L: list[str] = []
    w = L.append
    w("def loop(k0, k1):")
    w("    Tv = T")
    w("    for k in range(k0, k1):")
    w(f"        t = {t0!r} + k * {h!r}")
    w("        Tv.value = t")

    def copies(i: int, io: InstanceIO, ind: str) -> None:
        names = []
        for j, (pos, arr, idx, f, o) in enumerate(io.copies):
            a = f"src_{i}_{j}"
            env[a] = arr
            expr = f"{a}[{idx}]" if (f == 1.0 and o == 0.0) else f"{a}[{idx}] * {f!r} + {o!r}"
            w(f"{ind}v{j} = {expr}")
            names.append(f"v{j}")
        if names and check_inputs:  # one test for all: a sum is non-finite if any term is (or it overflows)
            w(f"{ind}x = {' + '.join(names)}")
            w(f"{ind}if x - x != 0.0: return (k, {io.name!r}, 'inputs', x)")
        for j, (pos, *_rest) in enumerate(io.copies):
            w(f"{ind}in_{i}[{pos}] = v{j}")
        if io.copies:
            w(f"{ind}s = setr_{i}(c_{i}, invr_{i}, nin_{i}, in_{i})")
            w(f"{ind}if s: return (k, {io.name!r}, 'fmi2SetReal', s)")
        for j, _ in enumerate(io.other):
            w(f"{ind}s = other_{i}_{j}()")
            w(f"{ind}if s: return (k, {io.name!r}, 'fmi2SetInteger/Boolean', s)")

    def step(i: int, io: InstanceIO, ind: str) -> None:
        w(f"{ind}s = dostep_{i}(c_{i}, Tv, H, 1)")
        w(f"{ind}if s: return (k, {io.name!r}, 'fmi2DoStep', s)")

    def get(i: int, io: InstanceIO, ind: str) -> None:
        w(f"{ind}s = getr_{i}(c_{i}, outvr_{i}, nout_{i}, out_{i})")
        w(f"{ind}if s: return (k + 1, {io.name!r}, 'fmi2GetReal', s)")

    for i, io in enumerate(ios):
        env.update({f"c_{i}": io.c, f"setr_{i}": io.set_real, f"dostep_{i}": io.do_step, f"getr_{i}": io.get_real,
                    f"invr_{i}": io.in_vr, f"in_{i}": io.in_val, f"nin_{i}": io.n_in, f"outvr_{i}": io.out_vr,
                    f"out_{i}": io.out_val, f"nout_{i}": io.n_out, f"geti_{i}": io.get_integer,
                    f"getb_{i}": io.get_boolean})
        for j, fn in enumerate(io.other):
            env[f"other_{i}_{j}"] = fn
    if algorithm == "jacobi":
        for i, io in enumerate(ios):
            copies(i, io, "        ")
        for i, io in enumerate(ios):
            step(i, io, "        ")
        for i, io in enumerate(ios):
            if io.n_out.value:
                get(i, io, "        ")
    else:
        for i, io in enumerate(ios):
            copies(i, io, "        ")
            step(i, io, "        ")
            if io.n_out.value:
                get(i, io, "        ")
    # recording
    w(f"        if (k + 1) % {dec} == 0 or k + 1 == {n_steps}:" if dec > 1 else "        if True:")
    w(f"            row[0] = {t0!r} + (k + 1) * {h!r}")
    for i, io in enumerate(ios):
        for kind, spec, getter in (("int", io.rec_int, f"geti_{i}"), ("bool", io.rec_bool, f"getb_{i}")):
            if spec is None:
                continue
            vr, buf, n, slots = spec
            env[f"{kind}vr_{i}"], env[f"{kind}buf_{i}"], env[f"{kind}n_{i}"] = vr, buf, n
            w(f"            s = {getter}(c_{i}, {kind}vr_{i}, {kind}n_{i}, {kind}buf_{i})")
            w(f"            if s: return (k + 1, {io.name!r}, 'fmi2Get{kind.capitalize()}', s)")
            for j, slot in enumerate(slots):
                w(f"            row[{slot}] = {kind}buf_{i}[{j}]")
    w("            append(bytes(row))")
    w("    return None")
    src = "\n".join(L)
    code = compile(src, "<cosim-loop>", "exec")
    exec(code, env)
    loop = env["loop"]
    loop.source = src  # type: ignore[attr-defined]
    return loop
