"""The wiring (libcosim's manipulators): where each input the master sets takes its value from.

A Real input set by the master is fed by an output in the row buffer through ``value_in = factor *
value_out + offset`` (the connection's unit conversion and linear transform folded into one factor and
offset), or holds a start value until an event overrides it.  Events override, bias or reset inputs and
outputs; a bias on an output acts before the connection's transform.  Integer, Boolean and Enumeration
connections are copied with a get and a set per step.

The row buffer (one float64 per slot): time, then each instance's Real outputs that are connected or
recorded, in the plan's order, then the recorded Integer/Boolean/Enumeration outputs.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .errors import RunError
from .instance import Instance, raw, real_array, vr_array
from .inputs import InputPlan
from .system import ConnectionPlan, EventPlan, Plan

#: (position in the instance's input array, source array, index in it, factor, offset)
Copy = tuple[int, Any, int, float, float]


@dataclass
class RowLayout:
    """Where each value lives in the row buffer."""

    reals: dict[str, list[int]]          # instance -> value references of its Real outputs in the row
    offset: dict[str, int]               # instance -> first slot of its Real outputs
    n_real: int                          # slots of time and Real outputs
    extra: list[Any]                     # recorded non-Real outputs (RecordPlan), after the Reals
    row: Any = None                      # the ctypes double array
    out_arr: dict[str, Any] = field(default_factory=dict)   # instance -> view of its Real outputs

    @classmethod
    def of(cls, plan: Plan) -> "RowLayout":
        reals: dict[str, list[int]] = {n: [] for n in plan.order}
        for c in plan.connections:
            if c.src_var.type == "Real" and c.src_var.vr not in reals[c.src]:
                reals[c.src].append(c.src_var.vr)
        for r in plan.record:
            if r.var.type == "Real" and r.var.vr not in reals[r.instance]:
                reals[r.instance].append(r.var.vr)
        offset, pos = {}, 1
        for n in plan.order:
            offset[n] = pos
            pos += len(reals[n])
        lay = cls(reals, offset, pos, [r for r in plan.record if r.var.type != "Real"])
        lay.row = (ctypes.c_double * (pos + len(lay.extra)))()
        lay.out_arr = {n: (ctypes.c_double * len(reals[n])).from_buffer(lay.row, offset[n] * 8) for n in plan.order}
        return lay

    def slot(self, rec: Any) -> int:
        """The row slot of a recorded variable (RecordPlan)."""
        if rec.var.type == "Real":
            return self.offset[rec.instance] + self.reals[rec.instance].index(rec.var.vr)
        return self.n_real + self.extra.index(rec)


class Wiring:
    """Every Real input set by the master, its source, and the overrides that events have put in force."""

    def __init__(self, plan: Plan, layout: RowLayout) -> None:
        self.plan = plan
        self.vrs: dict[str, list[int]] = {n: [] for n in plan.order}
        self.base: dict[tuple[str, int], Copy] = {}
        self.feeds: dict[tuple[str, int], tuple[str, int]] = {}     # (inst, pos) -> output (inst, vr)
        for c in plan.connections:
            if not is_real(c):
                continue
            pos = self._pos(c.dst, c.dst_var.vr)
            src = layout.out_arr[c.src], layout.reals[c.src].index(c.src_var.vr)
            self.base[(c.dst, pos)] = (pos, *src, c.factor, c.offset)
            self.feeds[(c.dst, pos)] = (c.src, c.src_var.vr)
        self.tables: dict[str, tuple[Any, np.ndarray]] = {}   # instance -> (array the copies read, values)
        for inst in plan.order:  # tabulated Real inputs: sources refreshed before each step
            cols = [ip for ip in plan.inputs if ip.instance == inst and ip.var.type == "Real"]
            if cols:
                arr = (ctypes.c_double * len(cols))()
                for j, ip in enumerate(cols):
                    pos = self._pos(inst, ip.var.vr)
                    self.base[(inst, pos)] = (pos, arr, j, 1.0, 0.0)
                self.tables[inst] = (arr, np.ascontiguousarray(np.column_stack([ip.values for ip in cols])))
        for ev in plan.events:  # an unconnected input driven by events holds its start value until overridden
            if ev.var.causality != "input" or ev.var.type != "Real":
                continue
            key = (ev.instance, self._pos(ev.instance, ev.var.vr))
            if key not in self.base:
                self.base[key] = (key[1], real_array([float(_start(plan, ev))]), 0, 1.0, 0.0)
        self.overrides: dict[tuple[str, int, str], tuple[str, float]] = {}

    def _pos(self, inst: str, vr: int) -> int:
        vrs = self.vrs[inst]
        if vr not in vrs:
            vrs.append(vr)
        return vrs.index(vr)

    def apply(self, ev: EventPlan) -> None:
        """Put an event's action in force (override, bias on top of an earlier one, or reset)."""
        key = (ev.instance, ev.var.vr, ev.var.causality)
        if ev.action == "reset":
            self.overrides.pop(key, None)
            return
        prev = self.overrides.get(key)
        if ev.action == "bias" and prev is not None:   # on top of an earlier override or bias
            self.overrides[key] = (prev[0], prev[1] + float(ev.value))
        else:
            self.overrides[key] = (ev.action, float(ev.value))

    def copies(self, inst: str) -> list[Copy]:
        """The copies that set ``inst``'s Real inputs, with the overrides in force."""
        out = []
        for pos, vr in enumerate(self.vrs[inst]):
            _, arr, i, f, o = self.base[(inst, pos)]
            ov = self.overrides.get((inst, vr, "input"))
            if ov is None and (inst, pos) in self.feeds:
                src, svr = self.feeds[(inst, pos)]
                ov = self.overrides.get((src, svr, "output"))
                if ov is not None and ov[0] == "bias":  # a bias on the output, before the connection's transform
                    ov = ("bias", ov[1] * f)
            if ov is None:
                out.append((pos, arr, i, f, o))
            elif ov[0] == "override":
                out.append((pos, real_array([ov[1]]), 0, 1.0, 0.0))
            else:
                out.append((pos, arr, i, f, o + ov[1]))
        return out

    def bad_input(self, name: str, in_vr: Any, copies: list[Copy], t: float) -> RunError:
        """The first non-finite value about to be set on an input of ``name``, named with the output that
        produced it (or an overflow of their sum, reported as such)."""
        ip = self.plan.instances[name]
        by_vr = {v.vr: v for v in ip.model.variables.values()}
        vrs = list(in_vr)
        for pos, arr, i, f, o in copies:
            v = arr[i] * f + o if (f != 1.0 or o != 0.0) else arr[i]
            if v - v != 0.0:
                var = by_vr.get(vrs[pos])
                label = f"{name}.{ip.our_name(var)}" if var is not None else f"{name} input {vrs[pos]}"
                src = self.feeds.get((name, pos))
                origin = ""
                if src is not None:
                    sp = self.plan.instances[src[0]]
                    svar = next(v for v in sp.model.variables.values() if v.vr == src[1] and v.causality == "output")
                    origin = f"{src[0]}.{sp.our_name(svar)} produced {arr[i]!r}; "
                return RunError(f"{origin}{label} would receive the non-finite value {v!r} at t = {t:.6g} s",
                                src[0] if src else name, t)
        return RunError(f"{name}: the inputs' values overflow (their sum is not finite) at t = {t:.6g} s", name, t)


