"""FMI 3.0 FMUs with clocks in co-simulation (with event mode: ``hasEventMode``, instantiated with
eventModeUsed on and earlyReturnAllowed off) and in Model Exchange: the master ticks their input clocks and
reads the output clocks they raise, at the communication points, in the plan's order.

The events of a communication point t_(k+1) are handled at the end of the step that ends there (the
instance's fast-path step): after its fmi3DoStep (or integration) from t_k to t_(k+1), with the inputs set
for that step (under Gauss-Seidel the values at t_(k+1) of the instances before it in the plan's order),
the instance enters event mode at t_(k+1); each instance's events come after those of the instances before
it in the order, as the FMI 3.0 co-simulation event mode loop has them (the importer steps to the
communication point, then handles the events there).  An event is due at t_(k+1) when

- a periodic input clock ticks there (intervalVariability constant, fixed or tunable: shift + i interval
  [s], on the master's grid; a tunable clock keeps the interval it declares: the master never changes it);
- a triggered input clock is ticked there: by ``clock_ticks``, or by an output clock connected to it that
  its FMU raised at t_(k+1) (an instance before this one in the order: ``check`` refuses the rest);
- (co-simulation) the FMU asked for event handling in the step that ended at t_(k+1) (fmi3DoStep's
  eventHandlingNeeded; without early return the FMU ends its step at the communication point).

At the start of the step from t_k the instance takes the ticks of t_k that came after its events there:
those of an output clock raised at t_k by a Model Exchange FMU before it in the order at the start of its
own step from t_k (an event of its new inputs, which an instance after it in the order computed).

The event (FMI 3.0, co-simulation with event mode, 4.2.5; Model Exchange, 3.2.4):

  fmi3EnterEventMode; fmi3SetClock (the input clocks that tick); the clocked inputs of those clocks set
  (their values as the step's inputs carry them); fmi3GetClock (the output clocks: which the FMU raised);
  the clocked outputs of every active clock read (their values at the tick); fmi3UpdateDiscreteStates
  until no new discrete states are needed; fmi3EnterStepMode (co-simulation) or
  fmi3EnterContinuousTimeMode (Model Exchange, whose integrator restarts there).

The events at the start time are those of the end of initialisation (the FMU is in event mode there);
those of the stop time end the last step.  A Model Exchange FMU's own events (time, state, step events, and those of its new inputs)
read its output clocks too; one it raises at an instant that is not a communication point reaches no
other FMU: if it is connected, the run ends there in one line (the FMUs after it are at t_k already).

A clocked variable is exchanged only at its clock's ticks: the fast path's set passes on the inputs that
are not clocked and keeps the clocked ones for their clock's next tick; its get gives, for a clocked
output, the value read at its last tick (before the first: its start value).  The row of a communication
point is read after the steps that end there, and so after their events: what is recorded at t_k is the
value after the events of t_k (a tick's effect shows in the row of its time).  Where every step of a
clocked FMU is one interval of its periodic clock, it so computes what the same FMU without event mode
computes at the end of each step (G1 through the clocked sensor and controller equals the fixed-step run
bit for bit)."""
from __future__ import annotations

import ctypes
import os
from typing import TYPE_CHECKING, Any

from ..messages.errors import RunError
from ..model.clocks import Clock, clocks_of
from .contract import FastPath
from .in_process import ACCESS, Instance3, raw
from .model_exchange import ModelExchange3

#: Why the step of an instance with clocks runs alone (:attr:`FastPath.alone`).
CLOCKED_ALONE = "an instance with clocks: its events run in Python, in the plan's order"
#: Updates of the discrete states at one event after which the event iteration is taken not to end.
MAX_UPDATES = 1000
#: The name of each FMI 3.0 type in its get and set functions (fmi3GetInt32 ...).
_TNAME = {t: name for t, (_, name) in ACCESS[3].items()}


