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

from ..instances.contract import FmuInstance
from ..instances.in_process import real_array, vr_array
from ..messages.errors import RunError
from ..model.description import Variable
from ..scenario.inputs import InputPlan
from ..stepping.algorithm import Copy, Doubles
from ..stepping.graph import FeedGraph
from .feeds import feed_graph
from .records import ConnectionPlan, EventPlan, Plan, RecordPlan



@dataclass
class RowLayout:
    """Where each value lives in the row buffer: doubles first (time, each instance's Float64 outputs that
    are connected or recorded, then the other recorded reals), then 64-bit integers (recorded integers,
    enumerations and booleans).  A slot numbers the doubles from 0 and the integers after them."""

    reals: dict[str, list[tuple[int, int]]]   # instance -> (vr, number of values) of its Float64 outputs
    offset: dict[str, int]                     # instance -> first slot of its Float64 outputs
    n_real: int                                # slots of time and Float64 outputs
    extra: list[RecordPlan]                    # recorded outputs that are not Float64
    n_double: int = 0
    n_int: int = 0
    buf: ctypes.Array[ctypes.c_byte] = field(init=False)     # the raw bytes of the row (set by of)
    row: Doubles = field(init=False)                         # its doubles (ctypes view)
    irow: ctypes.Array[ctypes.c_int64] = field(init=False)   # its integers (ctypes view)
    out_arr: dict[str, Doubles] = field(default_factory=dict)   # instance -> view of its Float64 outputs
    extra_slot: dict[int, int] = field(default_factory=dict)  # id(RecordPlan) -> slot

    @classmethod
    def of(cls, plan: Plan) -> "RowLayout":
        reals: dict[str, list[tuple[int, int]]] = {n: [] for n in plan.order}

        def add(inst: str, var: Variable) -> None:
            if var.is_float64 and (var.vr, var.size) not in reals[inst]:
                reals[inst].append((var.vr, var.size))
        for c in plan.connections:
            add(c.src, c.src_var)
        for r in plan.record:
            add(r.instance, r.var)
        for inst, var in plan.watched:   # outputs the events' conditions read
            if var.causality == "output":
                add(inst, var)
        offset, pos = {}, 1
        for n in plan.order:
            offset[n] = pos
            pos += sum(size for _, size in reals[n])
        lay = cls(reals, offset, pos, [r for r in plan.record if not r.var.is_float64])
        floats = [r for r in lay.extra if r.var.type == "Real"]
        ints = [r for r in lay.extra if r.var.type != "Real"]
        lay.n_double, lay.n_int = pos + len(floats), len(ints)
        lay.extra_slot = {id(r): pos + j for j, r in enumerate(floats)}
        lay.extra_slot.update({id(r): lay.n_double + j for j, r in enumerate(ints)})
        lay.buf = (ctypes.c_byte * (8 * (lay.n_double + lay.n_int)))()
        lay.row = (ctypes.c_double * lay.n_double).from_buffer(lay.buf)
        lay.irow = (ctypes.c_int64 * max(1, lay.n_int)).from_buffer(lay.buf, 8 * lay.n_double) if lay.n_int \
            else (ctypes.c_int64 * 1)()
        lay.out_arr = {n: (ctypes.c_double * sum(sz for _, sz in reals[n])).from_buffer(
            lay.buf, offset[n] * 8) for n in plan.order}
        return lay

    def index(self, inst: str, vr: int, elem: int = 0) -> int:
        """The position of a Float64 output's value in ``out_arr[inst]``."""
        i = 0
        for v, size in self.reals[inst]:
            if v == vr:
                return i + elem
            i += size
        raise KeyError((inst, vr))

    def slot(self, rec: RecordPlan) -> int:
        """The row slot of a recorded variable (RecordPlan)."""
        if rec.var.is_float64:
            return self.offset[rec.instance] + self.index(rec.instance, rec.var.vr, rec.elem)
        return self.extra_slot[id(rec)]

    def write(self, slot: int, value: Any) -> None:
        """Put a value in a slot: a float in a double's, an int or a bool in an integer's."""
        if slot < self.n_double:
            self.row[slot] = value
        else:
            self.irow[slot - self.n_double] = value


