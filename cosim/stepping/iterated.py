"""The iterated coupling: every coupling loop solved at every macro step (``algorithm = "iterated"``).

The instances step in the plan's order, as under Gauss-Seidel; an instance outside any loop is set,
stepped and read once.  A coupling loop (a strongly connected set of instances in the plan's graph of
Float64 connections, cosim.stepping.graph.FeedGraph.loops) is stepped as one: its coupling inputs u (the
inputs its copies feed from its own outputs) are the unknowns of

    r(u) = G(y(t + h; u)) - u = 0,

where y(t + h; u) are the loop's outputs after a step of every loop instance from the saved state at t with
the coupling inputs u (held over the step, or linear from their value at t to u: ``inputs``), its other
inputs as Gauss-Seidel gives them, and G the connections' transforms.  Each evaluation after the first
restores the loop's instances to the state saved at t (fmi2SetFMUstate) before stepping again.  The
iteration stops when ``max_i |r_i| / (1 + |G_i|) <= tolerance``; the outputs kept are those of the last
evaluation.

* fixed point: u <- u + relaxation * r;
* Newton: u <- u - J^-1 r with J = dr/du by forward differences (one more evaluation per coupling
  input), kept from step to step while the residual shrinks at least by half per iteration (a chord
  method: a linear loop then costs two evaluations per step), made anew where it does not; J du = -r
  solved by Gaussian elimination in plain floats (:func:`solve_linear`).

The first guess at a step is the loop's coupling inputs extrapolated linearly from the last two steps
(G(y(t)) at the first step).  At initialisation (in initialisation mode, after the initial exchange), the
same iteration solves the loop's algebraic part with sets and gets only: no step, no state.

A loop that does not meet the tolerance within ``max_iterations`` evaluations (or whose iterate becomes
non-finite) ends the run with one line naming the loop's instances, the step, the time and the residual.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, cast

import numpy as np

from ..instances.failure import Call, Failure
from ..messages.errors import RunError
from ..messages.words import count
from .algorithm import Clock, InstanceIO, Row, StepDone
from .settings import IterationSpec
from .graph import FeedGraph
from .stepper import Stepper, SteppedAlgorithm



@dataclass
class Unknown:
    """One coupling input: instance ``i``'s input at ``pos`` takes ``src[slot] * factor + offset``."""

    i: int
    pos: int
    vr: int
    src: Any
    slot: int
    factor: float
    offset: float
    src_i: int = -1      # the instance whose output feeds it
    src_vr: int = -1     # ... and that output's value reference

    def g(self) -> float:
        """G of the output now in the row."""
        v = self.src[self.slot]
        return v if self.factor == 1.0 and self.offset == 0.0 else v * self.factor + self.offset


@dataclass
class Loop:
    """One coupling loop and what its iteration keeps from step to step."""

    members: list[int]
    unknowns: list[Unknown]
    names: list[str]
    u_end: list[float] | None = None          # the coupling inputs the last step ended with
    u_prev: list[float] | None = None         # ... and the step before it
    h_prev: float = 0.0
    jac: np.ndarray | None = None             # Newton's Jacobian, kept while it serves
    steps: int = 0
    jacobians: int = 0
    evaluations: int = 0                      # every step of the loop's instances, the Jacobian's included
    worst_residual: float = 0.0               # the largest residual accepted
    histogram: dict[int, int] = field(default_factory=dict)   # iterations -> the steps that took that many

    @property
    def iterations(self) -> int:
        """The iterations of all its steps."""
        return sum(n * c for n, c in self.histogram.items())

    @property
    def max_iterations(self) -> int:
        return max(self.histogram, default=0)

    @property
    def label(self) -> str:
        return " <-> ".join(self.names)

    def stats(self) -> dict[str, Any]:
        return {"instances": self.names, "unknowns": len(self.unknowns), "steps": self.steps,
                "iterations": self.iterations, "max_iterations_per_step": self.max_iterations,
                "mean_iterations_per_step": round(self.iterations / self.steps, 6) if self.steps else None,
                "steps_by_iterations": {str(n): self.histogram[n] for n in sorted(self.histogram)},
                "jacobians": self.jacobians, "loop_evaluations": self.evaluations,
                "max_residual_accepted": self.worst_residual}