def _size(v: Any) -> int:
    """The number of values of a variable (FMPy's): 1 for a scalar, the product of an array's dimensions."""
    n = 1
    for d in v.dimensions or ():
        n *= int(d.start) if d.start is not None else 1
    return n


def _start(v: Any, size: int) -> list[Any]:
    """A variable's start values (FMPy's start text: its values separated by blanks), as Python values of
    its type; without a start, zeros (false)."""
    words = str(v.start).split() if v.start is not None else []
    conv: Any = float if v.type in ("Float64", "Float32") else (
        (lambda w: w.lower() in ("true", "1")) if v.type == "Boolean" else int)
    if v.type == "String":
        return [w.encode() for w in words[:1]] or [b""]
    vals = [conv(w) for w in words] or [conv("0")] * size
    return (vals * size)[:size] if len(vals) != size else vals


class ClockEvents:
    """The clocks of an FMI 3.0 instance and its events at the communication points (mixed into the
    co-simulation and the Model Exchange instance: see the module's docstring)."""

    name: str
    c: Any
    fmu: Any
    log: Any
    fatal: bool

    if TYPE_CHECKING:   # (given by the instance this is mixed into)
        def call(self, what: str, fn: Any, *args: Any, t: float | None = None) -> Any: ...

        def fail_status(self, what: str, status: int, t: float | None) -> RunError: ...

    @property
    def can_get_and_set_state(self) -> bool:
        """No: its clocks' state (the ticks taken, the values held at them) is the master's, not saved with
        the FMU's."""
        return False

    def get_state(self) -> Any:
        raise RunError(f"{self.name}: an instance with clocks cannot save its state (the master keeps its "
                       "clocks' ticks and values)", self.name)

    def set_state(self, state: Any) -> None:
        raise RunError(f"{self.name}: an instance with clocks cannot restore a state", self.name)

    def _init_clocks(self, md: Any, unzipdir: str) -> None:
        self._fns: dict[str, Any] = {}                  # the FMU's functions, looked up once (:meth:`_fn`)
        self._getters: dict[str, tuple[Any, Any]] = {}  # its get of each type (:meth:`_get_of`)
        self._in_plans: dict[tuple[frozenset[str], int], tuple[Any, ...]] = {}   # (:meth:`_set_clocked_inputs`)
        self._out_plans: dict[frozenset[str], list[tuple[Any, ...]]] = {}        # (:meth:`_out_plan`)
        self._set_clocks: dict[tuple[str, ...], tuple[Any, ...]] = {}            # (:meth:`_tick`)
        with open(os.path.join(unzipdir, "modelDescription.xml"), "rb") as fh:
            self.clocks: list[Clock] = clocks_of(fh.read())
        by_var = {v: c for c in self.clocks for v in c.clocked}
        clocked = [v for v in md.modelVariables if v.name in by_var and v.type != "Clock"]
        #: the number of values of each variable [vr -> count] (an array's elements, row-major)
        self.sizes: dict[int, int] = {int(v.valueReference): _size(v) for v in md.modelVariables}
        #: the clocked variables, of every type: value reference -> the clock's name
        self.clocked_vr: dict[int, str] = {int(v.valueReference): by_var[v.name].name for v in clocked}
        #: the values at the last tick of each clocked variable [vr -> its values]; before the first, its start
        self.held: dict[int, list[Any]] = {int(v.valueReference): _start(v, self.sizes[int(v.valueReference)])
                                           for v in clocked}
        #: the clocked outputs by FMI type (read at their clock's ticks): type -> value references
        self._outputs: dict[str, list[int]] = {}
        for v in clocked:
            if v.causality == "output":
                self._outputs.setdefault(v.type, []).append(int(v.valueReference))
        self.in_held: dict[int, list[float]] = {}          # the clocked Float64 inputs' values, set at their next tick
        self.raised: list[tuple[float, str]] = []          # (time [s], output clock) the FMU raised
        self.ticked: list[tuple[float, str]] = []          # (time [s], input clock) the master ticked
        self.raised_at: dict[str, tuple[int, int]] = {}    # output clock -> (grid index, count) of its last rise
        self.sources: dict[str, list[tuple["ClockEvents", str]]] = {}   # input clock -> (instance, output clock)
        self.fed: set[str] = set()                         # the output clocks connected to an input clock
        self._seen: dict[tuple[int, str], int] = {}        # (source, its output clock) -> the rises taken
        self._start, self._step = 0.0, 1.0
        self._periodic: dict[str, tuple[int, int]] = {}    # clock -> (first grid index, interval in steps)
        self._ticks: dict[str, set[int]] = {}              # triggered clock -> its grid indices (clock_ticks)
        self._done = -1                                    # the last grid index whose scheduled ticks were taken
        self._outputs_read = False                         # this event's output clocks are read already

    def schedule(self, start: float, step: float, ticks: dict[str, list[float]]) -> None:
        """The master's grid (``start`` [s], ``step`` [s]) and the times [s] of the triggered clocks given
        by ``clock_ticks`` (each on the grid: ``check`` refuses the rest)."""
        self._start, self._step = start, step
        for c in self.clocks:
            if c.periodic and c.interval is not None:
                on_grid = c.grid(step)
                assert on_grid is not None   # (check refuses the rest)
                self._periodic[c.name] = on_grid
        for name, times in ticks.items():
            self._ticks[name] = {round((t - start) / step) for t in times}

    def connect_clock(self, clock: str, source: "ClockEvents", output_clock: str) -> None:
        """Input clock ``clock`` ticks when ``source`` raises ``output_clock`` (``source`` steps first)."""
        self.sources.setdefault(clock, []).append((source, output_clock))
        source.fed.add(output_clock)

    def _index(self, t: float) -> int | None:
        """The grid index of the time ``t`` [s], None off the grid."""
        n = round((t - self._start) / self._step)
        return n if abs(self._start + n * self._step - t) <= 1e-9 * self._step else None

    def _due(self, n: int) -> list[Clock]:
        """The input clocks that tick at grid index ``n`` and have not ticked for it yet."""
        out = []
        for c in self.clocks:
            if c.causality != "input":
                continue
            p = self._periodic.get(c.name)
            if n > self._done and ((p is not None and n >= p[0] and (n - p[0]) % p[1] == 0)
                                   or n in self._ticks.get(c.name, ())):
                out.append(c)
                continue
            for src, oc in self.sources.get(c.name, ()):
                at = src.raised_at.get(oc)
                if at is not None and at[0] == n and at[1] > self._seen.get((id(src), oc), 0):
                    out.append(c)
                    break
        return out

    def _tick(self, n: int, t: float, due: list[Clock]) -> None:
        """In event mode at grid index ``n`` (time ``t`` [s]): the input clocks ``due`` set, their clocked
        inputs set, the output clocks and the clocked outputs of every active clock read."""
        c = ctypes.c_void_p(self.c)
        self._done = max(self._done, n)
        for k in due:
            for src, oc in self.sources.get(k.name, ()):
                at = src.raised_at.get(oc)
                if at is not None and at[0] == n:
                    self._seen[(id(src), oc)] = at[1]
        if due:
            names = tuple(k.name for k in due)
            setting = self._set_clocks.get(names)
            if setting is None:   # (the arrays of a set of clocks made once)
                setting = self._set_clocks[names] = (
                    (ctypes.c_uint32 * len(due))(*[k.vr for k in due]), ctypes.c_size_t(len(due)),
                    (ctypes.c_bool * len(due))(*[True] * len(due)), f"fmi3SetClock({', '.join(names)})")
            vrs, n_vr, on, what = setting
            self._ok(self._fn("fmi3SetClock")(c, vrs, n_vr, on), what, t)
            self.ticked += [(t, name) for name in names]
            self._set_clocked_inputs(c, frozenset(names), t)
        self._read_outputs(n, t, {k.name for k in due})

    def _set_clocked_inputs(self, c: Any, names: frozenset[str], t: float) -> None:
        """The clocked inputs of the clocks ``names`` set to the values kept for their tick (one
        fmi3SetFloat64; its arrays made once for the clocks and the inputs kept)."""
        key = (names, len(self.in_held))
        plan = self._in_plans.get(key)
        if plan is None:
            vrs = [vr for vr in self.in_held if self.clocked_vr[vr] in names]
            nv = sum(len(self.in_held[vr]) for vr in vrs)
            plan = self._in_plans[key] = (vrs, (ctypes.c_uint32 * max(1, len(vrs)))(*vrs), ctypes.c_size_t(len(vrs)),
                                          (ctypes.c_double * max(1, nv))(), ctypes.c_size_t(nv))
        vrs, vr_arr, n_vr, vals, nv = plan
        if not vrs:
            return
        i, held, in_held = 0, self.held, self.in_held
        for vr in vrs:
            v = in_held[vr]
            vals[i:i + len(v)] = v
            i += len(v)
            held[vr] = list(v)
        self._ok(self._fn("fmi3SetFloat64")(c, vr_arr, n_vr, vals, nv), "fmi3SetFloat64 (clocked inputs)", t)

    def _read_outputs(self, n: int | None, t: float, active: set[str]) -> None:
        """The output clocks read (those raised: at grid index ``n``, None off the grid) and the clocked
        outputs of every active clock (``active``: the input clocks that tick) read into :attr:`held`."""
        c = ctypes.c_void_p(self.c)
        active = set(active)
        for k in self.clocks:
            if k.causality != "output":
                continue
            value = (ctypes.c_bool * 1)()
            self._ok(self._fn("fmi3GetClock")(c, (ctypes.c_uint32 * 1)(k.vr), ctypes.c_size_t(1), value),
                     f"fmi3GetClock({k.name})", t)
            if not value[0]:
                continue
            active.add(k.name)
            self.raised.append((t, k.name))
            if n is None:
                if k.name in self.fed:
                    why = (f"{self.name}: output clock {k.name} raised at t = {t:.9g} s, between communication "
                           "points: the FMUs it ticks are at communication points only")
                    self.log.append(why)   # (the integration's failure names it as its last log)
                    raise RunError(why, self.name, t)
            else:
                self.raised_at[k.name] = (n, self.raised_at.get(k.name, (0, 0))[1] + 1)
        held = self.held
        for get, vr_arr, n_vr, vals, nv, slices, what in self._out_plan(frozenset(active)):
            self._ok(get(vr_arr, n_vr, vals, nv), what, t)
            for vr, i, j in slices:
                held[vr] = vals[i:j]
        self._outputs_read = True

    def _out_plan(self, active: frozenset[str]) -> list[tuple[Any, ...]]:
        """Per FMI type with outputs clocked by a clock of ``active``: its get, the value references, a
        buffer for their values and where each one's values are in it; made once for each set of clocks."""
        plan = self._out_plans.get(active)
        if plan is not None:
            return plan
        plan = []
        for fmi_type, vrs in self._outputs.items():
            outs = [vr for vr in vrs if self.clocked_vr[vr] in active]
            if not outs:
                continue
            get, ctype = self._get_of(fmi_type)
            slices, i = [], 0
            for vr in outs:
                slices.append((vr, i, i + self.sizes[vr]))
                i += self.sizes[vr]
            plan.append((get, (ctypes.c_uint32 * len(outs))(*outs), ctypes.c_size_t(len(outs)), (ctype * i)(),
                         ctypes.c_size_t(i), slices, f"fmi3Get{_TNAME.get(fmi_type, fmi_type)} (clocked outputs)"))
        self._out_plans[active] = plan
        return plan

    def _ok(self, status: int, what: str, t: float) -> None:
        if status > 1:
            raise self.fail_status(what, status, t)

    def _get_of(self, fmi_type: str) -> tuple[Any, Any]:
        """The FMU's own get of ``fmi_type`` (:meth:`accessor` without the held values), made once."""
        got = self._getters.get(fmi_type)
        if got is None:
            got = self._getters[fmi_type] = super().accessor(fmi_type, "Get")   # type: ignore[misc]
        return got

    def _fn(self, name: str) -> Any:
        """The FMU's function ``name`` (:func:`.in_process.raw`), looked up once: an event calls several."""
        f = self._fns.get(name)
        if f is None:
            f = self._fns[name] = raw(self.fmu.dll, name)
        return f

    def accessor(self, fmi_type: str, op: str) -> tuple[Any, Any]:
        """The FMU's get or set of ``fmi_type``; its get gives each clocked variable the values of its last
        tick (held by the master: the FMU defines them at its clock's ticks only), asking the FMU for the
        others."""
        fn, ctype = super().accessor(fmi_type, op)   # type: ignore[misc]
        if op != "Get" or not self._outputs.get(fmi_type):   # (no clocked output of this type)
            return fn, ctype
        held, sizes = self.held, self.sizes

        def call(vrs: Any, n: Any, buf: Any, nv: Any) -> int:
            status, i = 0, 0
            for j in range(int(getattr(n, "value", n))):
                vr = int(vrs[j])
                size = sizes.get(vr, 1)
                vals = held.get(vr)
                if vals is None:
                    one = (ctype * size)()
                    status = max(status, int(fn((ctypes.c_uint32 * 1)(vr), ctypes.c_size_t(1), one,
                                                ctypes.c_size_t(size))))
                    vals = list(one)
                for e in range(size):
                    buf[i + e] = vals[e]
                i += size
            return status
        return call, ctype

    def _clocked_path(self, inner: FastPath, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                      in_val: Any, plain_in: list[int], plain_out: list[int]) -> FastPath:
        """The fast path over ``inner`` (built for the inputs ``plain_in`` and outputs ``plain_out`` that are
        not clocked, positions in ``in_vrs``/``out_vrs``): the set keeps the clocked inputs for their tick;
        the step takes the ticks still due at its start (output clocks raised there after this instance's
        events), steps, then handles the events due at its end; the get gives each clocked output its
        value at its last tick."""
        in_val = in_val if in_val is not None else (ctypes.c_double * max(1, n_in))()
        sizes = self.sizes
        in_off, out_off = self._offsets(in_vrs), self._offsets(out_vrs)
        clocked_in = [(in_off[i], vr, sizes.get(vr, 1)) for i, vr in enumerate(in_vrs) if vr in self.clocked_vr]
        clocked_out = [(out_off[i], vr, sizes.get(vr, 1)) for i, vr in enumerate(out_vrs) if vr in self.clocked_vr]
        p_in_pos = [in_off[i] + e for i in plain_in for e in range(sizes.get(in_vrs[i], 1))]
        p_out_pos = [out_off[i] + e for i in plain_out for e in range(sizes.get(out_vrs[i], 1))]
        i_set, i_step, i_get, p_in = inner.set_real, inner.do_step, inner.get_real, inner.in_val
        p_in_vr = (ctypes.c_uint32 * max(1, len(plain_in)))(*[in_vrs[i] for i in plain_in])
        p_out_vr = (ctypes.c_uint32 * max(1, len(plain_out)))(*[out_vrs[i] for i in plain_out])
        p_out = (ctypes.c_double * max(1, len(p_out_pos)))()
        n_pin, n_pout = ctypes.c_size_t(len(plain_in)), ctypes.c_size_t(len(plain_out))
        held, in_held = self.held, self.in_held

        def set_real(c: Any, vrs: Any, n: Any, vals: Any, *tail: Any) -> int:
            for i, vr, size in clocked_in:
                in_held[vr] = vals[i:i + size]
            if not plain_in:
                return 0
            for j, i in enumerate(p_in_pos):
                p_in[j] = vals[i]
            return int(i_set(c, p_in_vr, n_pin, p_in, *inner.set_tail))

        def get_real(c: Any, vrs: Any, n: Any, out: Any, *tail: Any) -> int:
            s = 0
            if plain_out:
                s = int(i_get(c, p_out_vr, n_pout, p_out, *inner.get_tail))
                for j, i in enumerate(p_out_pos):
                    out[i] = p_out[j]
            for i, vr, size in clocked_out:
                vals = held[vr]
                for e in range(size):
                    out[i + e] = vals[e]
            return s

        def do_step(c: Any, t: Any, h: Any, *tail: Any) -> int:
            s = self._events_or_status(t.value)   # (ticks from output clocks raised at t_k after our events there)
            if s:
                return s
            s = int(i_step(c, t, h, *inner.step_tail))
            self._stepped(s)
            if s > 1:
                return s
            # the events of t_(k+1), at the end of the step that ends there
            return self._events_or_status(t.value + h.value) or s

        return FastPath(inner.c, set_real, do_step, get_real, in_val, set_tail=(ctypes.c_size_t(n_in),),
                        get_tail=(ctypes.c_size_t(n_out),), terminated=inner.terminated, last_time=inner.last_time,
                        alone=CLOCKED_ALONE, abi=inner.abi)

    def _events_at(self, n: int, t: float) -> None:
        """The event at grid index ``n`` (time ``t`` [s]) if one is due."""
        raise NotImplementedError

    def _events_or_status(self, t: float) -> int:
        """The events due at ``t`` [s] where it is a point of the grid: 0, or the FMI status of their failure
        (its line logged)."""
        try:
            n = self._index(t)
            if n is not None:
                self._events_at(n, t)
        except RunError as exc:
            self.log.append(str(exc))
            return 4 if self.fatal else 3
        return 0

    def _stepped(self, status: int) -> None:
        """After the step (its FMI status)."""

    def _offsets(self, vrs: list[int]) -> list[int]:
        """The position of each variable's first value among the values of ``vrs`` (arrays take several)."""
        out, i = [], 0
        for vr in vrs:
            out.append(i)
            i += self.sizes.get(vr, 1)
        return out

    def _plain(self, vrs: list[int], plain: list[int]) -> tuple[list[int], int]:
        """The value references at the positions ``plain`` and how many values they have."""
        sel = [vrs[i] for i in plain]
        return sel, sum(self.sizes.get(vr, 1) for vr in sel)

    def _split(self, in_vrs: list[int], out_vrs: list[int]) -> tuple[list[int], list[int]]:
        """The positions of the inputs and outputs that are not clocked."""
        return ([i for i, vr in enumerate(in_vrs) if vr not in self.clocked_vr],
                [i for i, vr in enumerate(out_vrs) if vr not in self.clocked_vr])


