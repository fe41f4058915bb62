"""The integrators that advance a Model Exchange FMU between communication points.

:class:`SolverSpec` is what a scenario (``[instances.X] solver, tolerance, max_step, event_tolerance``) and
the Python API say of one Model Exchange instance's integrator.
"""
from __future__ import annotations

import ctypes
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Callable, Sequence

#: The integrators a scenario may name.
SOLVERS = ("cvode", "euler", "rk4")
#: CVODE's relative tolerance when neither the instance, the experiment nor the FMU gives one (FMPy's).
DEFAULT_RTOL = 1e-5
#: The time tolerance [s] to which a fixed-step integrator locates a state event.
DEFAULT_EVENT_TOLERANCE = 1e-10


#: Why a Model Exchange instance in this process steps alone when instances step at once.
ME_ALONE = ("a Model Exchange instance: its integrator runs in Python, which holds the GIL (isolate = true "
            "steps it in a process of its own)")


@dataclass(frozen=True)
class SolverSpec:
    """One Model Exchange instance's integrator: ``name`` one of :data:`SOLVERS`; ``tolerance`` CVODE's
    relative tolerance (None: :data:`DEFAULT_RTOL`; the absolute one is it times each state's nominal);
    ``max_step`` [s] the largest internal step (None: CVODE takes (stop - start) / 50 as FMPy does, Euler and
    RK4 one step per communication step); ``event_tolerance`` [s] the width to which Euler and RK4 locate a
    state event (CVODE locates its roots to its own, tighter, tolerance)."""

    name: str = "cvode"
    tolerance: float | None = None
    max_step: float | None = None
    event_tolerance: float = DEFAULT_EVENT_TOLERANCE


# ---------------------------------------------------------------------------------------------------------
# The integrators.  Each advances one FMU's continuous states through :class:`Equations` (the raw calls of
# the FMU's continuous-time equations), between events: the instance (cosim.instances.model_exchange) handles the events.

class IntegrationError(Exception):
    """The integration failed: ``status`` is the FMI status of the FMU call that failed (0 when the
    integrator itself failed), ``call`` its name, or the integrator's message."""

    def __init__(self, message: str, status: int = 0, call: str = "") -> None:
        super().__init__(message)
        self.status, self.call = status, call


@dataclass
class Equations:
    """An FMU's continuous-time equations as raw calls, each returning an FMI status: ``set_time(t)``;
    ``set_x(ptr)``, ``get_x(ptr)``, ``get_dx(ptr)``, ``get_nominals(ptr)`` over the ``nx`` states and
    ``get_z(ptr)`` over the ``nz`` event indicators (``ptr`` a pointer to doubles); ``names`` the FMI names
    of the calls in that order, for messages; ``completed(t)`` after each integrator step: True when the
    integration must stop there (the FMU asked for event mode or the end of the simulation)."""

    nx: int
    nz: int
    set_time: Callable[[float], int]
    set_x: Callable[[Any], int]
    get_x: Callable[[Any], int]
    get_dx: Callable[[Any], int]
    get_nominals: Callable[[Any], int]
    get_z: Callable[[Any], int]
    completed: Callable[[float], bool]
    names: tuple[str, ...] = ("SetTime", "SetContinuousStates", "GetContinuousStates", "GetDerivatives",
                              "GetNominalsOfContinuousStates", "GetEventIndicators")

    def check(self, status: int, which: int) -> None:
        """An IntegrationError for a status above Warning of call number ``which`` (see ``names``)."""
        if status > 1:
            raise IntegrationError(f"{self.names[which]} returned status {status}", status, self.names[which])


def crossed(before: Sequence[float], after: Sequence[float]) -> bool:
    """Whether an event indicator changed domain (z > 0 against z <= 0: FMI 2.0, 3.1)."""
    return any((a > 0.0) != (b > 0.0) for a, b in zip(before, after))


#: What CVODE's root function gives for an event indicator that is exactly 0: the negative number nearest
#: to it, since 0 is in the domain z <= 0.  (CVODE looks for sign changes and takes a zero as a root or,
#: at its start, leaves that component out until it moves away: an indicator starting at 0 and rising
#: would be no root, one touching 0 from below would be one.)
ZERO_SIDE = -math.ulp(0.0)


