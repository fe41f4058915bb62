"""The execution: owns the instances and the clock; runs a plan from set-up to the last step and writes
its results folder.

``run(plan, out)`` reads as its phases: load the FMUs, initialise (instantiate, set up the experiment, set
parameters and start values, enter initialisation mode, exchange outputs to inputs until nothing changes,
exit initialisation mode), step (the algorithm's generated loop, in segments between events and flushes),
and finish (terminate and free every instance exactly once; nothing after a Fatal).

The run stops at the first non-OK status of any FMU call (Warning included) or the first non-finite value
passed along a connection; non-finite values in recorded outputs stop it at the next flush of the
recording.  An FMU that ends the simulation itself (Discard from fmi2DoStep with fmi2Terminated true)
ends the run cleanly at its last successful time.  What was recorded up to there is on disk.
"""
from __future__ import annotations

import ctypes
import heapq
import math
import shutil
import sys
import tempfile
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .algorithm import InstanceIO, compile_loop
from .condition import compile_condition
from .archive import safe_extract
from .errors import CosimError, RunError
from .instance import Instance, Instance3, accessor, raw, vr_array
from .pacing import Pacer
from .failure import Call, Failure, FmiStatus
from .status import RunStatus
from .recording import NpyRecorder, OutputLock, RowBuffer, make_folder, write_csv, write_json
from .system import Plan
from .wiring import RowLayout, Wiring, discrete_copier, is_f64, is_real, table_feeder

#: Rows recorded between two flushes to disk (and progress updates).
FLUSH_ROWS = 2500


@dataclass
class RunResult:
    status: RunStatus
    message: str
    steps: int
    t_end: float
    wall_s: float               # the stepping loop, first step to last, recording included
    setup_s: float              # extraction, instantiation, initialisation
    out_dir: Path | None
    columns: list[str]
    final: dict[str, float] = field(default_factory=dict)
    fmi_s: float | None = None  # time inside FMI calls (only with timing=True)
    events: list[dict[str, Any]] = field(default_factory=list)   # the event log: time, event, action, ...
    real_time: dict[str, Any] | None = None   # pacing: factor, steps, overruns, late_max_s, late_mean_s

    @property
    def exit_code(self) -> int:
        return RunStatus(self.status).exit_code


class _Stop(Exception):
    """An FMU ended the simulation itself at ``t``."""

    def __init__(self, name: str, t: float, recorded: bool = False) -> None:
        self.name, self.t, self.recorded = name, t, recorded


class _Stopped(Exception):
    """A stop event (``events[index]``) ended the run before the step from ``t`` (step ``k``)."""

    def __init__(self, index: int, t: float, k: int) -> None:
        self.index, self.t, self.k = index, t, k