def _start(plan: Plan, ev: EventPlan) -> float:
    start = ev.var.start if ev.var.start is not None else 0.0
    for v, val in plan.instances[ev.instance].parameters:
        if v.vr == ev.var.vr:
            start = val
    return start


def table_feeder(inst: Instance, table: tuple[Any, np.ndarray] | None, discrete: list[InputPlan]
                 ) -> Callable[[int], int] | None:
    """A closure that puts the tabulated inputs of step k in place: the Real values where the copies read
    them, the others set on the FMU (Integer, Enumeration, Boolean with one call per type; String)."""
    if table is None and not discrete:
        return None
    steps: list[Callable[[int], int]] = []
    if table is not None:
        view = np.ctypeslib.as_array(table[0])
        values = table[1]

        def reals(k: int) -> int:
            view[:] = values[k]
            return 0
        steps.append(reals)
    c = ctypes.c_void_p(inst.c)
    for kind, types in (("Integer", ("Integer", "Enumeration")), ("Boolean", ("Boolean",))):
        cols = [ip for ip in discrete if ip.var.type in types]
        if cols:
            vrs, buf, n = vr_array([ip.var.vr for ip in cols]), (ctypes.c_int * len(cols))(), ctypes.c_size_t(len(cols))
            mat = np.column_stack([ip.values.astype(np.int64) for ip in cols]).tolist()
            put = raw(inst.fmu.dll, f"fmi2Set{kind}")

            def ints(k: int, put=put, vrs=vrs, buf=buf, n=n, mat=mat) -> int:
                buf[:] = mat[k]
                return put(c, vrs, n, buf)
            steps.append(ints)
    strings = [ip for ip in discrete if ip.var.type == "String"]
    if strings:
        vrs_s = vr_array([ip.var.vr for ip in strings])
        put_s = raw(inst.fmu.dll, "fmi2SetString")
        mat_s = [[str(v).encode("utf-8") for v in row] for row in zip(*(ip.values for ip in strings))]
        sbuf = (ctypes.c_char_p * len(strings))()
        ns = ctypes.c_size_t(len(strings))

        def texts(k: int) -> int:
            sbuf[:] = mat_s[k]
            return put_s(c, vrs_s, ns, sbuf)
        steps.append(texts)
    if len(steps) == 1:
        return steps[0]

    def feed(k: int) -> int:
        for f in steps:
            s = f(k)
            if s:
                return s
        return 0
    return feed