def solve_linear(a: list[list[float]], b: list[float]) -> list[float] | None:
    """x with ``a`` x = ``b`` (Newton's step: a loop's Jacobian, n by n, and minus its residual) by Gaussian
    elimination with partial pivoting, in plain floats; None where a pivot is zero (the matrix is singular).

    Written out, not numpy's LAPACK solve: its kernels (OpenBLAS's, chosen by the CPU at run time, with fused
    multiply-adds) round differently from one machine to another, and the FMU container's runtime
    (stepping/container_iter.c) does these operations in C in this order, so that its Newton steps equal
    the master's bit for bit.  The pivot of column c is the first row at or below c of the largest |a[i][c]|;
    each row below it loses l = a[i][c] / a[c][c] times it (then the right-hand side: b[i] - l * b[c]); back
    substitution subtracts a[i][j] x[j] for j = i + 1 .. n - 1 in that order, then divides by a[i][i].  A 1 by
    1 system is b / a, as LAPACK's."""
    n = len(b)
    m = [list(row) for row in a]
    x = list(b)
    for c in range(n):
        p = c
        for i in range(c + 1, n):
            if abs(m[i][c]) > abs(m[p][c]):
                p = i
        if m[p][c] == 0.0:
            return None
        if p != c:
            m[c], m[p] = m[p], m[c]
            x[c], x[p] = x[p], x[c]
        for i in range(c + 1, n):
            lc = m[i][c] / m[c][c]
            for j in range(c + 1, n):
                m[i][j] = m[i][j] - lc * m[c][j]
            x[i] = x[i] - lc * x[c]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, n):
            s = s - m[i][j] * x[j]
        x[i] = s / m[i][i]
    return x


class NotConverged(Exception):
    """A loop's iteration failed: the message (without the step and time)."""


def find_loops(ios: list[InstanceIO], feeds: FeedGraph) -> tuple[list[list[int]], list[Loop]]:
    """The components of the graph ``feeds`` in stepping order and the coupling loops among them, with
    their unknowns (the loop's copies that read its own outputs)."""
    owner = {id(io.out_val): i for i, io in enumerate(ios)}
    loops = []
    for comp in feeds.loops:
        mine = set(comp)
        unknowns = [Unknown(i, c.pos, ios[i].in_vr[c.pos] if c.pos < len(ios[i].in_vr) else -1, c.src, c.slot,
                            c.factor, c.offset, owner[id(c.src)], ios[owner[id(c.src)]].out_vr[c.slot])
                    for i in comp for c in ios[i].copies if owner.get(id(c.src)) in mine]
        loops.append(Loop(comp, unknowns, [ios[i].name for i in comp]))
    return feeds.components, loops


class LoopSolver:
    """The iteration of one loop (see the module's docstring)."""

    def __init__(self, spec: IterationSpec) -> None:
        self.spec = spec

    def solve(self, loop: Loop, evaluate: Callable[[list[float]], list[float]],
              guess: list[float], directional: Callable[[], np.ndarray] | None = None) -> list[float]:
        """The coupling inputs that meet the tolerance, the last evaluation's outputs left in the row;
        ``evaluate(u)`` gives G(y(u)); ``directional()``, where given, Newton's Jacobian dr/du from the
        FMUs' directional derivatives at the last evaluation.  NotConverged when it fails."""
        spec = self.spec
        u = list(guess)
        err_prev = math.inf
        for it in range(1, spec.max_iterations + 1):
            g = evaluate(u)
            loop.evaluations += 1
            r = [gi - ui for gi, ui in zip(g, u)]
            err = max((abs(ri) / (1.0 + abs(gi)) for ri, gi in zip(r, g)), default=0.0)
            if err <= spec.tolerance:
                loop.histogram[it] = loop.histogram.get(it, 0) + 1
                loop.worst_residual = max(loop.worst_residual, err)
                return u
            if not math.isfinite(err):
                raise NotConverged(f"the iterate is no longer finite after {count(it, 'iteration')} ({spec.method})")
            if it == spec.max_iterations:
                raise NotConverged(f"residual {err:.3g} after {count(it, 'iteration')} ({spec.method}, tolerance "
                                   f"{spec.tolerance:g})")
            if spec.method == "fixed-point":
                w = spec.relaxation
                u = [ui + w * ri for ui, ri in zip(u, r)]
            else:
                if loop.jac is None or err > 0.5 * err_prev:
                    if directional is not None:
                        loop.jac = directional()
                        loop.jacobians += 1
                    else:
                        loop.jac = self.jacobian(loop, evaluate, u, r)
                du = solve_linear(loop.jac.tolist(), [-ri for ri in r])
                if du is None:
                    raise NotConverged(f"the Jacobian is singular after {count(it, 'iteration')} (newton)")
                u = [ui + d for ui, d in zip(u, du)]
            if not all(math.isfinite(x) for x in u):
                raise NotConverged(f"the iterate is no longer finite after {count(it, 'iteration')} ({spec.method})")
            err_prev = err
        raise AssertionError("unreachable")   # (the last iteration returns or raises)

    def jacobian(self, loop: Loop, evaluate: Callable[[list[float]], list[float]], u: list[float],
                 r: list[float]) -> np.ndarray:
        """dr/du by forward differences at u (r: the residual there)."""
        n = len(u)
        jac = np.empty((n, n))
        for j in range(n):
            d = 1.4901161193847656e-08 * max(1.0, abs(u[j]))   # sqrt(machine epsilon), scaled
            uj = list(u)
            uj[j] += d
            gj = evaluate(uj)
            loop.evaluations += 1
            for i in range(n):
                jac[i, j] = ((gj[i] - uj[i]) - r[i]) / d
        loop.jacobians += 1
        return jac