class Wiring:
    """Every Real input set by the master, its source, and the overrides that events have put in force."""

    def __init__(self, plan: Plan, layout: RowLayout) -> None:
        self.plan = plan
        self.vrs: dict[str, list[int]] = {n: [] for n in plan.order}
        self.values: dict[str, list[tuple[int, int]]] = {n: [] for n in plan.order}
        self.base: dict[tuple[str, int], Copy] = {}
        self.feeds: dict[tuple[str, int], tuple[str, int]] = {}     # (inst, pos) -> output (inst, vr)
        for c in plan.connections:
            if not c.is_float64:
                continue
            for e in range(c.dst_var.size):  # every element of an array (or the one element connected)
                pos = self._pos(c.dst, c.dst_var.vr, e)
                src = layout.out_arr[c.src], layout.index(c.src, c.src_var.vr, e if c.src_elem is None else c.src_elem)
                self.base[(c.dst, pos)] = Copy(pos, *src, c.factor, c.offset)
                self.feeds[(c.dst, pos)] = (c.src, c.src_var.vr)
        self.tables: dict[str, tuple[Doubles, np.ndarray]] = {}   # instance -> (array the copies read, values)
        for inst in plan.order:  # tabulated Real inputs: sources refreshed before each step
            cols = [ip for ip in plan.inputs if ip.instance == inst and ip.var.is_float64]
            if cols:
                arr = (ctypes.c_double * len(cols))()
                for j, ip in enumerate(cols):
                    pos = self._pos(inst, ip.var.vr)
                    self.base[(inst, pos)] = Copy(pos, arr, j, 1.0, 0.0)
                self.tables[inst] = (arr, np.ascontiguousarray(np.column_stack([ip.values for ip in cols])))
        for ev in plan.events + plan.conditions:  # an unconnected input driven by events holds its start
            if ev.var is None or ev.var.causality != "input" or ev.var.type != "Real" or ev.action == "set":
                continue
            assert ev.instance is not None   # (an event with a variable has its instance)
            key = (ev.instance, self._pos(ev.instance, ev.var.vr))
            if key not in self.base:
                self.base[key] = Copy(key[1], real_array([float(_start(plan, ev))]), 0, 1.0, 0.0)
        self.overrides: dict[tuple[str, int, str], tuple[str, float]] = {}
        self._held: dict[tuple[str, int, str], Doubles] = {}   # the array each override's copies read

    def graph(self) -> FeedGraph:
        """Who feeds whom now: the plan's graph (``plan.feeds``), less the copies whose input, or whose
        source output, an override holds (they read the held value, not the connection)."""
        held = {key for key, (action, _) in self.overrides.items() if action == "override"}
        if not held:
            return self.plan.feeds
        return feed_graph(self.plan.order, self.plan.connections,
                          lambda c: (c.dst, c.dst_var.vr, "input") in held or (c.src, c.src_var.vr, "output") in held)

    def is_wired(self, inst: str, vr: int, causality: str) -> bool:
        """Whether the copies can carry an override of this Real input (one the master sets) or output
        (one feeding a connection); an input the master never sets is set on the FMU directly instead."""
        if causality == "output":
            return any(src == (inst, vr) for src in self.feeds.values())
        return any(v == vr for v, _ in self.values[inst])

    def _pos(self, inst: str, vr: int, elem: int = 0) -> int:
        """The position of (vr, element) among the values the master sets on ``inst`` (an array's
        elements follow one another; the value references of fmi3SetFloat64 name each array once)."""
        vals = self.values[inst]
        if (vr, elem) not in vals:
            vals.append((vr, elem))
            if elem == 0:
                self.vrs[inst].append(vr)
        return vals.index((vr, elem))

    def apply(self, ev: EventPlan) -> bool:
        """Put an event's action in force (override, bias on top of an earlier one, or reset).  Returns
        whether the copies changed (False: a new value of an override already in force, written in place)."""
        assert ev.instance is not None and ev.var is not None, "a stop event acts on no variable"
        return self.act(ev.instance, ev.var.vr, ev.var.causality, ev.action, ev.value)

    def act(self, inst: str, vr: int, causality: str, action: str, value: float | None) -> bool:
        """:meth:`apply` for one Real variable ``(inst, vr, causality)`` (``value`` None for a reset)."""
        key = (inst, vr, causality)
        if action == "reset":
            return self.overrides.pop(key, None) is not None
        assert value is not None, f"{action} without a value"
        prev = self.overrides.get(key)
        if action == "bias" and prev is not None:   # on top of an earlier override or bias
            self.overrides[key] = (prev[0], prev[1] + float(value))
            if prev[0] == "override":
                self._held_value(key, prev[1] + float(value))
                return False
            return True
        self.overrides[key] = (action, float(value))
        if action == "override" and prev is not None and prev[0] == "override":
            self._held_value(key, float(value))
            return False
        return True

    def _held_value(self, key: tuple[str, int, str], value: float) -> Doubles:
        arr = self._held.get(key)
        if arr is None:
            arr = self._held[key] = real_array([value])
        arr[0] = value
        return arr

    def copies(self, inst: str) -> list[Copy]:
        """The copies that set ``inst``'s Real inputs, with the overrides in force: an override of the input
        replaces its value; else what its connection carries (the source output's override as it is, or the
        output with its bias through the connection's transform) plus the input's own bias (in the input's
        unit), the two biases adding up.  An override is read from an array of its own, so that a new value
        needs no new loop."""
        out = []
        for pos, (vr, _) in enumerate(self.values[inst]):
            _, arr, i, f, o = self.base[(inst, pos)]
            key = (inst, vr, "input")
            ov = self.overrides.get(key)
            if ov is not None and ov[0] == "override":
                out.append(Copy(pos, self._held_value(key, ov[1]), 0, 1.0, 0.0))
                continue
            bias = ov[1] if ov is not None else 0.0
            if (inst, pos) in self.feeds:
                src, svr = self.feeds[(inst, pos)]
                okey = (src, svr, "output")
                oov = self.overrides.get(okey)
                if oov is not None and oov[0] == "override":
                    out.append(Copy(pos, self._held_value(okey, oov[1]), 0, 1.0, bias))
                    continue
                if oov is not None:     # a bias on the output, before the connection's transform
                    bias += oov[1] * f
            out.append(Copy(pos, arr, i, f, o + bias))
        return out

    def bad_input(self, name: str, in_vr: ctypes.Array[ctypes.c_uint], copies: list[Copy], t: float) -> RunError:
        """The first non-finite value about to be set on an input of ``name``, named with the output that
        produced it (or an overflow of their sum, reported as such)."""
        ip = self.plan.instances[name]
        by_vr = {v.vr: v for v in ip.model.variables.values()}
        vrs = [vr for vr, _ in self.values[name]]
        for pos, arr, i, f, o in copies:
            v = arr[i] * f + o   # non-finite exactly when the value set is (x * 1.0 + 0.0 keeps inf, nan)
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


