"""A Model Exchange FMU (FMI 2.0 or 3.0) as an instance of a system: the FMU's equations advanced between
communication points by one of the master's integrators (cosim.instances.integrators), so that the algorithms and
the loop see it like a co-simulation instance (cosim.instances.contract's contract).

Life cycle (FMI 2.0, 3.2.3; FMI 3.0, 3.3): instantiate, set up, set start values, enter initialisation
mode (the execution exchanges the inputs), exit it, the event iteration (update discrete states until no
new ones are needed), continuous-time mode; the integrator starts there.

A communication step from t to t + h (the fast path's ``do_step``):

* Inputs are held constant over the step at the values set before it.  Continuous Real inputs are set in
  continuous-time mode; a change of them is a discontinuity of the right-hand side, so the integrator
  restarts at t (a step with unchanged inputs continues the integration).  If an event indicator changed
  domain by the new inputs, that is a state event at t, handled before integrating.  Anything else that is
  set between steps (discrete inputs and connections, tunable parameters, the scenario's events, the
  script) enters event mode first, as the standard requires, and the event iteration runs at t.
* Time events (the FMU's next event time) are integrated to exactly and handled there; state events
  (event indicators) where the integrator locates them; step events where ``completedIntegratorStep``
  asks for event mode (called after each integrator step, when the FMU does not say it needs none).
  An event inside the step is handled there, and the integration goes on to t + h.
* The FMU ending the simulation (``terminateSimulation``) ends the step there: the fast path says so
  (``FastPath.terminated`` and ``last_time``) and the run stops after recording it.

State for rollback (where the model exchange interface declares it can): the FMU's state with the
instance's own (mode, next time event, inputs, indicators); the integrator restarts at the saved time both
when the state is saved and when it is restored, so a restored step repeats the first exactly.
"""
from __future__ import annotations

import ctypes
import math
from typing import TYPE_CHECKING, Any, Callable

from ..messages.errors import RunError
from ..model.description import Variable, declares_state
from ..model.types import FLOAT64, FLOAT64_TYPES
from .contract import FastPath
from .failure import Call
from .in_process import Instance, Instance3, raw
from .integrators import ME_ALONE, Equations, IntegrationError, Integrator, SolverSpec, crossed, make_integrator

#: Events at one time after which the event iteration is taken not to end.
MAX_EVENTS_AT_ONE_TIME = 1000
#: Relative width [s per s of time] under which what is left of a step is not integrated (its end is
#: taken as reached: CVODE refuses to start over an interval this short).
TOO_SHORT = 1e-13