class Execution:
    """One run of a plan: its instances, wiring, row buffer and recording."""

    def __init__(self, plan: Plan, out: Path, timing: bool = False) -> None:
        self.plan, self.out, self.timing = plan, out, timing
        sc = plan.scenario
        self.t0, self.h, self.n_steps = sc.start, sc.step, plan.n_steps
        self.work = Path(tempfile.mkdtemp(prefix="wmr-cosim-fmus-"))
        self.instances: dict[str, Instance] = {}
        self.columns = ["time"] + [r.column for r in plan.record]
        self.types = ["Real"] + ["Int64" if r.var.fmi_type == "Enumeration" and plan.instances[r.instance].model.fmi == 3
                                 else r.var.fmi_type for r in plan.record]
        self.recorder: NpyRecorder | None = None
        self.rows: RowBuffer | None = None
        self.ios: list[InstanceIO] = []
        self.fmi_acc = [0.0]
        self.k_done = 0
        self.setup_s = self.wall_s = 0.0
        self.status, self.message = RunStatus.OK, ""
        self._discrete: dict[tuple[str, int], Any] = {}   # values events have set on non-Real inputs
        self.pacer: Pacer | None = None                    # real-time pacing (None: as fast as it goes)
        self.callbacks: list[Callable[[], Any]] = []       # called after every step (the API's step hooks)
        self.event_log: list[dict[str, Any]] = []          # every event that acted: time, event, action
        self._conds: list[tuple[Any, Callable[[float], bool]]] = []
        self._pending: list[tuple[int, int, Any, float]] = []
        self._dirty = False                                # the copies changed outside an event (set())
        self.stop_request = False                          # a callback asked to end the run after its step
        self.in_step = False                               # inside advance() (callbacks run there)
        self._bar = None

    # ---------------------------------------------------------------- set-up
    def load(self) -> None:
        """Extract every FMU file once and create an Instance per instance of the plan."""
        unz: dict[Path, str] = {}
        for name, ip in self.plan.instances.items():
            p = ip.model.path.resolve()
            if p not in unz:
                unz[p] = str(safe_extract(p, self.work / f"{len(unz)}_{p.stem}"))
            log = self.out / "logs" / f"{name}.log"
            if ip.spec.isolate:
                from .isolation import IsolatedInstance, spin_for
                spin = spin_for(sum(q.spec.isolate for q in self.plan.instances.values()))
                self.instances[name] = IsolatedInstance(name, ip.model.md, unz[p], log, ip.spec.logging,
                                                        ip.spec.step_timeout or 60.0, spin)
            else:
                cls = Instance3 if ip.model.fmi == 3 else Instance
                self.instances[name] = cls(name, ip.model.md, unz[p], log, ip.spec.logging)

    def initialise(self, check_inputs: bool) -> None:
        """Instantiate, set up, set start values, initialise with the inputs at their fixed point, and
        record the row at the start time."""
        sc = self.plan.scenario
        for name, inst in self.instances.items():
            inst.instantiate()
            inst.setup_experiment(self.t0, sc.stop, self.plan.instances[name].tolerance)
            inst.set_values(self.plan.instances[name].parameters)
        for inst in self.instances.values():
            inst.enter_initialization()
        self.layout = RowLayout.of(self.plan)
        self.wiring = Wiring(self.plan, self.layout)
        self.ios = [self._io(n) for n in self.plan.order]
        self._exchange_initial(check_inputs)
        for io in self.ios:
            self.instances[io.name].exit_initialization()
        self._get_all(self.t0)
        self.recorder = NpyRecorder(self.out / "signals.npy", self.columns, self.types)
        self.rows = RowBuffer(self.recorder, [0] + [self.layout.slot(r) for r in self.plan.record],
                              self.layout.n_double, self.layout.n_int)
        self.layout.row[0] = self.t0
        self.rows.chunk.append(bytes(self.layout.buf))

    def _io(self, n: str) -> InstanceIO:
        """The loop's view of instance ``n``: raw entry points, input and output arrays, copies."""
        inst, lay, plan = self.instances[n], self.layout, self.plan
        dll, fmi = getattr(inst.fmu, "dll", None), self.plan.instances[n].model.fmi
        names = ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal") if fmi == 2 else \
            ("fmi3SetFloat64", "fmi3DoStep", "fmi3GetFloat64")
        vrs, nvals = self.wiring.vrs[n], len(self.wiring.values[n])
        n_out = sum(size for _, size in lay.reals[n])
        if hasattr(inst, "entry_points"):   # isolated: the step slot in shared memory
            *fns, in_val = inst.entry_points(vrs, nvals, [vr for vr, _ in lay.reals[n]], n_out)
        else:
            fns, in_val = [raw(dll, f) for f in names], (ctypes.c_double * max(1, nvals))()
        io = InstanceIO(
            n, ctypes.c_void_p(inst.c), *fns, vr_array(vrs), in_val, ctypes.c_size_t(len(vrs)),
            vr_array([vr for vr, _ in lay.reals[n]]), lay.out_arr[n], ctypes.c_size_t(len(lay.reals[n])),
            self.wiring.copies(n), _extras(inst, [r for r in lay.extra if r.instance == n], lay),
            [discrete_copier(self.instances, c) for c in plan.connections if c.dst == n and not is_real(c)],
            table_feeder(inst, self.wiring.tables.get(n),
                         [ip for ip in plan.inputs if ip.instance == n and not is_f64(ip.var)]),
            fmi, ctypes.c_size_t(nvals), ctypes.c_size_t(n_out))
        if self.timing:
            io.set_real, io.do_step, io.get_real = (_timed(f, self.fmi_acc) for f in (io.set_real, io.do_step,
                                                                                       io.get_real))
        return io

    def _exchange_initial(self, check_inputs: bool) -> None:
        """In initialisation mode: outputs to inputs in the plan's order, pass after pass, until no input
        changes (a chain of N instances settles in at most N passes, whatever the order)."""
        self._get_all(self.t0)
        last: list[float] | None = None
        for _ in range(len(self.ios) + 1):
            values: list[float] = []
            for io in self.ios:
                inst = self.instances[io.name]
                if io.feed is not None:
                    _check(inst, "fmi2Set (tabulated inputs)", io.feed(0), self.t0)
                for pos, arr, i, f, o in io.copies:
                    io.in_val[pos] = arr[i] * f + o if (f != 1.0 or o != 0.0) else arr[i]
                    values.append(io.in_val[pos])
                if check_inputs and any(v - v != 0.0 for v in io.in_val[:io.nv_in.value]):
                    raise self.wiring.bad_input(io.name, io.in_vr, io.copies, self.t0)
                if io.n_in.value:
                    _check(inst, "set inputs", _set_reals(io), self.t0)
                for fn in io.other:
                    _check(inst, "set inputs (a connection)", fn(), self.t0)
                if io.n_out.value:
                    _check(inst, "get outputs", _get_reals(io), self.t0)
            if values == last:
                break
            last = values

    def _get_all(self, t: float) -> None:
        """Every instance's Float64 outputs and recorded other outputs into the row."""
        for io in self.ios:
            inst = self.instances[io.name]
            if io.n_out.value:
                _check(inst, "get outputs", _get_reals(io), t)
            for get, vrs, n, buf, nv, slots in io.extras:
                _check(inst, "get outputs (recorded)", get(vrs, n, buf, nv), t)
                for e, slot in slots:
                    self.layout.write(slot, buf[e])

    # ---------------------------------------------------------------- stepping
    def simulate(self, progress: bool | None, check_inputs: bool, stop: "_Interrupt") -> None:
        """Step from the start to the stop time in segments that end at events and flushes."""
        self.begin(progress, check_inputs, stop)
        try:
            self.advance(self.n_steps)
        finally:
            self.end()

    def begin(self, progress: bool | None, check_inputs: bool, stop: "_Interrupt | None" = None) -> None:
        """Ready to step (after :meth:`initialise`): the progress bar, the conditions' predicates, the
        conditions evaluated at the start time (an event whose condition holds there fires before the first
        step), the pacer's clock."""
        self._ev_i, self._loop, self._check_inputs, self._stop = 0, None, check_inputs, stop
        self._bar = _progress(progress, self.n_steps, self.h, sum(self.plan.internal_steps.values()))
        self._conds = []
        for ev in self.plan.conditions:
            read = {ref: self._reader(inst, var) for ref, (inst, var) in ev.reads.items()}
            self._conds.append((ev, compile_condition(ev.condition, read)))
        self._cond_state = [False] * len(self._conds)
        self._fired = [False] * len(self._conds)
        self._pending: list[tuple[int, int, Any, float]] = []   # (step, sequence, event, time it fired)
        self._seq = 0
        self._evaluate(0)
        if self.pacer is not None:
            self.pacer.start(self.t0)

    def advance(self, k_target: int) -> None:
        """Step from ``k_done`` to step ``k_target`` (at most the last): the generated loop in segments that
        end at events, flushes and ``k_target``; one step per segment while conditions, callbacks or
        pacing need the time between steps.  Raises _Stop / _Stopped when the run ends early."""
        rows, events, sc = self.rows, self.plan.events, self.plan.scenario
        block = FLUSH_ROWS * sc.decimation
        k_target = min(k_target, self.n_steps)
        wall0 = _time.perf_counter()
        self.in_step = True
        try:
            k = self.k_done
            while k < k_target and not self.stop_request:
                changed = self._loop is None or self._dirty
                self._dirty = False
                changed = self._apply_due(k) or changed
                if changed:
                    for io in self.ios:
                        io.copies = self.wiring.copies(io.name)
                    self._loop = compile_loop(self.ios, sc.algorithm, self.t0, self.h, sc.decimation, self.n_steps,
                                              self.layout, rows.chunk, self._check_inputs)
                per_step = self._conds or self.callbacks or self.pacer is not None
                k_end = k + 1 if per_step else min(k_target, k + block - (k % block))
                if self._ev_i < len(events):
                    k_end = min(k_end, max(events[self._ev_i].step, k + 1))
                if self._pending:
                    k_end = min(k_end, max(self._pending[0][0], k + 1))
                self._errors = {n: i.n_errors for n, i in self.instances.items()}
                fail = self._loop(k, k_end)
                if k_end < self.n_steps and self._stop is not None:  # a Ctrl-C after the last step interrupts nothing
                    self._stop.check()
                if fail is not None:
                    self._failed(fail)
                self.k_done = k = k_end
                if len(rows) >= FLUSH_ROWS or k == self.n_steps:
                    self._flush()
                if self._bar is not None:
                    self._bar.update(self.k_done * self.h - self._bar.n)
                if per_step:
                    if self._conds:
                        self._evaluate(k)
                    for cb in self.callbacks:
                        cb()
                    if self.stop_request:
                        return
                    if self.pacer is not None:
                        self.pacer.wait(self.t0 + k * self.h)
        except KeyboardInterrupt:
            last = rows.last_time()  # the steps completed inside the interrupted segment
            if last is not None:
                self.k_done = max(self.k_done, int(round((last - self.t0) / self.h)))
            raise
        finally:
            self.in_step = False
            self.wall_s += _time.perf_counter() - wall0

    def end(self) -> None:
        """Stepping is over: close the progress bar."""
        bar = getattr(self, "_bar", None)
        if bar is not None:
            bar.close()   # (tqdm's close may be called again)

    def _apply_due(self, k: int) -> bool:
        """Apply the timed events of step k and the condition events due at it; whether the copies changed."""
        changed = False
        events = self.plan.events
        while self._ev_i < len(events) and events[self._ev_i].step <= k:
            changed = self._act(events[self._ev_i], k, None) or changed
            self._ev_i += 1
        while self._pending and self._pending[0][0] <= k:
            _, _, ev, fired = heapq.heappop(self._pending)
            changed = self._act(ev, k, fired) or changed
        return changed

    def _act(self, ev: Any, k: int, fired: float | None) -> bool:
        """One event's action before the step from t_k, written to the event log."""
        t = self.t0 + k * self.h
        entry: dict[str, Any] = {"time": t, "event": ev.index, "action": ev.action}
        if ev.ref is not None:
            entry["variable"] = ev.ref
        if ev.value is not None:
            entry["value"] = ev.value
        if fired is not None:
            entry["when"] = ev.when
            entry["condition_time"] = fired
        self.event_log.append(entry)
        if ev.action == "stop":
            raise _Stopped(ev.index, t, k)
        if ev.action == "set":
            self.instances[ev.instance].set_values([(ev.var, ev.value)])
            return False
        if ev.var.type == "Real":
            return self.wiring.apply(ev)
        self._set_discrete(ev)
        return False

    def _evaluate(self, k: int) -> None:
        """The conditions at t_k (after the step that ends there): an event whose condition has become
        true acts ``delay`` later, before the step from the first communication point at or after it."""
        t = self.t0 + k * self.h
        for j, (ev, pred) in enumerate(self._conds):
            now = pred(t)
            if now and not self._cond_state[j] and not (ev.trigger == "once" and self._fired[j]):
                self._fired[j] = True
                kd = k if ev.delay == 0 else int(math.ceil((t + ev.delay - self.t0) / self.h - 1e-9))
                if kd < self.n_steps:
                    self._seq += 1
                    heapq.heappush(self._pending, (kd, self._seq, ev, t))
            self._cond_state[j] = now

    def _reader(self, inst: str, var: Any) -> Callable[[], Any]:
        """A function returning a variable's current value: from the row buffer for a Float64 output it
        holds (written by the loop at every step), else through an FMI get."""
        lay = self.layout
        if is_f64(var) and var.causality == "output" and any(vr == var.vr for vr, _ in lay.reals[inst]):
            row, slot = lay.row, lay.offset[inst] + lay.index(inst, var.vr)
            return lambda: row[slot]
        instance = self.instances[inst]
        return lambda: instance.get_value(var)

    # ---------------------------------------------------------------- values between steps
    def set(self, inst: str, var: Any, value: Any) -> None:
        """Set a variable between steps (the value already checked against its type and range): a tunable
        parameter; a Real input or an output feeding connections is overridden until :meth:`release`; an
        input no connection or table drives is set on the FMU, which holds it."""
        ref = f"{inst}.{self.plan.instances[inst].our_name(var)}"
        if var.causality == "parameter":
            if var.variability != "tunable":
                raise CosimError(f"{ref} is a {var.variability} parameter: only tunable parameters change during "
                                 "a run")
            self.instances[inst].set_values([(var, value)])
        elif is_f64(var) and var.causality in ("input", "output") and self.wiring.is_wired(inst, var.vr,
                                                                                            var.causality):
            self._dirty = self.wiring.act(inst, var.vr, var.causality, "override", value) or self._dirty
        elif var.causality == "input":
            if any(c.dst == inst and c.dst_var.vr == var.vr for c in self.plan.connections) or \
                    any(ip.instance == inst and ip.var.vr == var.vr for ip in self.plan.inputs):
                raise CosimError(f"{ref} is driven by a connection or a table: it cannot be set")
            self.instances[inst].set_values([(var, value)])
            self._discrete[(inst, var.vr)] = value
        elif var.causality == "output":
            raise CosimError(f"{ref} is an output that feeds no connection: setting it would change nothing")
        else:
            raise CosimError(f"{ref} is {var.causality}: only inputs, outputs feeding connections and tunable "
                             "parameters can be set between steps")

    def release(self, inst: str, var: Any) -> None:
        """End an override set by :meth:`set` (the value follows its source again)."""
        if is_f64(var) and self.wiring.is_wired(inst, var.vr, var.causality):
            self._dirty = self.wiring.act(inst, var.vr, var.causality, "reset", None) or self._dirty

    def _set_discrete(self, ev: Any) -> None:
        """An event on an Integer, Enumeration, Boolean or String input: set now, held until the next."""
        key = (ev.instance, ev.var.vr)
        start = ev.var.start
        for v, val in self.plan.instances[ev.instance].parameters:
            if v.vr == ev.var.vr:
                start = val
        current = self._discrete.get(key, start)
        if ev.action == "reset":
            self._discrete.pop(key, None)
            value = start
        elif ev.action == "bias":
            value = int(current or 0) + int(ev.value)
            self._discrete[key] = value
        else:
            value = ev.value
            self._discrete[key] = value
        if value is not None:
            self.instances[ev.instance].set_values([(ev.var, value)])

    def _failed(self, f: Failure) -> None:
        """A segment stopped at step ``f.step``: an FMU that ended the simulation, or an error."""
        name, tf = f.instance, self.t0 + f.step * self.h
        # a get after the step to t_kf failed: that step's row is not recorded, the steps done are kf - 1
        self.k_done = f.step - 1 if f.call.after_step else f.step
        inst = self.instances[name]
        if f.call is Call.NON_FINITE_INPUT:
            io = self.ios[self.plan.order.index(name)]
            raise self.wiring.bad_input(name, io.in_vr, io.copies, tf)
        if f.call is Call.TERMINATED:  # the step's row is recorded already
            raise _Stop(name, tf, recorded=True)
        if f.call is Call.DO_STEP and f.fmi == 2 and int(f.value) == FmiStatus.DISCARD \
                and inst.n_errors == self._errors[name]:
            # fmi2Terminated after a Discard with nothing logged at Discard, Error or Fatal: the FMU ended the
            # simulation (pythonfmu reports every failed step as terminated; its message tells them apart)
            t_end = inst.terminated_at()
            if t_end is not None:
                raise _Stop(name, t_end if math.isfinite(t_end) else tf)
        raise inst.fail_status(f.call.name_for(f.fmi), int(f.value), tf)

    def ended(self, s: "_Stop | _Stopped") -> None:
        """The run ended before its stop time: an FMU ended the simulation, or a stop event."""
        if isinstance(s, _Stopped):
            self.k_done = s.k
            self.status = RunStatus.STOPPED
            self.message = f"stopped by events[{s.index}] at t = {s.t:.6g} s"
            return
        self.k_done = min(self.n_steps, int(math.floor((s.t - self.t0) / self.h + 1e-9)))
        try:
            # the row at the FMU's last time, unless it is the last row recorded (the FMU ended the
            # simulation at a communication point without advancing)
            if not s.recorded and (s.t - self.layout.row[0]) / self.h > 1e-9:
                self.record_final(s.t)
            self.status = RunStatus.TERMINATED
            self.message = f"terminated by FMU {s.name} at t = {s.t:.6g} s"
        except RunError as exc:
            self.status, self.message = RunStatus.FAILED, str(exc)

    def record_final(self, t: float) -> None:
        """The row at the time an FMU ended the simulation."""
        self._get_all(t)
        self.layout.row[0] = t
        self.rows.chunk.append(bytes(self.layout.buf))

    def _flush(self) -> None:
        try:
            self.rows.flush()
        except RunError as exc:
            self.k_done = min(self.k_done, int(round((exc.time - self.t0) / self.h)))
            raise

    # ---------------------------------------------------------------- finish
    def close(self) -> None:
        """Flush what is left, terminate and free every instance (the Fatal rule), close the recording."""
        if self.rows is not None and len(self.rows):
            try:
                self._flush()
            except RunError as exc:
                if self.status != RunStatus.FAILED:
                    self.status, self.message = RunStatus.FAILED, str(exc)
        for inst in self.instances.values():
            inst.shutdown()
        if self.recorder is not None:
            self.recorder.close()
        shutil.rmtree(self.work, ignore_errors=True)


