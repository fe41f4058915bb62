"""The execution: the one object that steps a system (libcosim's ``execution``).  It owns the instances,
the clock, the algorithm, the observers and the manipulators, and the run's results folder (or none: a
run kept in memory).

    ex = Execution(plan, "out")            # the folder locked, scenario.json written
    ex.initialize()                        # FMUs loaded, set up, initialised; the row at the start time
    ex.step_to(10.0)                       # or step(n), simulate_until(t), simulate_until() to the end
    ex.set("plant.mu", 0.2); ex.get("plant.x_A")
    result = ex.close()                    # RunResult; summary.json, signals.csv written

Every driver (``run`` below, the Python API, protocols, sweeps, the paper job) is a few calls of these.

A step flows: before each segment the manipulators act (timed and condition events, the script's
changes) and, when the copies of some input changed, the algorithm takes the new ones; the algorithm
advances from step k to the end of the segment, which is the nearest of: the target, the next action of a
manipulator, a recording flush, and one step when an observer or manipulator must see every step; after
the segment the observers are called (recording, progress, conditions, callbacks, pacing).

The run stops at the first non-OK status of any FMU call (Warning included) or the first non-finite value
passed along a connection; non-finite values in recorded outputs stop it at the next flush of the
recording.  An FMU that ends the simulation itself (Discard from fmi2DoStep with fmi2Terminated true, or
fmi3DoStep's terminateSimulation) ends the run cleanly at its last successful time.  A stop event or the
script ends it cleanly before its stop time.  What was recorded up to there is on disk, and the status
(:class:`.status.RunStatus`) and message are set once, where the run ends (:meth:`Execution._end_with`).
"""
from __future__ import annotations

import ctypes
import dataclasses
import math
import shutil
import tempfile
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..instances.contract import FmuInstance
from ..instances.failure import Call, Failure, FmiStatus, InstanceLost
from ..instances.handoff import Handoff
from ..instances.model_exchange import ModelExchange
from ..messages.errors import CosimError, RunError, ScenarioError
from ..model.description import Variable
from ..plan.records import EventPlan, Plan
from ..plan.resolution import given_event
from ..plan.wiring import RowLayout, Wiring
from ..results.event_log import ended_entry, instance_entries, table
from ..results.folder import ResultsFolder, RunResult, scenario_record, summary, write_results, write_robustness
from ..results.status import RunStatus
from ..stepping import table as algorithms
from ..stepping.algorithm import Algorithm, Clock, InstanceIO
from ..stepping.multirate import MultiRate
from .access import VariableAccess
from .interrupt import Interrupt
from .manipulators import Actuator, ConditionEvents, EventStop, Manipulator, ScriptChanges, TimedEvents
from .monitoring import RequirementMonitors
from .observers import Observer, Pacing, ProgressBar, Recorder, StepCallback
from .pacing import Pacer
from .startup import (check, exchange_initial, handoff_for, instance_io, load_instances, read_outputs, recorded_getters,
                      recorded_types, set_up)
from .views import ManipulatedRun, ObservedRun

__all__ = ["Execution", "RunResult", "run"]


class FmuEnded(Exception):
    """An FMU ended the simulation itself at ``t`` [s] (``recorded``: the row of that time is recorded)."""

    def __init__(self, name: str, t: float, recorded: bool = False) -> None:
        super().__init__(name, t)
        self.name, self.t, self.recorded = name, t, recorded


def _algorithm(plan: Plan) -> Algorithm:
    """The algorithm object of a plan: the scenario's, at each instance's own rate where one has one."""
    sc = plan.scenario
    return algorithms.make(sc.algorithm, sc.iteration, sc.adaptive, workers=sc.workers,
                           own_rates=any(ip.decimation > 1 for ip in plan.instances.values()))


@dataclass
class SavedPoint:
    """A communication point of a run to come back to (:meth:`Execution.save_point`): the steps done, the
    row's bytes, each instance's saved state, the wiring's overrides and biases, the event log's length."""

    k: int
    row: bytes
    states: dict[str, Any]
    overrides: dict[tuple[str, int, str], tuple[str, float]]
    n_log: int


