"""An FMI 3.0 co-simulation FMU with clocks, run with event mode (``hasEventMode``; instantiated with
eventModeUsed on, earlyReturnAllowed off): the master ticks its input clocks and reads the output clocks
it raises, at the communication points.

At a communication point t (the end of a step, and the start time after initialisation), the instance
handles an event when one is due there: a periodic input clock ticks at t (intervalVariability constant,
fixed or tunable: shift + k interval [s], on the master's grid; a tunable clock keeps the interval it
declares: the master never changes it), a triggered input clock is ticked at t (``clock_ticks``, or an
output clock connected to it that its FMU raised at t), or the FMU asked for event handling in the step
that ended at t (fmi3DoStep's eventHandlingNeeded).  The event, FMI 3.0 co-simulation with event mode:

  fmi3EnterEventMode; fmi3SetClock (the input clocks that tick); the clocked inputs of those clocks set
  (their values as the step's inputs carry them); fmi3GetClock (the output clocks: which the FMU raised);
  the clocked outputs of every active clock read (their values at the tick); fmi3UpdateDiscreteStates
  until no new discrete states are needed; fmi3EnterStepMode.

Then the step from t.  A clocked variable is exchanged only at its clock's ticks: the fast path's set
passes on the continuous inputs only and keeps the clocked ones for the tick; its get returns, for a
clocked output, the value read at its last tick (before the first: its start value).  The instances
step in the plan's order, so an output clock and the clocked values of an FMU reach the FMUs after it in
that order at the same instant (``check`` refuses a clock connection against the order): the clocked
partitions that tick together run in their dependency order (FMI 3.0, 2.2.8)."""
from __future__ import annotations

import ctypes
import os
from fractions import Fraction
from typing import Any

from ..messages.errors import RunError
from ..model.clocks import Clock, clocks_of, grid_multiple
from .contract import FastPath
from .in_process import Instance3, raw

#: Why the step of a clocked instance runs alone (:attr:`FastPath.alone`).
CLOCKED_ALONE = "an instance with clocks: its events run in Python, in the plan's order"
#: Updates of the discrete states at one event after which the event iteration is taken not to end.
MAX_UPDATES = 1000