def run(plan: Plan, out_dir: str | Path | None, progress: bool | None = None,
        timing: bool = False, check_inputs: bool = True, real_time: float | None = None) -> RunResult:
    """Run the plan and write its results folder ``out_dir``: signals.npy (written as the run goes),
    signals.csv, scenario.json (the scenario as resolved), logs/<instance>.log and summary.json.
    ``out_dir=None`` runs in a temporary folder that is removed afterwards (the result keeps the
    final values).  ``timing=True`` also measures the time spent inside the stepping FMI calls.
    ``real_time=FACTOR`` paces the steps to the wall clock at FACTOR x real time (cosim.pacing)."""
    pacer = Pacer(real_time) if real_time is not None else None
    keep = out_dir is not None
    out = make_folder(Path(out_dir)) if keep else Path(tempfile.mkdtemp(prefix="wmr-cosim-out-"))
    with OutputLock(out):
        return _run(plan, out, keep, progress, timing, check_inputs, pacer)


def _run(plan: Plan, out: Path, keep: bool, progress: bool | None, timing: bool, check_inputs: bool,
         pacer: Pacer | None = None) -> RunResult:
    _prepare(out, plan)
    ex = Execution(plan, out, timing)
    ex.pacer = pacer
    stop = _Interrupt()
    t_setup = _time.perf_counter()
    try:
        ex.load()
        ex.initialise(check_inputs)
        ex.setup_s = _time.perf_counter() - t_setup
        stop.check()
        ex.simulate(progress, check_inputs, stop)
    except (_Stop, _Stopped) as s:
        ex.ended(s)
    except KeyboardInterrupt:
        ex.status = RunStatus.INTERRUPTED
        ex.message = f"interrupted by the user at t = {ex.t0 + ex.k_done * ex.h:.6g} s"
    except CosimError as exc:
        ex.status, ex.message = RunStatus.FAILED, str(exc)
        if getattr(exc, "died", False) and exc.time is not None:  # an isolated FMU died inside a segment
            ex.k_done = int(round((exc.time - ex.t0) / ex.h))
    finally:
        stop.restore()
        ex.close()
    res = _results(ex, keep)
    if not keep:
        shutil.rmtree(out, ignore_errors=True)
    return res


