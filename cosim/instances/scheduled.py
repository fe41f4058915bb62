"""An FMI 3.0 Scheduled Execution instance: the master's scheduler activates the FMU's model partitions
(fmi3ActivateModelPartition) at the ticks of its input clocks, on the master's grid of steps.

The scheduler, for the instance's input clocks (:mod:`..model.clocks`):

- a periodic clock (intervalVariability constant, fixed, tunable, with intervalDecimal [s] and
  shiftDecimal [s]) ticks at shift + k interval;
- a triggered clock ticks at the times the scenario gives it (``clock_ticks``);
- a countdown clock ticks when the FMU says so: after the FMU calls clockUpdate, the master asks each
  countdown clock its interval (fmi3GetIntervalDecimal) and, where it changed, ticks it that long after
  the current instant (0: at this instant, after the partitions of higher priority).

The clocks that tick at one instant are activated in the order of their priority (lower first; FMI 3.0
2.2.8.4).  A step of the master from t to t + h activates the ticks in (t, t + h]; the ticks at the
start time are activated at the end of initialisation, so that the outputs read at a time are those after
every partition due then.  Output clocks the FMU raises are read (fmi3GetClock) and counted
(:attr:`ScheduledExecution3.raised`); they feed nothing yet.  Every tick falls on the master's grid
(``check`` refuses a clock that cannot; a countdown interval off the grid ends the run in one line).
"""
from __future__ import annotations

import ctypes
import heapq
import os
from fractions import Fraction
from typing import Any

from ..messages.errors import RunError
from ..model.clocks import Clock, clocks_of, grid_multiple
from .contract import FastPath
from .in_process import Instance3, raw

#: Why the step of a scheduled execution instance runs alone (:attr:`FastPath.alone`).
SE_ALONE = "a scheduled execution instance: its scheduler runs in Python, which holds the GIL"
_INTERVAL_CHANGED = 2   # fmi3IntervalChanged