class Integrator(ABC):
    """Advances the states of one FMU from ``t`` towards ``t_out``."""

    @abstractmethod
    def reset(self, t: float) -> None:
        """Start again from the FMU's states at ``t`` [s] (after an event, a change of inputs, a restored
        state): nothing of the integration before ``t`` is used after it."""

    @abstractmethod
    def advance(self, t: float, t_out: float) -> tuple[float, bool]:
        """Integrate from ``t`` to ``t_out`` [s], stopping early at a state event or where
        ``Equations.completed`` asked to stop; returns (the time reached, whether a state event stopped it).
        The FMU's time and states are those at the time reached."""

    def free(self) -> None:
        """Release what the integrator holds outside Python."""


def make_integrator(spec: SolverSpec, eq: Equations, t0: float, span: float) -> Integrator:
    """The integrator ``spec`` names, started at ``t0`` [s] from the FMU's states; ``span`` [s]: the run's
    length (CVODE's default largest step is span / 50)."""
    if spec.name == "cvode":
        max_step = spec.max_step if spec.max_step is not None else (span / 50.0 if math.isfinite(span) and span > 0
                                                                     else math.inf)
        return Cvode(eq, t0, spec.tolerance if spec.tolerance is not None else DEFAULT_RTOL, max_step)
    if spec.name in FIXED_STEP:
        return FixedStep(eq, FIXED_STEP[spec.name], spec.max_step, spec.event_tolerance)
    raise ValueError(f"unknown solver {spec.name!r}: one of {', '.join(SOLVERS)}")


# ------------------------------------------------------------------------------------------------- CVODE
class Cvode(Integrator):
    """CVODE (SUNDIALS, through FMPy's bindings) with the settings FMPy's own simulation uses: BDF, a dense
    linear solver, relative tolerance ``rtol``, absolute tolerance ``rtol`` times each state's nominal,
    largest step ``max_step`` [s], root finding on every event indicator (CVODE returns the root on the far
    side of the crossing, located to about 100 machine epsilons of t), each indicator seen in its FMI
    domain (a zero as :data:`ZERO_SIDE`, on the side of z <= 0).  Normal mode: CVODE may step past
    ``t_out`` internally and interpolates back; ``Equations.completed`` is called at each time returned.
    A failing FMU call in the right-hand side is returned to CVODE as unrecoverable (Error, Fatal) or
    recoverable (Discard: CVODE retries with a smaller step)."""

    MAX_NUM_STEPS = 100_000    # internal steps per call before CVODE gives up

    def __init__(self, eq: Equations, t0: float, rtol: float, max_step: float) -> None:
        from fmpy import sundials as sd   # (loads the SUNDIALS libraries FMPy ships)

        self.sd, self.eq, self.rtol = sd, eq, rtol
        self.discrete = eq.nx == 0          # no states: one dummy state (as FMPy)
        self.nx = max(1, eq.nx)
        self.failure: IntegrationError | None = None
        self.ctx = sd.SUNContext()
        self._ok(sd.SUNContext_Create(sd.SUN_COMM_NULL, ctypes.byref(self.ctx)), "SUNContext_Create")
        self.x = sd.N_VNew_Serial(self.nx, self.ctx)
        self.abstol = sd.N_VNew_Serial(self.nx, self.ctx)
        self.px, self.pabs = sd.NV_DATA_S(self.x), sd.NV_DATA_S(self.abstol)
        self._load_states()
        self.mem = sd.CVodeCreate(sd.CV_BDF, self.ctx)
        self.f_, self.g_ = sd.CVRhsFn(self._f), sd.CVRootFn(self._g)   # (kept: CVODE calls them)
        self._ok(sd.CVodeInit(self.mem, self.f_, t0, self.x), "CVodeInit")
        self._ok(sd.CVodeSVtolerances(self.mem, rtol, self.abstol), "CVodeSVtolerances")
        self._ok(sd.CVodeRootInit(self.mem, eq.nz, self.g_), "CVodeRootInit")
        self.A = sd.SUNDenseMatrix(self.nx, self.nx, self.ctx)
        self.LS = sd.SUNLinSol_Dense(self.x, self.A, self.ctx)
        self._ok(sd.CVodeSetLinearSolver(self.mem, self.LS, self.A), "CVodeSetLinearSolver")
        self._ok(sd.CVodeSetMaxStep(self.mem, max_step), "CVodeSetMaxStep")
        self._ok(sd.CVodeSetMaxNumSteps(self.mem, self.MAX_NUM_STEPS), "CVodeSetMaxNumSteps")
        self._ok(sd.CVodeSetNoInactiveRootWarn(self.mem), "CVodeSetNoInactiveRootWarn")
        self.roots = (ctypes.c_int * max(1, eq.nz))()
        self.tret = sd.realtype(0.0)

    @staticmethod
    def _ok(flag: int, what: str) -> None:
        if flag != 0:
            raise IntegrationError(f"CVODE: {what} returned {flag}")

    def _load_states(self) -> None:
        """x and the absolute tolerances from the FMU's states and nominals."""
        if self.discrete:
            self.px[0], self.pabs[0] = 1.0, self.rtol
            return
        self.eq.check(self.eq.get_x(self.px), 2)
        self.eq.check(self.eq.get_nominals(self.pabs), 4)
        for i in range(self.nx):
            self.pabs[i] = abs(self.pabs[i]) * self.rtol

    def _fail(self, exc: IntegrationError) -> int:
        self.failure = exc
        return 1 if exc.status == 2 else -1     # Discard: recoverable (a smaller step); else unrecoverable

    def _f(self, t: float, y: Any, ydot: Any, user_data: Any) -> int:
        eq, sd = self.eq, self.sd
        try:
            eq.check(eq.set_time(t), 0)
            if self.discrete:
                sd.NV_DATA_S(ydot)[0] = 0.0
            else:
                eq.check(eq.set_x(sd.NV_DATA_S(y)), 1)
                eq.check(eq.get_dx(sd.NV_DATA_S(ydot)), 3)
        except IntegrationError as exc:
            return self._fail(exc)
        return 0

    def _g(self, t: float, y: Any, gout: Any, user_data: Any) -> int:
        eq = self.eq
        try:
            eq.check(eq.set_time(t), 0)
            if not self.discrete:
                eq.check(eq.set_x(self.sd.NV_DATA_S(y)), 1)
            eq.check(eq.get_z(gout), 5)
        except IntegrationError as exc:
            return self._fail(exc)
        for i in range(eq.nz):     # (a zero is in the domain z <= 0: see ZERO_SIDE)
            if gout[i] == 0.0:
                gout[i] = ZERO_SIDE
        return 0

    def reset(self, t: float) -> None:
        self._load_states()
        self._ok(self.sd.CVodeReInit(self.mem, t, self.x), "CVodeReInit")

    def advance(self, t: float, t_out: float) -> tuple[float, bool]:
        sd, eq = self.sd, self.eq
        self.failure = None
        flag = sd.CVode(self.mem, t_out, self.x, ctypes.byref(self.tret), sd.CV_NORMAL)
        if flag < 0:
            if self.failure is not None:
                raise self.failure
            raise IntegrationError(f"CVODE failed at t = {self.tret.value:.9g} s (flag {flag})")
        t_now = t_out if flag == 0 else self.tret.value
        eq.check(eq.set_time(t_now), 0)
        if not self.discrete:
            eq.check(eq.set_x(self.px), 1)
        root = flag == sd.CV_ROOT_RETURN
        eq.completed(t_now)
        return t_now, root

    def free(self) -> None:
        sd = self.sd
        if getattr(self, "mem", None) is None:
            return
        sd.CVodeFree(ctypes.byref(ctypes.c_void_p(self.mem)))
        self.mem = None
        _destroy(self.LS, self.A, self.x, self.abstol, self.ctx)

    def __del__(self) -> None:
        try:
            self.free()
        except Exception:
            pass