def _prepare(out: Path, plan: Plan) -> Path:
    """The results folder, emptied of an earlier run's result files, with the resolved scenario."""
    (out / "logs").mkdir(exist_ok=True)
    for stale in ("signals.npy", "signals.csv", "summary.json"):
        (out / stale).unlink(missing_ok=True)
    for old in (out / "logs").glob("*.log"):
        old.unlink()
    write_json(out / "scenario.json", _resolved(plan))
    return out


def _results(ex: Execution, keep: bool) -> RunResult:
    """The run's result, signals.csv and summary.json."""
    plan, out = ex.plan, ex.out
    sc = plan.scenario
    final: dict[str, float] = {}
    if ex.recorder is not None and ex.recorder.rows:
        data = np.load(out / "signals.npy", mmap_mode="r")
        final = {c: data[c][-1].item() for c in ex.columns}
        if keep and sc.csv:
            write_csv(out / "signals.npy", out / "signals.csv")
    t_end = final.get("time", ex.t0 + ex.k_done * ex.h) if ex.status == RunStatus.TERMINATED \
        else ex.t0 + ex.k_done * ex.h
    res = RunResult(ex.status, ex.message, ex.k_done, t_end, ex.wall_s, ex.setup_s, out if keep else None,
                    ex.columns, final, ex.fmi_acc[0] if ex.timing else None, list(ex.event_log),
                    ex.pacer.summary() if ex.pacer is not None else None)
    write_json(out / "summary.json", {
        "status": ex.status, "message": ex.message, "steps": ex.k_done, "n_steps": plan.n_steps,
        "t_end": res.t_end, "step": ex.h, "algorithm": sc.algorithm, "wall_s": round(ex.wall_s, 6),
        "setup_s": round(ex.setup_s, 6),
        "us_per_step": round(ex.wall_s / ex.k_done * 1e6, 3) if ex.k_done else None,
        "rows": ex.recorder.rows if ex.recorder else 0,
        "instances": {n: {"fmu": str(ip.model.path), "model": ip.model.model_name,
                          "log_lines": ex.instances[n].log_lines if n in ex.instances else 0,
                          "log_received": ex.instances[n].received if n in ex.instances else 0}
                      for n, ip in plan.instances.items()},
        "final": final,
        "columns": plan.columns(),
        "not_recorded": plan.not_recorded,
        "events": ex.event_log,
        **({"real_time": res.real_time} if res.real_time is not None else {}),
    })
    return res