class IteratedStep:
    """The iterated macro step from t over h (any t and h: the step-size control takes it too)."""

    def __init__(self, stepper: Stepper, spec: IterationSpec) -> None:
        self.stepper, self.spec = stepper, spec
        self.solver = LoopSolver(spec)
        self.comps: list[list[int]] = []
        self.loops: dict[int, Loop] = {}        # first member -> loop
        self.old: dict[tuple[str, ...], Loop] = {}
        self.initial_iterations = 0
        self.refresh()

    def refresh(self) -> None:
        """The loops of the copies as they are now (after events changed them); a loop whose instances are
        the same keeps its counts (the history of its inputs is dropped: the copies changed)."""
        comps, loops = find_loops(self.stepper.ios, self.stepper.graph)
        self.comps = comps
        self.loops = {}
        for lp in loops:
            prev = self.old.get(tuple(lp.names))
            if prev is not None:
                for f in ("steps", "jacobians", "evaluations", "worst_residual", "histogram"):
                    setattr(lp, f, getattr(prev, f))
            self.old[tuple(lp.names)] = lp
            self.loops[lp.members[0]] = lp
        for lp in self.loops.values():
            self.stepper.allow_rollback(lp.members)

    def memo(self) -> list[tuple[Any, ...]]:
        """What the loops keep from step to step (for the step-size control's rollback)."""
        return [(lp.u_end, lp.u_prev, lp.h_prev) for lp in self.loops.values()]

    def restore_memo(self, memo: list[tuple[Any, ...]]) -> None:
        for lp, (a, b, c) in zip(self.loops.values(), memo):
            lp.u_end, lp.u_prev, lp.h_prev = a, b, c

    def step(self, k: int, t: float, h: float) -> Failure | None:
        st = self.stepper
        for comp in self.comps:
            lp = self.loops.get(comp[0])
            if lp is None:
                fail = st.pass_gauss_seidel(k, t, h, comp)
            else:
                fail = self.loop_step(lp, k, t, h)
            if fail is not None:
                return fail
        return None

    def loop_step(self, lp: Loop, k: int, t: float, h: float) -> Failure | None:
        st, spec = self.stepper, self.spec
        g0 = [x.g() for x in lp.unknowns]
        start = lp.u_end if lp.u_end is not None else g0
        if lp.u_end is not None and lp.u_prev is not None and lp.h_prev > 0.0:
            s = h / lp.h_prev
            guess = [a + (a - b) * s for a, b in zip(lp.u_end, lp.u_prev)]
        else:
            guess = list(g0)
        linear = spec.inputs == "linear"
        saved = st.save(lp.members)
        first = [True]
        fail_box: list[Failure] = []

        def evaluate(u: list[float]) -> list[float]:
            if not first[0]:
                st.restore(saved)
            first[0] = False
            given: dict[int, dict[int, float]] = {}
            for x, v in zip(lp.unknowns, start if linear else u):
                given.setdefault(x.i, {})[x.pos] = v
            for i in lp.members:
                fail = st.set_inputs(i, k, t, given.get(i))
                if fail is None and linear:
                    fail = self.derivatives(lp, i, k, t, h, start, u)
                if fail is not None:
                    fail_box.append(fail)
                    raise NotConverged("")
            for i in lp.members:
                fail = st.do_step(i, k, t, h) or st.get_outputs(i, k, t + h)
                if fail is not None:
                    fail_box.append(fail)
                    raise NotConverged("")
            return [x.g() for x in lp.unknowns]

        dd = (lambda: self.directional(lp, t + h)) if spec.jacobian == "directional" else None
        try:
            u = self.solver.solve(lp, evaluate, guess, dd)
        except NotConverged as exc:
            if fail_box:
                return fail_box[0]
            return Failure(k, lp.names[0], Call.COUPLING,
                           f"the coupling loop {lp.label} did not converge at step {k} (t = {t:.9g} s, h = "
                           f"{h:.6g} s): {exc}", t)
        except RunError as exc:
            return Failure(k, lp.names[0], Call.COUPLING, str(exc), t)
        finally:
            st.free(saved)
        lp.u_prev, lp.u_end, lp.h_prev = start, u, h
        lp.steps += 1
        return None

    def directional(self, lp: Loop, t: float) -> np.ndarray:
        """dr/du = D - I, D[m, j] = factor_m * d y_m / d u_j from the directional derivatives of the
        instance owning both (zero across instances: an instance's outputs depend on its own inputs only)
        at the current point (RunError where a call fails)."""
        ios = self.stepper.ios
        n = len(lp.unknowns)
        jac = -np.eye(n)
        for j, xj in enumerate(lp.unknowns):
            rows = [m for m, xm in enumerate(lp.unknowns) if xm.src_i == xj.i]
            if not rows:
                continue
            io = ios[xj.i]
            assert io.directional_derivative is not None
            st, col = io.directional_derivative([lp.unknowns[m].src_vr for m in rows], [xj.vr], [1.0])
            if st:
                raise RunError(f"{io.name}: the directional derivative returned status {st} at t = {t:.9g} s",
                               io.name, t)
            for m, v in zip(rows, col):
                jac[m, j] += lp.unknowns[m].factor * v
        return jac

    def derivatives(self, lp: Loop, i: int, k: int, t: float, h: float, start: list[float], u: list[float]
                    ) -> Failure | None:
        """Instance i's coupling inputs linear from ``start`` at t to ``u`` at t + h."""
        io = self.stepper.ios[i]
        mine = [(x.vr, (b - a) / h) for x, a, b in zip(lp.unknowns, start, u) if x.i == i]
        if not mine:
            return None
        assert io.set_input_derivatives is not None
        s = io.set_input_derivatives([v for v, _ in mine], [d for _, d in mine])
        if s:
            return Failure(k, io.name, Call.COUPLING, f"{io.name}: fmi2SetRealInputDerivatives returned {s} at "
                           f"t = {t:.9g} s", t)
        return None

    def initialize(self, t0: float) -> None:
        """The loops' algebraic part at t0 in initialisation mode: set and get, no step (RunError)."""
        st = self.stepper
        for lp in self.loops.values():
            fail_box: list[Failure] = []

            def evaluate(u: list[float], lp: Loop = lp, fail_box: list[Failure] = fail_box) -> list[float]:
                given: dict[int, dict[int, float]] = {}
                for x, v in zip(lp.unknowns, u):
                    given.setdefault(x.i, {})[x.pos] = v
                for i in lp.members:
                    fail = st.set_inputs(i, 0, t0, given.get(i))
                    if fail is None:
                        fail = st.get_outputs(i, -1, t0)
                    if fail is not None:
                        fail_box.append(fail)
                        raise NotConverged("")
                return [x.g() for x in lp.unknowns]

            g0 = [x.g() for x in lp.unknowns]
            before = (lp.iterations, lp.evaluations, dict(lp.histogram))
            dd = (lambda lp=lp: self.directional(lp, t0)) if self.spec.jacobian == "directional" else None
            try:
                self.solver.solve(lp, evaluate, g0, dd)
            except NotConverged as exc:
                if fail_box:
                    f = fail_box[0]
                    raise RunError(f"{f.instance}: {f.call.value} returned {f.value} at t = {t0:.6g} s "
                                   "(initialisation)", f.instance, t0) from None
                raise RunError(f"the coupling loop {lp.label} did not converge at initialisation (t = {t0:.9g} s): "
                               f"{exc}", lp.names[0], t0) from None
            self.initial_iterations += lp.iterations - before[0]
            _, lp.evaluations, lp.histogram = before
            lp.jac = None   # (the Jacobian of the algebraic part alone is not the step's)