def discrete_event_value(plan: Plan, held: dict[tuple[str, int], Any], ev: EventPlan) -> Any:
    """The value an event on an Integer, Enumeration, Boolean or String input sets now (None: none): a reset
    its start (the scenario's, else the FMU's), a bias the value held plus its own, else its value; ``held``
    ((instance, value reference) -> value) keeps it until the next event on that input."""
    assert ev.instance is not None and ev.var is not None
    key = (ev.instance, ev.var.vr)
    start = ev.var.start
    for v, val in plan.instances[ev.instance].parameters:
        if v.vr == ev.var.vr:
            start = val
    current = held.get(key, start)
    if ev.action == "reset":
        held.pop(key, None)
        return start
    value = int(current or 0) + int(ev.value) if ev.action == "bias" else ev.value
    held[key] = value
    return value


def _start(plan: Plan, ev: EventPlan) -> float:
    assert ev.instance is not None and ev.var is not None
    start = ev.var.start if ev.var.start is not None else 0.0
    for v, val in plan.instances[ev.instance].parameters:
        if v.vr == ev.var.vr:
            start = val
    return start


def table_feeder(inst: FmuInstance, table: tuple[Doubles, np.ndarray] | None, discrete: list[InputPlan]
                 ) -> Callable[[int], int] | None:
    """A closure that puts the tabulated inputs of step k in place: the Float64 values where the copies
    read them, the others set on the FMU with one call per FMI type."""
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
    for t in sorted({ip.var.fmi_type for ip in discrete}):
        cols = [ip for ip in discrete if ip.var.fmi_type == t]
        put, ctype = inst.accessor(t, "Set")
        vrs, n = vr_array([ip.var.vr for ip in cols]), ctypes.c_size_t(len(cols))
        buf = (ctype * len(cols))()
        mat: list[list[Any]]   # the values of each step, of the FMI type's ctype
        if ctype is ctypes.c_char_p:
            mat = [[str(v).encode("utf-8") for v in row] for row in zip(*(ip.values for ip in cols))]
        elif ctype in (ctypes.c_double, ctypes.c_float):
            mat = np.column_stack([ip.values.astype(float) for ip in cols]).tolist()
        else:
            mat = [list(map(int, row)) for row in zip(*(ip.values for ip in cols))]

        def put_k(k: int, put=put, vrs=vrs, n=n, buf=buf, mat=mat) -> int:
            buf[:] = mat[k]
            return put(vrs, n, buf, n)
        steps.append(put_k)
    if len(steps) == 1:
        return steps[0]

    def feed(k: int) -> int:
        for f in steps:
            s = f(k)
            if s:
                return s
        return 0
    return feed