def _destroy(ls: Any, a: Any, x: Any, abstol: Any, ctx: Any) -> None:
    """Free a CVODE run's linear solver, matrix, vectors and context (FMPy's solver leaves them)."""
    from fmpy.sundials.libraries import sundials_cvode as lib

    for name, arg in (("SUNLinSolFree", ls), ("SUNMatDestroy", a), ("N_VDestroy", x), ("N_VDestroy", abstol)):
        fn = getattr(lib, name)
        fn.argtypes, fn.restype = [ctypes.c_void_p], None
        fn(ctypes.cast(arg, ctypes.c_void_p))
    free_ctx = lib.SUNContext_Free
    free_ctx.argtypes, free_ctx.restype = [ctypes.POINTER(ctypes.c_void_p)], ctypes.c_int
    free_ctx(ctypes.byref(ctypes.c_void_p(ctypes.cast(ctx, ctypes.c_void_p).value)))


# -------------------------------------------------------------------------------------- Euler and RK4
def _euler(eq: Equations, x: list[float], t: float, dt: float, buf: Any, d: Any) -> list[float]:
    """One explicit Euler step of ``dt`` [s] from ``x`` at ``t``."""
    k = _slope(eq, x, t, buf, d)
    return [xi + dt * ki for xi, ki in zip(x, k)]