class Clocked3(ClockEvents, Instance3):
    """An FMI 3.0 co-simulation FMU with clocks, run with event mode (see the module's docstring)."""

    def _slave(self, md: Any, unzipdir: str) -> Any:
        fmu = super()._slave(md, unzipdir)
        self._init_clocks(md, unzipdir)
        self._event_needed = False
        return fmu

    def instantiate(self) -> None:
        """fmi3InstantiateCoSimulation with eventModeUsed on (earlyReturnAllowed off: the FMU ends each
        step at the communication point and asks for event handling there)."""
        self.call("fmi3InstantiateCoSimulation", self.fmu.instantiate, False, True, True, False, self._log3)
        self.c = self.fmu.component
        self._debug_logging("fmi3SetDebugLogging")

    def exit_initialization(self) -> None:
        """Exit initialisation mode (the FMU is in event mode then: eventModeUsed), the events at the start
        time, step mode."""
        super().exit_initialization()
        n = self._index(self._start)
        assert n is not None
        self._event(n, self._start, self._due(n), in_event_mode=True)

    def _events_at(self, n: int, t: float) -> None:
        due = self._due(n)
        if due or self._event_needed:
            self._event(n, t, due)

    def _event(self, n: int, t: float, due: list[Clock], in_event_mode: bool = False) -> None:
        self._event_needed = False
        c = ctypes.c_void_p(self.c)
        if not in_event_mode:
            self._ok(self._fn("fmi3EnterEventMode")(c), "fmi3EnterEventMode", t)
        self._tick(n, t, due)
        for _ in range(MAX_UPDATES):
            needed, terminate = self.call("fmi3UpdateDiscreteStates", self.fmu.updateDiscreteStates, t=t)[:2]
            if terminate:
                raise RunError(f"{self.name}: the FMU ended the simulation in its event at t = {t:.9g} s", self.name, t)
            if not needed:
                break
        else:
            raise RunError(f"{self.name}: the event iteration at t = {t:.9g} s did not end after {MAX_UPDATES} "
                           "updates of the discrete states", self.name, t)
        self._ok(self._fn("fmi3EnterStepMode")(c), "fmi3EnterStepMode", t)

    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                  in_val: Any = None) -> FastPath:
        """fmi3DoStep, then the events due at its end, eventHandlingNeeded among them (see
        :meth:`ClockEvents._clocked_path`)."""
        plain_in, plain_out = self._split(in_vrs, out_vrs)
        inner = super().fast_path(*self._plain(in_vrs, plain_in), *self._plain(out_vrs, plain_out))
        self._needed_flag = inner.step_tail[1]._obj   # fmi3DoStep's eventHandlingNeeded
        return self._handed(self._clocked_path(inner, in_vrs, n_in, out_vrs, n_out, in_val, plain_in, plain_out))

    def _stepped(self, status: int) -> None:
        self._event_needed = status <= 1 and bool(self._needed_flag.value)