def discrete_copier(instances: dict[str, FmuInstance], c: ConnectionPlan) -> Callable[[], int]:
    """A closure copying one output to an input with a get and a set (FMI 2.0 or 3.0, arrays whole):
    integers, enumerations, booleans and strings as they are; reals of another width through the factor
    and offset; Boolean -> Real as 0 or 1 through the factor and offset; Real -> Boolean as value > threshold."""
    n = c.src_var.size
    get, gt = instances[c.src].accessor(c.src_var.fmi_type, "Get")
    put, pt = instances[c.dst].accessor(c.dst_var.fmi_type, "Set")
    svr, dvr = vr_array([c.src_var.vr]), vr_array([c.dst_var.vr])
    one, nv = ctypes.c_size_t(1), ctypes.c_size_t(n)
    ibuf, obuf = (gt * n)(), (pt * n)()
    sk, dk = c.src_var.type, c.dst_var.type
    if sk == dk and sk != "Real" and gt is pt:
        def copy() -> int:
            return get(svr, one, ibuf, nv) or put(dvr, one, ibuf, nv)
        return copy
    f, o, threshold = c.factor, c.offset, c.spec.threshold

    def convert() -> int:
        s = get(svr, one, ibuf, nv)
        if s:
            return s
        for i in range(n):
            x = ibuf[i]
            if dk == "Real":
                obuf[i] = (float(x) if sk == "Real" else (1.0 if x else 0.0)) * f + o
            elif dk == "Boolean" and sk == "Real":
                obuf[i] = x > threshold
            else:
                obuf[i] = x
        return put(dvr, one, obuf, nv)
    return convert