def _rk4(eq: Equations, x: list[float], t: float, dt: float, buf: Any, d: Any) -> list[float]:
    """One classical Runge-Kutta step of ``dt`` [s] from ``x`` at ``t``."""
    h2 = 0.5 * dt
    k1 = _slope(eq, x, t, buf, d)
    k2 = _slope(eq, [xi + h2 * ki for xi, ki in zip(x, k1)], t + h2, buf, d)
    k3 = _slope(eq, [xi + h2 * ki for xi, ki in zip(x, k2)], t + h2, buf, d)
    k4 = _slope(eq, [xi + dt * ki for xi, ki in zip(x, k3)], t + dt, buf, d)
    s6 = dt / 6.0
    return [xi + s6 * (a + 2.0 * (b + c) + e) for xi, a, b, c, e in zip(x, k1, k2, k3, k4)]


def _slope(eq: Equations, x: list[float], t: float, buf: Any, d: Any) -> list[float]:
    """dx/dt at (t, x) from the FMU."""
    eq.check(eq.set_time(t), 0)
    if x:
        buf[:] = x
        eq.check(eq.set_x(buf), 1)
        eq.check(eq.get_dx(d), 3)
    return d[:len(x)]


#: The fixed-step methods by name.
FIXED_STEP: dict[str, Callable[..., list[float]]] = {"euler": _euler, "rk4": _rk4}


class FixedStep(Integrator):
    """An explicit fixed-step method (Euler or RK4): each communication step ``h`` split into
    ceil(h / ``max_step``) equal steps (one with no ``max_step``).  After each step the event indicators
    are compared with the ones before it; when one changed domain, the crossing is located by bisection on
    the length of a step from the step's start, to ``event_tol`` [s], and the integration stops just after it
    (on the far side, where the indicator has changed)."""

    def __init__(self, eq: Equations, method: Callable[..., list[float]], max_step: float | None,
                 event_tol: float) -> None:
        self.eq, self.method, self.max_step, self.event_tol = eq, method, max_step, event_tol
        self.buf = (ctypes.c_double * max(1, eq.nx))()
        self.d = (ctypes.c_double * max(1, eq.nx))()
        self.zbuf = (ctypes.c_double * max(1, eq.nz))()
        self.x: list[float] = []
        self.z: list[float] = []

    def _states(self) -> list[float]:
        if not self.eq.nx:
            return []
        self.eq.check(self.eq.get_x(self.buf), 2)
        return self.buf[:self.eq.nx]

    def _indicators(self, t: float, x: list[float]) -> list[float]:
        """The event indicators at (t, x) (the FMU is left at them)."""
        eq = self.eq
        eq.check(eq.set_time(t), 0)
        if x:
            self.buf[:] = x   # type: ignore[assignment]
            eq.check(eq.set_x(self.buf), 1)
        if not eq.nz:
            return []
        eq.check(eq.get_z(self.zbuf), 5)
        return self.zbuf[:eq.nz]

    def reset(self, t: float) -> None:
        self.x = self._states()
        self.z = self._indicators(t, self.x)

    def advance(self, t: float, t_out: float) -> tuple[float, bool]:
        if not self.x and self.eq.nx:
            self.reset(t)
        span = t_out - t
        n = 1 if self.max_step is None else max(1, math.ceil(span / self.max_step - 1e-9))
        for i in range(n):
            ti, tn = t + span * i / n, (t + span * (i + 1) / n if i + 1 < n else t_out)
            xn = self.method(self.eq, self.x, ti, tn - ti, self.buf, self.d)
            zn = self._indicators(tn, xn)
            if self.eq.nz and crossed(self.z, zn):
                tn, xn, zn = self._locate(ti, tn, zn)
                self.x, self.z = xn, zn
                self.eq.completed(tn)
                return tn, True
            self.x, self.z = xn, zn
            if self.eq.completed(tn):
                return tn, False
        return t_out, False

    def _locate(self, ti: float, tn: float, zn: list[float]) -> tuple[float, list[float], list[float]]:
        """The crossing inside the step [ti, tn]: the shortest step from ti (to ``event_tol``) after which an
        indicator has changed domain; the FMU left at its end."""
        x0, z0 = self.x, self.z
        lo, hi, x_hi, z_hi = ti, tn, None, zn
        while hi - lo > self.event_tol:
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            xm = self.method(self.eq, x0, ti, mid - ti, self.buf, self.d)
            zm = self._indicators(mid, xm)
            if crossed(z0, zm):
                hi, x_hi, z_hi = mid, xm, zm
            else:
                lo = mid
        if x_hi is None:     # the full step is the shortest found
            x_hi = self.method(self.eq, x0, ti, tn - ti, self.buf, self.d)
        z_hi = self._indicators(hi, x_hi)
        return hi, x_hi, z_hi