# ---------------------------------------------------------------------- helpers
class _Interrupt:
    """Ctrl-C during a run: a Python KeyboardInterrupt raised inside an FMU's own Python code (a pythonfmu
    slave runs in this interpreter) would make that FMU report Fatal.  So the first SIGINT only sets a
    flag, checked between loop segments (every few hundredths of a second); a second one interrupts at once."""

    def __init__(self) -> None:
        import signal
        import threading

        self.flag = False
        self.old = None
        if threading.current_thread() is threading.main_thread():
            self.old = signal.signal(signal.SIGINT, self._handler)

    def _handler(self, signum, frame) -> None:
        if self.flag:
            raise KeyboardInterrupt
        self.flag = True

    def check(self) -> None:
        if self.flag:
            raise KeyboardInterrupt

    def restore(self) -> None:
        if self.old is not None:
            import signal
            signal.signal(signal.SIGINT, self.old)
            self.old = None


def _extras(inst: Instance, recs: list[Any], lay: RowLayout) -> list[tuple]:
    """One getter per FMI type for an instance's recorded outputs that are not Float64:
    (get, vrs, n, buffer, n_values, [(index in the buffer, row slot)])."""
    out = []
    for t in sorted({r.var.fmi_type for r in recs}):
        mine = [r for r in recs if r.var.fmi_type == t]
        vars_ = list({r.var.vr: r.var for r in mine}.values())
        start = {}
        i = 0
        for v in vars_:
            start[v.vr] = i
            i += v.size
        get, ctype = accessor(inst, t, "Get")
        out.append((get, vr_array([v.vr for v in vars_]), ctypes.c_size_t(len(vars_)), (ctype * i)(),
                    ctypes.c_size_t(i), [(start[r.var.vr] + r.elem, lay.slot(r)) for r in mine]))
    return out