class ClockedME3(ClockEvents, ModelExchange3):
    """An FMI 3.0 Model Exchange FMU with clocks (see the module's docstring)."""

    def _slave(self, md: Any, unzipdir: str) -> Any:
        fmu = super()._slave(md, unzipdir)
        self._init_clocks(md, unzipdir)
        return fmu

    def _event_iteration(self, t: float, kind: str) -> bool:
        """The FMU's own events read its output clocks first (and at the start time its input clocks due
        there tick); the ticks the master gives have read them already."""
        if kind == "initial":
            n = self._index(t)
            assert n is not None
            self._tick(n, t, self._due(n))
        elif not self._outputs_read:
            self._read_outputs(self._index(t), t, set())
        self._outputs_read = False
        return super()._event_iteration(t, kind)

    def _events_at(self, n: int, t: float) -> None:
        due = self._due(n)
        if not due:
            return
        assert self.integrator is not None
        if self.mode != "event":
            self.call("fmi3EnterEventMode", self.fmu.enterEventMode, t=t)
            self.mode = "event"
        self.events.append((t, "clock"))
        self._tick(n, t, due)
        if self._event_iteration(t, "clock"):
            raise RunError(f"{self.name}: the FMU ended the simulation in its event at t = {t:.9g} s", self.name, t)
        self.integrator.reset(t)
        self.z = self._indicators()
        self.dirty = False   # (the event iteration took the new inputs: as after any event)

    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                  in_val: Any = None) -> FastPath:
        """The Model Exchange fast path (the integration, the FMU's own events inside it handled where they
        happen), then the ticks due at its end (see :meth:`ClockEvents._clocked_path`)."""
        plain_in, plain_out = self._split(in_vrs, out_vrs)
        inner = super().fast_path(*self._plain(in_vrs, plain_in), *self._plain(out_vrs, plain_out))
        return self._clocked_path(inner, in_vrs, n_in, out_vrs, n_out, in_val, plain_in, plain_out)