class Clocked3(Instance3):
    """An FMI 3.0 co-simulation FMU with clocks, run with event mode (see the module's docstring)."""

    def _slave(self, md: Any, unzipdir: str) -> Any:
        fmu = super()._slave(md, unzipdir)
        with open(os.path.join(unzipdir, "modelDescription.xml"), "rb") as fh:
            self.clocks: list[Clock] = clocks_of(fh.read())
        self._by_name = {c.name: c for c in self.clocks}
        by_var = {v: c for c in self.clocks for v in c.clocked}
        reals = {v.name: v for v in md.modelVariables if v.type == "Float64"}
        #: the clocked Float64 variables: value reference -> the clock's name
        self.clocked_vr: dict[int, str] = {int(reals[n].valueReference): c.name for n, c in by_var.items()
                                           if n in reals}
        #: the value at the last tick of each clocked output [vr -> value]; before the first, its start
        self.held: dict[int, float] = {int(v.valueReference): float(v.start) if v.start is not None else 0.0
                                       for v in reals.values()
                                       if int(v.valueReference) in self.clocked_vr and v.causality == "output"}
        self._in_held: dict[int, float] = {}   # the clocked inputs' values, set at their clock's next tick
        self.raised: list[tuple[float, str]] = []          # (time [s], output clock) the FMU raised
        self.ticked: list[tuple[float, str]] = []          # (time [s], input clock) the master ticked
        self.raised_at: dict[str, int] = {}                # output clock -> the grid index it last rose at
        self.sources: dict[str, list[tuple["Clocked3", str]]] = {}   # input clock -> (instance, output clock)
        self._start, self._step = 0.0, 1.0
        self._periodic: dict[str, tuple[int, int]] = {}    # clock -> (first grid index, interval in steps)
        self._ticks: dict[str, set[int]] = {}              # triggered clock -> its grid indices (clock_ticks)
        self._event_needed = False
        self.events = 0
        return fmu

    def instantiate(self) -> None:
        """fmi3InstantiateCoSimulation with eventModeUsed on (earlyReturnAllowed off: the FMU ends each
        step at the communication point and asks for event handling there)."""
        self.call("fmi3InstantiateCoSimulation", self.fmu.instantiate, False, True, True, False, self._log3)
        self.c = self.fmu.component
        self._debug_logging("fmi3SetDebugLogging")
        dll = self.fmu.dll
        self._set_clock, self._get_clock = raw(dll, "fmi3SetClock"), raw(dll, "fmi3GetClock")
        self._get_f64, self._set_f64 = raw(dll, "fmi3GetFloat64"), raw(dll, "fmi3SetFloat64")
        self._do_step = raw(dll, "fmi3DoStep")
        self._enter_event, self._enter_step = raw(dll, "fmi3EnterEventMode"), raw(dll, "fmi3EnterStepMode")

    def schedule(self, start: float, step: float, ticks: dict[str, list[float]]) -> None:
        """The master's grid (``start`` [s], ``step`` [s]) and the times [s] of the triggered clocks given
        by ``clock_ticks`` (each on the grid: ``check`` refuses the rest)."""
        self._start, self._step = start, step
        for c in self.clocks:
            if c.periodic and c.interval is not None:
                n0, k = grid_multiple(Fraction(c.shift or "0"), step), grid_multiple(c.interval, step)
                assert n0 is not None and k is not None and k > 0   # (check refuses the rest)
                self._periodic[c.name] = (n0, k)
        for name, times in ticks.items():
            self._ticks[name] = {round((t - start) / step) for t in times}

    def connect_clock(self, clock: str, source: "Clocked3", output_clock: str) -> None:
        """Input clock ``clock`` ticks when ``source`` raises ``output_clock`` (``source`` steps first)."""
        self.sources.setdefault(clock, []).append((source, output_clock))

    # ------------------------------------------------------------------ events
    def _due(self, n: int) -> list[Clock]:
        """The input clocks that tick at grid index ``n``."""
        out = []
        for c in self.clocks:
            if c.causality != "input":
                continue
            p = self._periodic.get(c.name)
            if p is not None and n >= p[0] and (n - p[0]) % p[1] == 0:
                out.append(c)
            elif n in self._ticks.get(c.name, ()):
                out.append(c)
            elif any(src.raised_at.get(oc) == n for src, oc in self.sources.get(c.name, ())):
                out.append(c)
        return out

    def exit_initialization(self) -> None:
        """Exit initialisation mode (the FMU is in event mode then, eventModeUsed), the event at the start
        time, step mode."""
        super().exit_initialization()
        self._event(0, in_event_mode=True)

    def _event(self, n: int, in_event_mode: bool = False) -> None:
        """The event at grid index ``n`` if one is due (always after initialisation: ``in_event_mode``)."""
        t = self._start + n * self._step
        due = self._due(n)
        if not (due or self._event_needed or in_event_mode):
            return
        self._event_needed = False
        c = ctypes.c_void_p(self.c)
        if not in_event_mode:
            self._check(self._enter_event(c), "fmi3EnterEventMode", t)
        self.events += 1
        if due:
            vrs = (ctypes.c_uint32 * len(due))(*[k.vr for k in due])
            self._check(self._set_clock(c, vrs, ctypes.c_size_t(len(due)), (ctypes.c_bool * len(due))(*[True] * len(due))),
                        "fmi3SetClock(" + ", ".join(k.name for k in due) + ")", t)
            self.ticked += [(t, k.name) for k in due]
            names = {k.name for k in due}
            ins = [(vr, v) for vr, v in self._in_held.items() if self.clocked_vr[vr] in names]
            if ins:
                self._check(self._set_f64(c, (ctypes.c_uint32 * len(ins))(*[vr for vr, _ in ins]), ctypes.c_size_t(len(ins)),
                                          (ctypes.c_double * len(ins))(*[v for _, v in ins]), ctypes.c_size_t(len(ins))),
                            "fmi3SetFloat64 (clocked inputs)", t)
        active = {k.name for k in due}
        for k in self.clocks:
            if k.causality != "output":
                continue
            value = (ctypes.c_bool * 1)()
            self._check(self._get_clock(c, (ctypes.c_uint32 * 1)(k.vr), ctypes.c_size_t(1), value),
                        f"fmi3GetClock({k.name})", t)
            if value[0]:
                active.add(k.name)
                self.raised.append((t, k.name))
                self.raised_at[k.name] = n
        outs = [vr for vr in self.held if self.clocked_vr[vr] in active]
        if outs:
            vals = (ctypes.c_double * len(outs))()
            self._check(self._get_f64(c, (ctypes.c_uint32 * len(outs))(*outs), ctypes.c_size_t(len(outs)), vals,
                                      ctypes.c_size_t(len(outs))), "fmi3GetFloat64 (clocked outputs)", t)
            for vr, v in zip(outs, vals):
                self.held[vr] = float(v)
        for _ in range(MAX_UPDATES):
            needed, terminate = self.call("fmi3UpdateDiscreteStates", self.fmu.updateDiscreteStates, t=t)[:2]
            if terminate:
                self._terminated.value, self._last.value = True, t
                return
            if not needed:
                break
        else:
            raise RunError(f"{self.name}: the event iteration at t = {t:.9g} s did not end after {MAX_UPDATES} "
                           "updates of the discrete states", self.name, t)
        self._check(self._enter_step(c), "fmi3EnterStepMode", t)

    def _check(self, status: int, what: str, t: float) -> None:
        if status > 1:
            raise self.fail_status(what, status, t)

    # ------------------------------------------------------------------ the step's fast path
    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                  in_val: Any = None) -> FastPath:
        """The set passes on the inputs that are not clocked and keeps the clocked ones for their tick;
        the step is fmi3DoStep, then the event at its end if one is due; the get reads the outputs that are
        not clocked and gives each clocked one its value at its last tick."""
        self._terminated, self._last = ctypes.c_bool(False), ctypes.c_double(0.0)
        in_val = in_val if in_val is not None else (ctypes.c_double * max(1, n_in))()
        plain_in = [i for i, vr in enumerate(in_vrs) if vr not in self.clocked_vr]
        clocked_in = [(i, vr) for i, vr in enumerate(in_vrs) if vr in self.clocked_vr]
        p_in_vr = (ctypes.c_uint32 * max(1, len(plain_in)))(*[in_vrs[i] for i in plain_in])
        p_in = (ctypes.c_double * max(1, len(plain_in)))()
        plain_out = [i for i, vr in enumerate(out_vrs) if vr not in self.clocked_vr]
        clocked_out = [(i, vr) for i, vr in enumerate(out_vrs) if vr in self.clocked_vr]
        p_out_vr = (ctypes.c_uint32 * max(1, len(plain_out)))(*[out_vrs[i] for i in plain_out])
        p_out = (ctypes.c_double * max(1, len(plain_out)))()
        flags = ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()
        set_f64, get_f64, do_step_raw = self._set_f64, self._get_f64, self._do_step
        held, in_held = self.held, self._in_held

        def set_real(c: Any, vrs: Any, n: Any, vals: Any, *tail: Any) -> int:
            for i, vr in clocked_in:
                in_held[vr] = vals[i]
            if not plain_in:
                return 0
            for j, i in enumerate(plain_in):
                p_in[j] = vals[i]
            return int(set_f64(c, p_in_vr, ctypes.c_size_t(len(plain_in)), p_in, ctypes.c_size_t(len(plain_in))))

        def get_real(c: Any, vrs: Any, n: Any, out: Any, *tail: Any) -> int:
            s = 0
            if plain_out:
                s = int(get_f64(c, p_out_vr, ctypes.c_size_t(len(plain_out)), p_out, ctypes.c_size_t(len(plain_out))))
                for j, i in enumerate(plain_out):
                    out[i] = p_out[j]
            for i, vr in clocked_out:
                out[i] = held[vr]
            return s

        def do_step(c: Any, t: Any, h: Any, *tail: Any) -> int:
            s = int(do_step_raw(c, t, h, True, *(ctypes.byref(f) for f in flags)))
            if s > 1:
                return s
            if flags[1].value:   # terminateSimulation
                self._terminated.value, self._last.value = True, flags[3].value
                return s
            self._event_needed = bool(flags[0].value)
            try:
                self._event(round((t.value + h.value - self._start) / self._step))
            except RunError as exc:
                self.log.append(str(exc))
                return 4 if self.fatal else 3
            return s

        return self._handed(FastPath(ctypes.c_void_p(self.c), set_real, do_step, get_real, in_val,
                                     set_tail=(ctypes.c_size_t(n_in),), get_tail=(ctypes.c_size_t(n_out),),
                                     terminated=self._terminated, last_time=self._last, alone=CLOCKED_ALONE,
                                     abi=3))