class ModelExchange:
    """The Model Exchange part shared by FMI 2.0 and 3.0 (mixed into :class:`Instance`/:class:`Instance3`)."""

    fmi_version: int
    fmu: Any
    md: Any
    name: str
    c: Any
    fatal: bool

    if TYPE_CHECKING:   # (given by the co-simulation instance this is mixed into)
        def call(self, what: str, fn: Any, *args: Any, t: float | None = None) -> Any: ...

    def _sizes(self) -> tuple[int, int]:
        """The numbers of continuous states and of event indicators."""
        raise NotImplementedError

    def _update_discrete_states(self) -> tuple[Any, ...]:
        """One update of the discrete states in event mode: (needed, terminate, nominals changed, values
        changed, next event time defined, next event time)."""
        raise NotImplementedError

    def __init__(self, name: str, md: Any, unzipdir: str, log_path: Any = None, logging: str = "warning",
                 solver: SolverSpec = SolverSpec()) -> None:
        self.solver = solver
        self.mode = "instantiated"            # "init", "event", "continuous"
        self.integrator: Integrator | None = None
        self.t = self.start = 0.0             # the FMU's time, the run's start [s]
        self.span = math.inf                  # stop - start [s]
        self.next_event: float | None = None  # the FMU's next time event [s]
        self.z: list[float] = []              # the event indicators at the end of the last step
        self.inputs: list[float] | None = None
        self.dirty = False                    # the inputs changed since the integrator last started
        self.events: list[tuple[float, str]] = []   # (time [s], "time" | "state" | "step" | "input" | "set")
        #: called at each event of the FMU (time, state, step, input; not the event mode entered to set
        #: values) with its time [s], once before the event mode and once after the event iteration:
        #: the recording's rows at the event (``[record] event_rows``)
        self.on_event: Callable[[float], None] | None = None
        self.n_saved = 0
        self.failed_call = ""
        self._terminated = ctypes.c_bool(False)
        self._last_time = ctypes.c_double(math.nan)
        super().__init__(name, md, unzipdir, log_path, logging)   # type: ignore[call-arg]

    # ------------------------------------------------------------------ life cycle
    def setup_experiment(self, start: float, stop: float | None, tolerance: float | None) -> None:
        self.t = self.start = start
        self.span = (stop - start) if stop is not None else math.inf
        super().setup_experiment(start, stop, tolerance)   # type: ignore[misc]

    def enter_initialization(self) -> None:
        super().enter_initialization()   # type: ignore[misc]
        self.mode = "init"

    def exit_initialization(self) -> None:
        """Exit initialisation mode, the event iteration at the start time, continuous-time mode, the
        integrator started."""
        super().exit_initialization()   # type: ignore[misc]
        self.mode = "event"
        self.nx, self.nz = self._sizes()
        self.eq = self._equations()
        if self._event_iteration(self.t, "initial"):
            raise RunError(f"{self.name}: the FMU ended the simulation in its initial event iteration at "
                           f"t = {self.t:.6g} s", self.name, self.t)
        try:
            self.integrator = make_integrator(self.solver, self.eq, self.t, self.span)
            self.integrator.reset(self.t)
            self.z = self._indicators()
            self.dirty = False
        except IntegrationError as exc:
            raise self._integration_error(exc, self.t) from None

    def handled_events(self) -> list[tuple[float, str]]:
        """Time, state, step and input events, in order (not the event mode entered to set values)."""
        return [e for e in self.events if e[1] != "set"]

    def shutdown(self) -> None:
        if self.integrator is not None:
            self.integrator.free()
            self.integrator = None
        super().shutdown()   # type: ignore[misc]

    # ------------------------------------------------------------------ setting values between steps
    def enter_event_mode(self) -> None:
        """Event mode now, if the FMU is in continuous-time mode (values other than continuous inputs are
        set there); the next step begins with the event iteration."""
        if self.mode == "continuous":
            self.call(f"fmi{self.fmi_version}EnterEventMode", self.fmu.enterEventMode, t=self.t)
            self.mode = "event"
            self.events.append((self.t, "set"))

    def set_values(self, pairs: list[tuple[Variable, Any]]) -> None:
        if pairs and self.mode == "continuous":
            self.enter_event_mode()
        super().set_values(pairs)   # type: ignore[misc]

    def accessor(self, fmi_type: str, op: str) -> tuple[Callable[[Any, Any, Any, Any], int], Any]:
        """As the co-simulation instance's; a set that changes values enters event mode first."""
        call, ctype = super().accessor(fmi_type, op)   # type: ignore[misc]
        if op != "Set":
            return call, ctype
        last: dict[tuple[int, ...], list[Any]] = {}

        def set_in_event_mode(vrs: Any, n: Any, buf: Any, nv: Any) -> int:
            key = tuple(vrs[:_count(n)])
            values = buf[:_count(nv)]
            if last.get(key) == values and self.mode != "init":
                return 0              # unchanged: the FMU holds it (no event)
            try:
                self.enter_event_mode()
            except RunError:
                return 3
            s = call(vrs, n, buf, nv)
            if s <= 1:
                last[key] = values
            return s
        return set_in_event_mode, ctype

    # ------------------------------------------------------------------ the step's fast path
    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                  in_val: Any = None) -> FastPath:
        """The co-simulation instance's set and get; the step is :meth:`do_step` (the integration)."""
        base = super().fast_path(in_vrs, n_in, out_vrs, n_out, in_val)   # type: ignore[misc]
        raw_set = base.set_real
        discrete = self._discrete_inputs(in_vrs)

        def set_real(c: Any, vrs: Any, n: Any, vals: Any, *tail: Any) -> int:
            if discrete and self.mode == "continuous":
                try:
                    self.enter_event_mode()
                except RunError:
                    return 3
            s = raw_set(c, vrs, n, vals, *tail)
            if s <= 1:
                now = vals[:n_in]
                if now != self.inputs:
                    self.inputs, self.dirty = now, True
            return s

        def do_step(c: Any, t: Any, h: Any, *tail: Any) -> int:
            return self.advance(t.value, self.step_end(t.value, h.value))

        return FastPath(base.c, set_real, do_step, base.get_real, base.in_val, set_tail=base.set_tail,
                        get_tail=base.get_tail, terminated=self._terminated, last_time=self._last_time,
                        alone=ME_ALONE, abi=base.abi)

    def step_end(self, t: float, h: float) -> float:
        """The end of the step of ``h`` from ``t`` [s]: the master's grid point start + (k + 1) h where ``t``
        is start + k h (t + h in floating point may miss it by an ulp, and a time event on it with it),
        else t + h."""
        k = round((t - self.start) / h)
        if self.start + k * h == t:
            return self.start + (k + 1) * h
        return t + h

    def _discrete_inputs(self, in_vrs: list[int]) -> bool:
        """Whether any of these Float64 inputs is discrete (set in event mode only)."""
        wanted = set(in_vrs)
        return any(v.variability == "discrete" and v.causality == "input" and int(v.valueReference) in wanted
                   and v.type in FLOAT64_TYPES for v in self.md.modelVariables)

    def call_name(self, call: Call) -> str:
        if call is Call.DO_STEP:
            return f"the integration ({self.solver.name}{': ' + self.failed_call if self.failed_call else ''})"
        return super().call_name(call)   # type: ignore[misc]

    def advance(self, t: float, t_end: float) -> int:
        """The FMU from ``t`` to ``t_end`` [s] with its events; an FMI status (Error with the reason in the
        log when the integration or an event failed)."""
        try:
            self._advance(t, t_end)
        except IntegrationError as exc:
            self.failed_call = exc.call or str(exc)
            self._note(f"integration failed at t = {self.t:.9g} s: {exc}")
            return exc.status if exc.status > 1 else 3
        except RunError as exc:
            self.failed_call = str(exc).split(" returned")[0].split(": ")[-1]
            return 4 if self.fatal else 3
        return 0

    def _advance(self, t: float, t_end: float) -> None:
        integ = self.integrator
        assert integ is not None, "not initialised"
        self.t = t
        if self.mode == "event":
            self._event_at(t, "set")
        elif self.dirty:
            self._inputs_changed(t)
        at_once = 0                     # events at one time (an FMU whose events do not end is refused)
        while not self._terminated.value:
            eps = TOO_SHORT * max(1.0, abs(t_end))
            if self.t >= t_end - eps:
                break
            te = self.next_event
            timed = te is not None and te <= t_end + eps
            target = max(self.t, min(te, t_end)) if te is not None and timed else t_end
            t_before = self.t
            if target - self.t > eps:
                self.t, state = integ.advance(self.t, target)
            else:                       # (what is left is shorter than CVODE can start over)
                self.t, state = target, False
                self.eq.check(self.eq.set_time(target), 0)
            if state or self.step_event:
                self._event_at(self.t, "state" if state else "step")
            elif timed and self.t >= target:
                self._event_at(self.t, "time")
            else:
                continue
            at_once = at_once + 1 if self.t == t_before else 0
            if at_once > MAX_EVENTS_AT_ONE_TIME:
                raise RunError(f"{self.name}: more than {MAX_EVENTS_AT_ONE_TIME} events at t = {self.t:.9g} s",
                               self.name, self.t)
        if self.t < t_end and not self._terminated.value:   # (within TOO_SHORT of it: the step's end)
            self.t = t_end
            self.eq.check(self.eq.set_time(t_end), 0)
        self.z = self._indicators()

    def _inputs_changed(self, t: float) -> None:
        """New inputs at t: the integrator restarts there; an indicator they moved across zero is an
        event at t."""
        assert self.integrator is not None
        self.dirty = False
        z = self._indicators()
        if self.nz and crossed(self.z, z):
            self._event_at(t, "input")
        else:
            self.integrator.reset(t)
            self.z = z

    def _event_at(self, t: float, kind: str) -> None:
        """Event mode (unless in it), the event iteration, continuous-time mode, the integrator restarted."""
        assert self.integrator is not None
        row = self.on_event if kind != "set" else None
        if self.mode != "event":
            if row is not None:
                row(t)                  # the values before the event
            self.call(f"fmi{self.fmi_version}EnterEventMode", self.fmu.enterEventMode, t=t)
            self.mode = "event"
        if kind != "set":
            self.events.append((t, kind))
        self.step_event = False
        if self._event_iteration(t, kind):
            return
        self.dirty = False
        self.integrator.reset(t)
        self.z = self._indicators()
        if row is not None:
            row(t)                      # the values after it

    def _event_iteration(self, t: float, kind: str) -> bool:
        """Update the discrete states until no new ones are needed, then continuous-time mode; True if the
        FMU ended the simulation (the fast path says so)."""
        update = self._update_discrete_states
        for _ in range(MAX_EVENTS_AT_ONE_TIME):
            needed, terminate, _nominals, _values, defined, t_next = self.call(
                f"fmi{self.fmi_version}{'NewDiscreteStates' if self.fmi_version == 2 else 'UpdateDiscreteStates'}",
                update, t=t)
            if terminate:
                self._terminated.value, self._last_time.value = True, t
                return True
            if not needed:
                break
        else:
            raise RunError(f"{self.name}: the event iteration at t = {t:.9g} s did not end after "
                           f"{MAX_EVENTS_AT_ONE_TIME} updates of the discrete states", self.name, t)
        self.next_event = float(t_next) if defined else None
        self.call(f"fmi{self.fmi_version}EnterContinuousTimeMode", self.fmu.enterContinuousTimeMode, t=t)
        self.mode = "continuous"
        return False

    step_event = False

    def _completed(self, t: float) -> bool:
        """completedIntegratorStep after an integrator step at ``t``; True if the integration must stop."""
        if not self.needs_completed:
            return False
        enter, terminate = self.call(f"fmi{self.fmi_version}CompletedIntegratorStep",
                                     self.fmu.completedIntegratorStep, self.n_saved == 0, t=t)
        if terminate:
            self._terminated.value, self._last_time.value = True, t
            return True
        self.step_event = bool(enter)
        return self.step_event

    def _indicators(self) -> list[float]:
        if not self.nz:
            return []
        self.eq.check(self.eq.get_z(self._zbuf), 5)
        return self._zbuf[:self.nz]

    def _integration_error(self, exc: IntegrationError, t: float) -> RunError:
        return RunError(f"{self.name}: {exc} at t = {t:.6g} s; last log: {self.last_log()}", self.name, t)  # type: ignore[attr-defined]

    def _note(self, line: str) -> None:
        self._logger(3, b"integrator", line.encode("utf-8"))   # type: ignore[attr-defined]

    # ------------------------------------------------------------------ the equations as raw calls
    def _equations(self) -> Equations:
        v, dll, c = self.fmi_version, self.fmu.dll, ctypes.c_void_p(self.c)
        names = (f"fmi{v}SetTime", f"fmi{v}SetContinuousStates", f"fmi{v}GetContinuousStates",
                 f"fmi{v}GetDerivatives" if v == 2 else "fmi3GetContinuousStateDerivatives",
                 f"fmi{v}GetNominalsOfContinuousStates", f"fmi{v}GetEventIndicators")
        f = [raw(dll, n) for n in names]
        nx, nz = ctypes.c_size_t(self.nx), ctypes.c_size_t(self.nz)
        self._zbuf = (ctypes.c_double * max(1, self.nz))()
        cd = ctypes.c_double
        return Equations(self.nx, self.nz, lambda t: f[0](c, cd(t)), lambda p: f[1](c, p, nx),
                         lambda p: f[2](c, p, nx), lambda p: f[3](c, p, nx), lambda p: f[4](c, p, nx),
                         lambda p: f[5](c, p, nz), self._completed, names)

    @property
    def needs_completed(self) -> bool:
        me = self.md.modelExchange
        if self.fmi_version == 2:
            return not bool(getattr(me, "completedIntegratorStepNotNeeded", False))
        return bool(getattr(me, "needsCompletedIntegratorStep", False))

    # ------------------------------------------------------------------ the point, for a linearisation
    def continuous_states(self) -> list[float]:
        """The continuous states now (fmi2GetContinuousStates), in the order of the model structure's
        derivatives."""
        buf = (ctypes.c_double * max(1, self.nx))()
        self._check_eq(self.eq.get_x(buf), 2)
        return buf[:self.nx]

    def set_continuous_states(self, x: list[float]) -> None:
        """Set the continuous states (fmi2SetContinuousStates); the integrator restarts at the next step."""
        self._check_eq(self.eq.set_x((ctypes.c_double * max(1, self.nx))(*x)), 1)
        self.dirty = True

    def state_derivatives(self) -> list[float]:
        """The derivatives of the states now (fmi2GetDerivatives) [state unit/s]."""
        buf = (ctypes.c_double * max(1, self.nx))()
        self._check_eq(self.eq.get_dx(buf), 3)
        return buf[:self.nx]

    def state_nominals(self) -> list[float]:
        """The nominal values of the states (fmi2GetNominalsOfContinuousStates)."""
        buf = (ctypes.c_double * max(1, self.nx))()
        self._check_eq(self.eq.get_nominals(buf), 4)
        return buf[:self.nx]

    def get_reals(self, vrs: list[int]) -> list[float]:
        """The Float64 values of these value references now (scalars)."""
        call, ctype = super().accessor(FLOAT64[self.fmi_version], "Get")   # type: ignore[misc]
        n = len(vrs)
        buf = (ctype * max(1, n))()
        self._check_call(call((ctypes.c_uint * max(1, n))(*vrs), ctypes.c_size_t(n), buf, ctypes.c_size_t(n)),
                         "Get")
        return buf[:n]

    def set_continuous_inputs(self, vrs: list[int], values: list[float]) -> None:
        """Set continuous Float64 inputs in continuous-time mode, where the standard allows it without an
        event (the integrator restarts at the next step)."""
        call, ctype = super().accessor(FLOAT64[self.fmi_version], "Set")   # type: ignore[misc]
        n = len(vrs)
        self._check_call(call((ctypes.c_uint * max(1, n))(*vrs), ctypes.c_size_t(n), (ctype * max(1, n))(*values),
                              ctypes.c_size_t(n)), "Set")
        self.dirty = True

    @property
    def provides_directional_derivative(self) -> bool:
        """The model exchange interface declares providesDirectionalDerivative."""
        return bool(getattr(self.md.modelExchange, "providesDirectionalDerivative", False))

    def directional_derivative(self, unknowns: list[int], knowns: list[int],
                               seed: list[float]) -> tuple[int, list[float]]:
        """fmi2GetDirectionalDerivative / fmi3GetDirectionalDerivative: (status, d unknowns = J seed)."""
        if not self.provides_directional_derivative:
            raise RunError(f"{self.name}: this FMU gives no directional derivatives", self.name)
        what = f"fmi{self.fmi_version}GetDirectionalDerivative"
        values = self.call(what, self.fmu.getDirectionalDerivative, list(unknowns), list(knowns), list(seed), t=self.t)
        return 0, list(values)

    def _check_eq(self, status: int, which: int) -> None:
        if status > 1:
            raise self.fail_status(self.eq.names[which], status, self.t)   # type: ignore[attr-defined]

    def _check_call(self, status: int, op: str) -> None:
        if status > 1:
            what = f"fmi{self.fmi_version}{op}{FLOAT64[self.fmi_version]}"
            raise self.fail_status(what, status, self.t)   # type: ignore[attr-defined]

    # ------------------------------------------------------------------ state (rollback)
    @property
    def can_get_and_set_state(self) -> bool:
        return declares_state(self.md.modelExchange)

    @property
    def can_interpolate_inputs(self) -> bool:
        """No: the integrator holds the inputs over the step (linear inputs are not implemented)."""
        return False

    def get_state(self) -> Any:
        """The FMU's state and the instance's; the integrator restarts here (see the module's docstring)."""
        if self.mode == "continuous" and self.integrator is not None:
            self.integrator.reset(self.t)
            self.dirty = False
        fmu_state = super().get_state()   # type: ignore[misc]
        self.n_saved += 1
        return (fmu_state, (self.t, self.mode, self.next_event, list(self.z),
                            None if self.inputs is None else list(self.inputs), self.dirty, len(self.events)))

    def set_state(self, state: Any) -> None:
        fmu_state, (t, mode, next_event, z, inputs, dirty, n_events) = state
        super().set_state(fmu_state)   # type: ignore[misc]
        self.t, self.mode, self.next_event, self.z, self.inputs, self.dirty = t, mode, next_event, list(z), inputs, dirty
        del self.events[n_events:]
        self._terminated.value = False
        if self.integrator is not None and mode == "continuous":
            try:
                self.integrator.reset(t)
            except IntegrationError as exc:
                raise self._integration_error(exc, t) from None

    def free_state(self, state: Any) -> None:
        super().free_state(state[0])   # type: ignore[misc]
        self.n_saved = max(0, self.n_saved - 1)