class Execution:
    """One run of a plan, stepped by its driver (see the module's docstring).

    ``out``: the results folder (None: none, the run kept in memory; the result has the final values, the
    summary and the scenario as resolved, and the signals with ``keep_signals``); ``progress``: the progress
    bar (None: on a terminal, for long runs); ``timing``: measure the time inside the step's FMI calls;
    ``check_inputs``: refuse non-finite values on connections; ``real_time``: pace the steps at that factor
    of the wall clock;
    ``algorithm``: an :class:`.algorithm.Algorithm` object (default: the scenario's)."""

    def __init__(self, plan: Plan, out: str | Path | None = None, *, progress: bool | None = False,
                 timing: bool = False, check_inputs: bool = True, real_time: float | None = None,
                 algorithm: Algorithm | None = None, keep_signals: bool = False) -> None:
        sc = plan.scenario
        start, _, step = sc.times()
        self.plan = plan
        self.clock = Clock(start, step, plan.n_steps, sc.decimation, None if plan.last_step is None else sc.stop)
        self.algorithm = algorithm if algorithm is not None else _algorithm(plan)
        slow = [n for n, ip in plan.instances.items() if ip.decimation > 1]
        if slow and not isinstance(self.algorithm, MultiRate):
            raise ScenarioError(sc.file, f"instances.{slow[0]}.step",
                                f"{slow[0]} steps at its own rate, and the algorithm given "
                                f"({type(self.algorithm).__name__}) steps every instance at every step "
                                "(cosim.stepping.multirate.MultiRate steps them at their rates)")
        self.progress, self.timing, self.check_inputs, self.keep_signals = progress, timing, check_inputs, keep_signals
        self.pacer = Pacer(real_time) if real_time is not None else None
        self.columns = ["time"] + [r.column for r in plan.record]
        self.instances: dict[str, FmuInstance] = {}   # (filled at initialisation)
        self.handoff: Handoff | None = None   # how the children and the master wait (filled at initialisation)
        self.ios: list[InstanceIO] = []
        self.observers: list[Observer] = []        # in the order added: the built-in ones first
        self.manipulators: list[Manipulator] = []  # likewise (the scenario's events first)
        self.status, self.message = RunStatus.OK, ""
        self._instance_events: list[dict[str, Any]] = []   # the instances' entries of the event table
        self.result: RunResult | None = None
        self.k_done = 0
        self.setup_s = self.wall_s = 0.0
        self._fmi_acc = [0.0]   # [s] inside the step's FMI calls (with timing)
        self._errors: dict[str, int] = {}          # each instance's logged errors before the segment
        self._pacing: Pacing | None = None
        self._per_step = False                     # some observer or manipulator must see every step
        self._stop_requested = False
        self._in_step = False
        self._started = False                      # initialize() was called
        self._points: list[SavedPoint] = []        # saved points not freed yet (save_point)
        self._ready = False                        # ... and the run can step
        self._observed, self._manipulated = ObservedRun(self), ManipulatedRun(self)   # what the parts see
        layout = self._layout = RowLayout.of(plan)
        self._wiring = Wiring(plan, layout)
        actuator = self._actuator = Actuator(plan, self.instances, self._wiring)
        self._script = ScriptChanges(actuator)
        self._given: dict[str, TimedEvents] = {}   # the events drivers give, by source (give)
        self.access = VariableAccess(plan, self.instances, layout, self._script)   # the variables by reference
        self.folder = ResultsFolder(out) if out is not None else None   # (None: the run kept in memory)
        if self.folder is not None:
            try:
                self.folder.prepare(plan)
            except BaseException:
                self.folder.release()
                raise
        self._work = Path(tempfile.mkdtemp(prefix="wmr-cosim-fmus-"))
        self._slots = [layout.slot(r) for r in plan.record]   # each recorded column's slot in the row
        self._recorder = Recorder(self.folder.signals if self.folder is not None else None, self.columns,
                                  recorded_types(plan), [0] + self._slots, layout, layout.n_int, self.clock,
                                  native=not plan.scenario.event_rows)
        self._requirements = RequirementMonitors(plan.requirements) if plan.requirements else None
        self._add_builtin_parts(progress)

    def _add_builtin_parts(self, progress: bool | None) -> None:
        """The scenario's events, its requirements' monitors, the recording and the progress bar, added as a
        script adds its own (and so before them)."""
        plan = self.plan
        self.add_manipulator(TimedEvents(self._actuator, plan.events))
        self.add_manipulator(ConditionEvents(self._actuator, plan.conditions))
        if self._requirements is not None:   # (a run without requirements has no part that sees every step)
            self.add_manipulator(self._requirements)
        self.add_observer(self._recorder)
        self.add_observer(ProgressBar(progress, self.clock, sum(plan.internal_steps.values())))
        self._builtin_parts = len(self.manipulators) + len(self.observers)

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        """The current communication point t_k = start + k h [s]."""
        return self.clock.time(self.k_done)

    @property
    def ended(self) -> bool:
        return self.result is not None

    def __enter__(self) -> "Execution":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ set-up
    def initialize(self) -> None:
        """Load, instantiate, set up, set start values, initialise with the inputs at their fixed point;
        record the row at the start time; the observers and manipulators started.  A failure ends the run
        (the result is set, the FMUs freed) and is raised."""
        if self._started or self.result is not None:
            raise CosimError("the execution is initialised already")
        self._started = True
        interrupt = Interrupt()
        t_setup = _time.perf_counter()
        try:
            self._initialise()
            self.setup_s = _time.perf_counter() - t_setup
            interrupt.check()
            self._start()
        except BaseException as exc:
            self._end_by(exc)
            raise
        finally:
            interrupt.restore()

    def _initialise(self) -> None:
        plan, layout, wiring = self.plan, self._layout, self._wiring
        self.handoff = handoff_for(plan)
        self.instances.update(load_instances(plan, self._work, self._logs(), self.handoff))
        set_up(plan, self.instances)
        self.ios = [instance_io(plan, n, self.instances[n], layout, wiring, self.instances,
                                self._fmi_acc if self.timing else None) for n in plan.order]
        exchange_initial(self.ios, self.instances, wiring, layout, self.clock.start, self.check_inputs)
        self.algorithm.feeds = wiring.graph()   # who feeds whom: the plan's graph (what check prints)
        self.algorithm.initialize(self.ios, self.clock.start, self.check_inputs)
        for io in self.ios:
            self.instances[io.name].exit_initialization()
        read_outputs(self.ios, self.instances, self.clock.start)
        self._recorder.open(recorded_getters(plan, self.instances, layout))
        self._recorder.record_at(self.clock.start)
        if plan.scenario.event_rows:   # (resolve allows it for one in-process model-exchange instance only)
            (io,) = self.ios
            inst = self.instances[io.name]
            assert isinstance(inst, ModelExchange), inst
            inst.on_event = self._event_row(io)

    def _event_row(self, io: InstanceIO) -> Callable[[float], None]:
        """The recording's row at an event of the lone model-exchange instance (``[record] event_rows``):
        its outputs read at the event's time t [s] into the row and recorded, the row then as it was (the
        step's own row is read after the step)."""
        layout, inst, recorder = self._layout, self.instances[io.name], self._recorder

        def row_at(t: float) -> None:
            saved = bytes(layout.buf)
            try:
                check(inst, "get outputs", io.get_outputs(), t)
                recorder.record_at(t)
            finally:
                ctypes.memmove(layout.buf, saved, len(saved))
        return row_at

    def _logs(self) -> Path:
        """The folder of the instances' logs: the results folder's, else one in the work folder (removed)."""
        if self.folder is not None:
            return self.folder.logs
        logs = self._work / "logs"
        logs.mkdir(exist_ok=True)
        return logs

    def _start(self) -> None:
        """The algorithm set up (told the recording's take); the manipulators and the observers started."""
        self.algorithm.setup(self.ios, self.clock, self._layout, self._recorder.take, self.check_inputs)
        self._ready = True
        for m in self.manipulators:
            m.started(self._manipulated)
        for o in self.observers:
            o.started(self._observed)
        if self.pacer is not None:
            self._pacing = Pacing(self.pacer)   # (its clock starts with the first step: see _advance)
        self._update_per_step()

    # ------------------------------------------------------------------ observers and manipulators
    def add_observer(self, obs: Observer) -> Observer:
        """Call ``obs`` from now on (after the observers added before it)."""
        return self._add(self.observers, obs, self._observed)

    def add_manipulator(self, m: Manipulator) -> Manipulator:
        """Let ``m`` act from now on (after the scenario's events and the manipulators added before it)."""
        return self._add(self.manipulators, m, self._manipulated)

    def _add(self, parts: list[Any], part: Any, view: ObservedRun) -> Any:
        if self.result is not None:
            raise CosimError(self._ended_message())
        parts.append(part)
        if self._ready:
            part.started(view)
        self._update_per_step()
        return part

    def _update_per_step(self) -> None:
        """Whether the segments must be one step long (worked out when the parts change, not per segment)."""
        self._per_step = (any(p.per_step for p in self.observers + self.manipulators)
                          or self._pacing is not None)

    def on_step(self, fn: Callable[[], Any]) -> Observer:
        """Call ``fn()`` after every step from now on."""
        return self.add_observer(StepCallback(fn))

    # ------------------------------------------------------------------ stepping
    def step(self, n: int = 1) -> RunStatus:
        """Do ``n`` communication steps (fewer at the stop time or when the run ends); the status."""
        return self._advance(self.k_done + int(n))

    def step_to(self, t: float) -> RunStatus:
        """Step until the communication point at or after ``t`` [s] (at most the stop time)."""
        return self._advance(int(math.ceil((float(t) - self.clock.start) / self.clock.step - 1e-9)))

    def simulate_until(self, t: float | None = None) -> RunStatus:
        """Step to ``t`` [s] as :meth:`step_to` does, or to the stop time (None)."""
        return self._advance(self.clock.n_steps) if t is None else self.step_to(t)

    def _advance(self, k_target: int) -> RunStatus:
        """Segments up to step ``k_target``.  The run ends (the result set, the FMUs freed) at its stop
        time, when an FMU or an event ends it, on a failure (raised: CosimError, a callback's error) or a
        Ctrl-C (raised: KeyboardInterrupt)."""
        if self.result is not None:
            raise CosimError(self._ended_message())
        if not self._ready:
            raise CosimError("the execution is not initialised: call initialize() first")
        interrupt = Interrupt()
        wall0 = _time.perf_counter()
        if self._pacing is not None and not self._pacing.running:
            self._pacing.started(self._observed)
        self._in_step = True
        try:
            self._segments(min(k_target, self.clock.n_steps), interrupt)
        except BaseException as exc:
            self.wall_s += _time.perf_counter() - wall0
            self._end_by(exc)         # (inside the step: a KeyboardInterrupt counts the steps recorded)
            if not isinstance(exc, (FmuEnded, EventStop)):
                raise
        else:
            self.wall_s += _time.perf_counter() - wall0
            self._in_step = False
            if self.k_done >= self.clock.n_steps or self._stop_requested:
                self._finish()
        finally:
            self._in_step = False
            interrupt.restore()
        return self.status

    def _segments(self, k_target: int, interrupt: Interrupt) -> None:
        k, n_steps = self.k_done, self.clock.n_steps
        while k < k_target and not self._stop_requested:
            acted = [m.act(self._manipulated, k) for m in self.manipulators]
            if self._script.act(self._manipulated, k) or any(acted):   # (the script's changes last: a manipulator may set)
                self._copies_changed()
            k_end = self._segment_end(k, k_target)
            self._errors = {n: i.n_errors for n, i in self.instances.items()}   # (see _failed)
            fail = self.algorithm.advance(k, k_end)
            if k_end < n_steps:  # a Ctrl-C after the last step interrupts nothing
                interrupt.check()
            if fail is not None:
                self._failed(fail)
            self.k_done = k = k_end
            self._stepped(k)

    def _copies_changed(self) -> None:
        """Every instance's copies taken again from the wiring, and the algorithm told."""
        for io in self.ios:
            io.copies = self._wiring.copies(io.name)
        self.algorithm.feeds = self._wiring.graph()
        self.algorithm.inputs_changed()

    def _segment_end(self, k: int, k_target: int) -> int:
        """The nearest of ``k_target``, the observers' boundaries and the manipulators' next actions (one
        step while any of them must see every step)."""
        if self._per_step:
            return k + 1
        k_end = k_target
        for o in self.observers:
            b = o.boundary(k)
            if b is not None:
                k_end = min(k_end, max(b, k + 1))
        for m in self.manipulators:
            a = m.next_action(k)
            if a is not None:
                k_end = min(k_end, max(a, k + 1))
        return k_end

    def _stepped(self, k: int) -> None:
        """After a segment: the manipulators that watch every step, the observers in the order added (the
        pacing last, skipped when the script has just stopped the run)."""
        for m in self.manipulators:
            if m.per_step:
                m.stepped(self._manipulated, k)
        for o in self.observers:
            o.stepped(self._observed, k)
        if self._pacing is not None and not self._stop_requested:
            self._pacing.stepped(self._observed, k)

    def _failed(self, f: Failure) -> None:
        """A segment stopped at step ``f.step``: an FMU that ended the simulation, or an error."""
        name, tf = f.instance, self.clock.time(f.step) if f.time is None else f.time
        # a get after the step to t_kf failed: that step's row is not recorded, the steps done are kf - 1
        self.k_done = f.step - 1 if f.call.after_step else f.step
        inst = self.instances[name]
        if f.call is Call.NON_FINITE_INPUT:
            io = self.ios[self.plan.order.index(name)]
            raise self._wiring.bad_input(name, io.in_vr, io.copies, tf)
        if f.call is Call.TERMINATED:  # the step's row is recorded already (unless it ended between points)
            raise FmuEnded(name, tf, recorded=f.time is None)
        if f.call is Call.COUPLING:
            raise RunError(str(f.value), name, tf)
        if f.call is Call.DO_STEP and int(f.value) == FmiStatus.DISCARD and inst.n_errors == self._errors.get(name, 0):
            # fmi2Terminated after a Discard with nothing logged at Discard, Error or Fatal: the FMU ended the
            # simulation (pythonfmu reports every failed step as terminated; its message tells them apart)
            t_end = inst.terminated_at()
            if t_end is not None:
                raise FmuEnded(name, t_end if math.isfinite(t_end) else tf)
        raise inst.fail_status(inst.call_name(f.call), int(f.value), tf)

    # ------------------------------------------------------------------ values between steps
    def get(self, ref: str) -> Any:
        """The current value of ``"instance.variable"`` (any variable).  A Float64 output the loop reads
        at every step gives its value at the last communication point (as recorded, and as conditions see
        it); any other variable is asked of the FMU, so an output with direct feedthrough already reflects
        an input :meth:`set` since that point."""
        if self.result is not None or not self._ready:
            self._alive()
        return self.access.get(ref)

    def last_row(self) -> list[float]:
        """The recorded columns (:attr:`columns`: the time [s] first) at the current communication point,
        read from the row the loop fills, with no FMU call: the Float64 outputs at t_k, the recorded outputs
        of other types as last recorded (they are read at the recorded steps).  What a view of the run as it
        goes shows (the live view)."""
        lay = self._layout
        n = lay.n_double
        return [self.time] + [lay.row[s] if s < n else float(lay.irow[s - n]) for s in self._slots]

    def reader(self, inst: str, var: Variable) -> Callable[[], Any]:
        """A function returning a variable's current value (see :meth:`.access.VariableAccess.reader`)."""
        self._alive()
        return self.access.reader(inst, var)

    def set(self, ref: str, value: Any) -> None:
        """Change ``"instance.variable"`` from the next step on: a tunable parameter; a Real input (its
        connection overridden until :meth:`release`); an output feeding connections (what they carry); an
        input no connection drives.  The value is checked against the variable's type and range."""
        self._alive()
        self.access.set(ref, value)

    def give(self, ref: str, value: Any, source: str = "live") -> EventPlan:
        """Give ``"instance.variable"`` the value ``value`` before the step from the current communication
        point, exactly as a timed event of the scenario at that time would (a tunable parameter set, an input
        overridden; checked as such an event is, against the variable's type and min/max: ScenarioError
        otherwise, see :func:`cosim.plan.resolution.given_event`), with an entry in the event table whose
        source and kind are ``source``.  Returns the event (its time [s] and checked value: what a scenario
        that replays the run names in its ``[[events]]``)."""
        self._alive()
        if self.k_done >= self.clock.n_steps:
            raise CosimError(f"the run is at its stop time (t = {self.time:.6g} s): a value given now would never act")
        ev = given_event(self.plan, ref, value, self.k_done)
        given = self._given.get(source)
        if given is None:
            given = self._given[source] = TimedEvents(self._actuator, [], source)
            self.add_manipulator(given)
        given.events.append(ev)
        return ev

    def pace(self, factor: float | None) -> None:
        """Pace the steps from now on at ``factor`` x real time (None: as fast as they go); the wall clock
        of the current communication point is the moment the next step starts (a run paused and resumed is
        not late).  The overruns of every pace so far add up in the result's ``real_time``."""
        self._alive()
        old = self.pacer
        if factor is None:
            self._pacing = None
        else:
            self.pacer = Pacer(factor) if old is None else dataclasses.replace(old, factor=factor, _wall0=None)
            self._pacing = Pacing(self.pacer)   # (its clock starts with the next step: see _advance)
        self._update_per_step()

    def release(self, ref: str) -> None:
        """End an override :meth:`set` put on a connected input or an output."""
        self._alive()
        self.access.release(ref)

    def bias(self, ref: str, value: float) -> None:
        """Add ``value`` to what reaches a connected Real input (in its unit), or to an output feeding
        connections, from the next step on, on top of any bias before; :meth:`release` ends it."""
        self._alive()
        self.access.bias(ref, value)

    # ------------------------------------------------------------------ going back to a communication point
    def save_point(self) -> "SavedPoint":
        """What the steps from here change, to come back to this communication point with
        :meth:`restore_point` and step again exactly as from here: every instance's state (fmi2GetFMUstate
        and its kin), the outputs in the row, the steps done, the script's overrides and biases.  Refused
        (CosimError naming why) where the steps keep more than that: an instance that cannot save its state,
        an algorithm other than one pass per step at one rate (the others carry iterates or step sizes from
        step to step), condition events, requirements or parts added to the execution (their memory is not
        saved), a results folder (the recording is not rolled back).  :meth:`free_point` lets it go."""
        self._alive()
        if self.folder is not None:
            raise CosimError("a point of a run cannot be saved while it records to a results folder "
                             "(the recording is not rolled back): run it without one")
        alg = self.algorithm
        if not alg.name or not algorithms.row(alg.name).one_pass or isinstance(alg, MultiRate):
            raise CosimError(f"the algorithm {alg.name or type(alg).__name__!r} keeps more than the outputs from "
                             f"step to step: a point is saved under one pass per step at one rate "
                             f"({', '.join(r.name for r in algorithms.ROWS if r.one_pass)})")
        if self.plan.conditions or self._requirements is not None \
                or len(self.manipulators) + len(self.observers) > self._builtin_parts:
            raise CosimError("a point cannot be saved in a run with condition events, requirements or parts "
                             "added to its execution: their memory is not saved")
        for name, inst in self.instances.items():
            if not inst.can_get_and_set_state:
                raise CosimError(f"{name}: its FMU cannot save and restore its state "
                                 "(canGetAndSetFMUstate is not declared): the run cannot go back to a point")
        for inst in self.instances.values():
            inst.allow_rollback()
        self.algorithm.inputs_changed()   # (its loop made again: the steps' noSetFMUStatePriorToCurrentPoint false)
        point = SavedPoint(self.k_done, bytes(self._layout.buf), {}, dict(self._wiring.overrides),
                           len(self._actuator.log))
        self._points.append(point)
        try:
            for name, inst in self.instances.items():
                point.states[name] = inst.get_state()
        except BaseException:
            self._free_saved(point)
            raise
        return point

    def restore_point(self, point: "SavedPoint") -> None:
        """Back to a point :meth:`save_point` saved (it stays saved: restore it again, then free it)."""
        self._alive()
        if not any(p is point for p in self._points):
            raise CosimError("this point was freed (free_point): save another")
        for name, st in point.states.items():
            self.instances[name].set_state(st)
        ctypes.memmove(self._layout.buf, point.row, len(point.row))
        self._wiring.overrides.clear()
        self._wiring.overrides.update(point.overrides)
        del self._actuator.log[point.n_log:]
        self.k_done = point.k
        self._copies_changed()

    def free_point(self, point: "SavedPoint") -> None:
        """Free the instances' saved states of a point.  The end of the run frees every point still saved
        before it frees the instances (their states belong to them: fmi2FreeFMUstate after fmi2FreeInstance
        calls into a library FMPy has unloaded); a point freed then, or before, is freed already."""
        self._free_saved(point)

    def _free_saved(self, point: "SavedPoint") -> None:
        """Every state of ``point`` freed (the first failure raised after); the point no longer saved."""
        self._points = [p for p in self._points if p is not point]
        states = dict(point.states)
        point.states.clear()
        failed: list[CosimError] = []
        for name, st in states.items():
            if not self.instances[name].fatal:   # (the Fatal rule: no call at all)
                try:
                    self.instances[name].free_state(st)
                except CosimError as exc:
                    failed.append(exc)
        if failed:
            raise failed[0]

    def verdicts(self) -> list[dict[str, Any]]:
        """The requirements' verdicts so far, as their online monitors have them at the current communication
        point (name, formula, verdict, robustness in the unit of the comparison, at [s], first_violation
        [s], decided_at [s], window [s], on_violation, description, unit); after the end, the run's (as
        summary.json has them).  [] for a run without requirements."""
        if self.result is not None:
            return list(self.result.requirements or [])
        monitors = self._requirements
        return monitors.so_far() if monitors is not None else []

    @property
    def events(self) -> list[dict[str, Any]]:
        """The event log so far: time, event, action, ..."""
        return list(self._actuator.log)

    def _alive(self) -> None:
        if self.result is not None:
            raise CosimError(self._ended_message())
        if not self._ready:
            raise CosimError("the execution is not initialised: call initialize() first")

    def _ended_message(self) -> str:
        r = self.result
        assert r is not None
        return f"the run has ended ({r.status}: {r.message or 'at the stop time'})"

    # ------------------------------------------------------------------ the end
    def stop(self, message: str | None = None, status: RunStatus = RunStatus.STOPPED) -> None:
        """End the run cleanly at the current time (from an observer or between steps): status "stopped"
        (or ``status``: "violated" for a requirement that stops the run)."""
        if self.result is not None:
            return
        self._set_status(status, message or f"stopped at t = {self.time:.6g} s")
        self._stop_requested = True
        if not self._in_step:
            self._finish()

    def close(self) -> RunResult:
        """End the run now if it has not ended (status "stopped" before the stop time) and return the result."""
        if self.result is None:
            if self.k_done < self.clock.n_steps and self.status == RunStatus.OK:
                self._set_status(RunStatus.STOPPED, f"closed at t = {self.time:.6g} s")
            self._finish()
        assert self.result is not None
        return self.result

    def _set_status(self, status: RunStatus, message: str) -> None:
        self.status, self.message = status, message

    def _end_by(self, exc: BaseException) -> None:
        """The run ends on ``exc``: its status and message, the steps done, then the results."""
        if self.result is not None:
            return
        if isinstance(exc, EventStop):
            self.k_done = exc.k
            self._set_status(RunStatus.STOPPED, f"stopped by events[{exc.index}] at t = {exc.t:.6g} s")
        elif isinstance(exc, FmuEnded):
            self._fmu_ended(exc)
        elif isinstance(exc, KeyboardInterrupt):
            last = self._recorder.last_time() if self._in_step else None
            if last is not None:   # the steps completed inside the interrupted segment
                self.k_done = max(self.k_done, self.clock.step_of(last))
            self._set_status(RunStatus.INTERRUPTED, f"interrupted by the user at t = {self.time:.6g} s")
        elif isinstance(exc, CosimError):
            if isinstance(exc, InstanceLost) and exc.time is not None:   # a child died inside a segment
                self.k_done = self.clock.step_of(exc.time)
            elif isinstance(exc, RunError) and exc.time is not None:     # e.g. a non-finite recorded value
                self.k_done = min(self.k_done, self.clock.step_of(exc.time))
            self._set_status(RunStatus.FAILED, str(exc))
        elif self._in_step:
            self._set_status(RunStatus.FAILED, f"a callback raised {type(exc).__name__}: {exc} at t = {self.time:.6g} s")
        else:
            self._set_status(RunStatus.FAILED, str(exc))
        self._finish()

    def _fmu_ended(self, s: FmuEnded) -> None:
        """An FMU ended the simulation at ``s.t``: the row at that time, unless it is the last row recorded
        (the FMU ended the simulation at a communication point without advancing)."""
        self.k_done = self.clock.steps_before(s.t)
        try:
            if not s.recorded and (s.t - self._layout.row[0]) / self.clock.step > 1e-9:
                read_outputs(self.ios, self.instances, s.t)
                self._recorder.record_at(s.t)
            self._set_status(RunStatus.TERMINATED, f"terminated by FMU {s.name} at t = {s.t:.6g} s")
            self._instance_events.append(ended_entry(s.name, s.t))
        except RunError as exc:
            self._set_status(RunStatus.FAILED, str(exc))

    def _finish(self) -> None:
        """Once: the observers finished (the last rows flushed), every instance terminated and freed (the
        Fatal rule), the recording closed, summary.json and signals.csv written, the folder released."""
        if self.result is not None:
            return
        try:
            for o in self.observers:
                try:
                    o.finished(self._observed)
                except RunError as exc:
                    if exc.time is not None:
                        self.k_done = min(self.k_done, self.clock.step_of(exc.time))
                    if self.status != RunStatus.FAILED:
                        self._set_status(RunStatus.FAILED, str(exc))
            self._instance_events = [e for n, inst in self.instances.items()
                                     for e in instance_entries(n, inst.handled_events())] + self._instance_events
            self.algorithm.finish()   # (its threads end before the instances they step)
            self._free_points()
            for inst in self.instances.values():
                inst.shutdown()
            self._recorder.close()
            shutil.rmtree(self._work, ignore_errors=True)
            self.result = self._result()
        finally:
            if self.folder is not None:
                self.folder.release()

    def _free_points(self) -> None:
        """The saved points not freed yet, freed while their instances live (a state that cannot be freed
        goes with its instance, freed next)."""
        while self._points:
            try:
                self._free_saved(self._points[-1])
            except CosimError:
                pass

    def _result(self) -> RunResult:
        final = self._recorder.final()
        t_end = self.time
        if self.status == RunStatus.TERMINATED:
            t_end = final.get("time", t_end)
        events, left_out = table(self.events, self._instance_events)
        res = RunResult(self.status, self.message, self.k_done, t_end, self.wall_s, self.setup_s,
                        self.folder.path if self.folder is not None else None, self.columns, final,
                        self._fmi_acc[0] if self.timing else None, events,
                        self.pacer.summary() if self.pacer is not None else None)
        res.stepping, res.events_left_out = algorithms.summary(self.algorithm), left_out
        res.handoff = self.handoff.summary() if self.handoff is not None else None
        monitors = self._requirements
        if monitors is not None and monitors.monitors:   # (none: the run ended before it started)
            res.requirements = monitors.finish(self.status)
            if self.folder is not None:
                write_robustness(self.folder.path / "requirements.npy", monitors.signals(), monitors.monitors[0].times)
        logs = {n: (i.log_lines, i.received) for n, i in self.instances.items()}
        res.summary = summary(self.plan, res, self._recorder.n_rows, logs)
        if self.folder is not None:
            write_results(self.folder, self.plan, res)
        res.scenario = scenario_record(self.plan)
        if self.keep_signals:
            res.signals = self._recorder.signals()
        return res


def run(plan: Plan, out_dir: str | Path | None, progress: bool | None = None, timing: bool = False,
        check_inputs: bool = True, real_time: float | None = None, algorithm: Algorithm | None = None) -> RunResult:
    """Run the plan and write its results folder ``out_dir``: signals.npy (written as the run goes),
    signals.csv, scenario.json (the scenario as resolved), logs/<instance>.log and summary.json.
    ``out_dir=None`` keeps the run in memory (no folder: the result has the final values, the summary and
    the scenario as resolved).  ``timing=True`` also measures the time spent inside the stepping FMI calls.
    ``real_time=FACTOR`` paces the steps to the wall clock at FACTOR x real time (cosim.runtime.pacing)."""
    ex = Execution(plan, out_dir, progress=progress, timing=timing, check_inputs=check_inputs,
                   real_time=real_time, algorithm=algorithm)
    try:
        ex.initialize()
        ex.simulate_until()
    except (CosimError, KeyboardInterrupt):
        pass   # the run has ended: its status and message say how
    return ex.close()