class Iterated(SteppedAlgorithm):
    """Fixed step, every coupling loop iterated (see the module's docstring)."""

    def __init__(self, spec: IterationSpec | None = None) -> None:
        self.spec = spec or IterationSpec()
        self.step: IteratedStep | None = None
        self.initial_iterations = 0

    def initialize(self, ios: list[InstanceIO], t0: float, check_inputs: bool = True) -> None:
        st = Stepper(ios, Clock(t0, 1.0, 0), cast(Row, _NoLayout()), lambda k, ended: None, check_inputs,
                     self.feeds)
        it = IteratedStep(st, self.spec)
        it.initialize(t0)
        self.initial_iterations = it.initial_iterations

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        super().setup(ios, clock, layout, done, check_inputs)
        self.step = IteratedStep(self.stepper, self.spec)

    def inputs_changed(self) -> None:
        super().inputs_changed()
        assert self.step is not None
        self.step.refresh()

    def take(self, k: int, t: float, h: float) -> Failure | None:
        assert self.step is not None
        return self.step.step(k, t, h)

    def summary(self) -> dict[str, Any] | None:
        loops = list(self.step.old.values()) if self.step is not None else []
        return {"iteration": self.spec.as_dict(),
                "initial_iterations": self.initial_iterations,
                "instance_steps": getattr(getattr(self, "stepper", None), "n_do_steps", 0),
                "loops": [lp.stats() for lp in loops]}


@dataclass
class _NoLayout:
    """The row's stand-in at initialisation: nothing is recorded there."""

    buf: Any = field(default_factory=lambda: bytearray())