def _count(n: Any) -> int:
    return int(getattr(n, "value", n))


class ModelExchange2(ModelExchange, Instance):
    """An FMI 2.0 Model Exchange FMU as an instance of a system."""

    fmi_version = 2

    def _slave(self, md: Any, unzipdir: str) -> Any:
        from fmpy.fmi2 import FMU2Model

        self._register_callbacks()
        return FMU2Model(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.modelExchange.modelIdentifier,
                         instanceName=self.name)

    def _sizes(self) -> tuple[int, int]:
        return int(self.md.numberOfContinuousStates or 0), int(self.md.numberOfEventIndicators or 0)

    def _update_discrete_states(self) -> tuple[Any, ...]:
        return self.fmu.newDiscreteStates()


class ModelExchange3(ModelExchange, Instance3):
    """An FMI 3.0 Model Exchange FMU as an instance of a system."""

    fmi_version = 3

    def _slave(self, md: Any, unzipdir: str) -> Any:
        from fmpy.fmi3 import FMU3Model

        self._experiment = (0.0, None, None)
        return FMU3Model(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.modelExchange.modelIdentifier,
                         instanceName=self.name)

    def instantiate(self) -> None:
        self.call("fmi3InstantiateModelExchange", self.fmu.instantiate, False, True, self._log3)
        self.c = self.fmu.component
        self._debug_logging("fmi3SetDebugLogging")

    def _sizes(self) -> tuple[int, int]:
        return (int(self.call("fmi3GetNumberOfContinuousStates", self.fmu.getNumberOfContinuousStates)),
                int(self.call("fmi3GetNumberOfEventIndicators", self.fmu.getNumberOfEventIndicators)))

    def _update_discrete_states(self) -> tuple[Any, ...]:
        return self.fmu.updateDiscreteStates()