def _set_reals(io: InstanceIO) -> int:
    if io.fmi == 2:
        return io.set_real(io.c, io.in_vr, io.n_in, io.in_val)
    return io.set_real(io.c, io.in_vr, io.n_in, io.in_val, io.nv_in)


def _get_reals(io: InstanceIO) -> int:
    if io.fmi == 2:
        return io.get_real(io.c, io.out_vr, io.n_out, io.out_val)
    return io.get_real(io.c, io.out_vr, io.n_out, io.out_val, io.nv_out)


def _timed(fn: Any, acc: list[float]) -> Any:
    pc = _time.perf_counter

    def wrapped(*args: Any) -> int:
        t0 = pc()
        r = fn(*args)
        acc[0] += pc() - t0
        return r
    return wrapped


def _check(inst: Instance, what: str, status: int, t: float) -> None:
    if status:
        raise inst.fail_status(what, status, t)


def _progress(enabled: bool | None, steps: int, h: float, internal: int = 0):
    """The progress bar on a terminal (runs of more than 5,000 steps, unless asked for or not): simulated
    seconds done of the run's, the rate in simulated seconds per second, and the FMUs' fixed internal steps
    over the run where they declare them."""
    if enabled is None:
        enabled = sys.stderr.isatty() and steps > 5000
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    what = f" ({internal:.3g} internal steps)" if internal else ""
    return tqdm(total=steps * h, leave=False, file=sys.stderr, mininterval=0.5, unit="s",
                bar_format="{l_bar}{bar}| t = {n:.4g} of {total:.4g} s" + what + " [{elapsed}<{remaining}, "
                           "{rate_fmt}]")


def _resolved(plan: Plan) -> dict[str, Any]:
    sc = plan.scenario
    return {"file": sc.file, "experiment": {"start": sc.start, "stop": sc.stop, "step": sc.step,
                                            "algorithm": sc.algorithm, "order": sc.order,
                                            "tolerance": sc.tolerance},
            "instances": {n: {"fmu": str(ip.model.path), "model": ip.model.model_name,
                              "parameters": {v.name: val for v, val in ip.parameters},
                              "names": ip.spec.names, "units": ip.spec.units, "logging": ip.spec.logging,
                              "tolerance": ip.tolerance}
                          for n, ip in plan.instances.items()},
            "connections": [{"from": c.spec.src, "to": c.spec.dst, "factor": c.factor, "offset": c.offset}
                            for c in plan.connections],
            "record": [r.column for r in plan.record], "columns": plan.columns(), "decimation": sc.decimation,
            "events": [{"time": e.time, "variable": e.ref, "action": e.action, "value": e.value,
                        **({"when": e.when, "trigger": e.trigger, "delay": e.delay} if e.when else {})}
                       for e in sorted(plan.events + plan.conditions, key=lambda e: e.index)],
            "document": sc.data}