class ScheduledExecution3(Instance3):
    """An FMI 3.0 Scheduled Execution FMU with the master's scheduler of its input clocks."""

    def _slave(self, md: Any, unzipdir: str) -> Any:
        from fmpy.fmi3 import FMU3ScheduledExecution

        self._experiment = (0.0, None, None)
        with open(os.path.join(unzipdir, "modelDescription.xml"), "rb") as fh:
            self.clocks: list[Clock] = clocks_of(fh.read())
        self._by_vr = {c.vr: c for c in self.clocks}   # (the scheduler's, at every step)
        self.raised: list[tuple[float, str]] = []   # (time [s], output clock) the FMU raised
        self._update = False
        self._start, self._step = 0.0, 1.0
        self._due: list[tuple[int, int, int]] = []  # (grid index, priority, vr): the heap of ticks to come
        return FMU3ScheduledExecution(guid=md.guid, unzipDirectory=unzipdir,
                                      modelIdentifier=md.scheduledExecution.modelIdentifier,
                                      instanceName=self.name)

    def _clock_update(self, env: Any) -> None:   # fmi3ClockUpdateCallback
        self._update = True

    def instantiate(self) -> None:
        """fmi3InstantiateScheduledExecution with this instance's log, clockUpdate and (no-op) preemption
        locks (the partitions run one at a time, in the master's thread)."""
        from fmpy.fmi3 import (fmi3ClockUpdateCallback, fmi3LockPreemptionCallback, fmi3LogMessageCallback,
                               fmi3UnlockPreemptionCallback)

        f = self.fmu
        self._cbs = (fmi3LogMessageCallback(self._log3), fmi3ClockUpdateCallback(self._clock_update),
                     fmi3LockPreemptionCallback(lambda: None), fmi3UnlockPreemptionCallback(lambda: None))
        resources = os.path.join(f.unzipDirectory, "resources") + os.path.sep

        def make() -> None:
            f.component = f.fmi3InstantiateScheduledExecution(
                self.name.encode("utf-8"), f.guid.encode("utf-8"), resources.encode("utf-8"), False, True, None,
                *self._cbs)
            if not f.component:
                raise RuntimeError("fmi3InstantiateScheduledExecution returned NULL")
        self.call("fmi3InstantiateScheduledExecution", make)
        self.c = f.component
        self._debug_logging("fmi3SetDebugLogging")
        dll = f.dll
        self._activate = raw(dll, "fmi3ActivateModelPartition")
        self._get_interval = raw(dll, "fmi3GetIntervalDecimal")
        self._get_clock = raw(dll, "fmi3GetClock")

    def schedule(self, start: float, step: float, ticks: dict[str, list[float]]) -> None:
        """The master's grid (``start`` [s], ``step`` [s]) and the times [s] of the triggered clocks
        (checked on the grid by ``check``): the ticks of the periodic and triggered clocks, by grid index."""
        self._start, self._step = start, step
        by_name = {c.name: c for c in self.clocks}
        self._horizon: dict[int, tuple[int, int]] = {}   # periodic: vr -> (first index, interval in steps)
        for c in self.clocks:
            if c.periodic and c.interval is not None:
                on_grid = c.grid(step)
                assert on_grid is not None   # (check refuses the rest)
                self._horizon[c.vr] = on_grid
                self._push(on_grid[0], c)
        for name, times in ticks.items():
            for t in times:
                n = grid_multiple(Fraction(repr(t)) - Fraction(repr(start)), step)
                assert n is not None
                self._push(n, by_name[name])

    def _push(self, n: int, c: Clock) -> None:
        heapq.heappush(self._due, (n, c.priority if c.priority is not None else 0, c.vr))

    def exit_initialization(self) -> None:
        super().exit_initialization()
        self._run_until(0)

    def _time(self, n: int) -> float:
        return self._start + n * self._step

    def _run_until(self, n_end: int) -> int:
        """Activate every tick at grid index <= ``n_end``, instant by instant, each instant's by priority:
        the FMI status (0: OK)."""
        by_vr = self._by_vr
        while self._due and self._due[0][0] <= n_end:
            n, _, vr = heapq.heappop(self._due)
            while self._due and self._due[0][:3] == (n, _, vr):   # the same tick given twice: once
                heapq.heappop(self._due)
            t = self._time(n)
            self._update = False
            status = self._activate(ctypes.c_void_p(self.c), ctypes.c_uint32(vr), ctypes.c_double(t))
            if status > 1:
                raise self.fail_status(f"fmi3ActivateModelPartition({by_vr[vr].name})", status, t)
            if vr in self._horizon:
                self._push(n + self._horizon[vr][1], by_vr[vr])
            if self._update:
                self._clocks_updated(n, t)
        return 0

    def _clocks_updated(self, n: int, t: float) -> None:
        """After clockUpdate: the countdown clocks' new intervals (ticked that long after now, on the grid),
        the output clocks the FMU raised."""
        for c in self.clocks:
            vr = (ctypes.c_uint32 * 1)(c.vr)
            if c.causality == "input" and c.variability == "countdown":
                interval, qualifier = (ctypes.c_double * 1)(), (ctypes.c_int * 1)()
                st = self._get_interval(ctypes.c_void_p(self.c), vr, ctypes.c_size_t(1), interval, qualifier)
                if st > 1:
                    raise self.fail_status(f"fmi3GetIntervalDecimal({c.name})", st, t)
                if qualifier[0] == _INTERVAL_CHANGED:
                    k = grid_multiple(repr(interval[0]), self._step)
                    if k is None or k < 0:
                        raise RunError(f"{self.name}: countdown clock {c.name} set to tick {interval[0]:g} s after "
                                       f"t = {t:g} s, off the master's grid of {self._step:g} s steps", self.name, t)
                    self._push(n + k, c)
            elif c.causality == "output":
                value = (ctypes.c_bool * 1)()
                st = self._get_clock(ctypes.c_void_p(self.c), vr, ctypes.c_size_t(1), value)
                if st > 1:
                    raise self.fail_status(f"fmi3GetClock({c.name})", st, t)
                if value[0]:
                    self.raised.append((t, c.name))

    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                  in_val: Any = None) -> FastPath:
        """fmi3SetFloat64 and fmi3GetFloat64 as for co-simulation; the step from t to t + h activates the
        partitions of the ticks in (t, t + h]."""
        dll = self.fmu.dll

        def do_step(c: Any, t: Any, h: Any, *tail: Any) -> int:
            n_end = round((t.value + h.value - self._start) / self._step)
            try:
                return self._run_until(n_end)
            except RunError as exc:
                self.log.append(str(exc))
                return 3
        return self._handed(FastPath(ctypes.c_void_p(self.c), raw(dll, "fmi3SetFloat64"), do_step,
                                     raw(dll, "fmi3GetFloat64"),
                                     in_val if in_val is not None else (ctypes.c_double * max(1, n_in))(),
                                     set_tail=(ctypes.c_size_t(n_in),), get_tail=(ctypes.c_size_t(n_out),),
                                     terminated=ctypes.c_bool(False), last_time=ctypes.c_double(0.0),
                                     alone=SE_ALONE, abi=3))