def is_real(c: ConnectionPlan) -> bool:
    """A Real -> Real connection (a copy in the generated loop); the others are copied by closures."""
    return c.src_var.type == "Real" and c.dst_var.type == "Real"


def discrete_copier(instances: dict[str, Instance], c: ConnectionPlan) -> Callable[[], int]:
    """A closure copying one output to an input with a get and a set: Integer, Enumeration, Boolean and
    String as they are; Boolean -> Real as 0 or 1 through the factor and offset; Real -> Boolean as
    value > threshold."""
    src, dst = instances[c.src], instances[c.dst]
    svr, dvr = vr_array([c.src_var.vr]), vr_array([c.dst_var.vr])
    one = ctypes.c_size_t(1)
    sc, dc = ctypes.c_void_p(src.c), ctypes.c_void_p(dst.c)
    kinds = {"Real": ("Real", ctypes.c_double), "Integer": ("Integer", ctypes.c_int),
             "Enumeration": ("Integer", ctypes.c_int), "Boolean": ("Boolean", ctypes.c_int),
             "String": ("String", ctypes.c_char_p)}
    (gk, gt), (pk, pt) = kinds[c.src_var.type], kinds[c.dst_var.type]
    get, put = raw(src.fmu.dll, f"fmi2Get{gk}"), raw(dst.fmu.dll, f"fmi2Set{pk}")
    ibuf, obuf = (gt * 1)(), (pt * 1)()
    if gt is pt:
        def copy() -> int:
            return get(sc, svr, one, ibuf) or put(dc, dvr, one, ibuf)
        return copy
    f, o, threshold = c.factor, c.offset, c.spec.threshold

    def convert() -> int:
        s = get(sc, svr, one, ibuf)
        if s:
            return s
        obuf[0] = (1.0 if ibuf[0] else 0.0) * f + o if pk == "Real" else int(ibuf[0] > threshold)
        return put(dc, dvr, one, obuf)
    return convert
