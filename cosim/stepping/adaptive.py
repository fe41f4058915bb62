"""Step-size control with an error estimate (``algorithm = "adaptive"``): step doubling with rollback.

The experiment's ``step`` is the output interval: the recording, the events, the script and the stop time
are on its grid t_k = start + k step, and every macro step lands on each of its points.  Between two of
them the macro steps h vary between ``min_step`` and ``max_step``.  A macro step from t is taken twice from
the same saved state of every instance (fmi2GetFMUstate / fmi2SetFMUstate) and of the row of outputs:

1. once over h, giving the coupling variables y_1 (the Float64 outputs that feed connections);
2. once as two steps of h/2, giving y_2;

the error estimate is the RMS over the coupling variables of (y_2 - y_1) / (atol + rtol max(|y_1|, |y_2|)).
A step whose estimate is at most 1 is kept with the two half steps' result (local extrapolation: the more
accurate of the two); one above 1 is rolled back to the saved state and taken again shorter.  The next step
comes from a PI controller (Gustafsson's, in the form Hairer and Wanner give it):

    h_next = h * clip(0.9 * err^(-0.7/q) * err_prev^(0.4/q), 0.2, 5),    q = p + 1,

p being the order of the coupling of the step taken (1 for one Gauss-Seidel or Jacobi pass and for the
iterated step with held inputs, 2 for the iterated step with linear inputs); after a rejection the step
does not grow, and a rejected step shrinks by clip(0.9 err^(-1/q), 0.2, 1).  A step that would leave less
than a tenth of itself before the next grid point is stretched to it (never beyond ``max_step``).  An
error above 1 at ``min_step`` ends the run with one line naming the time, the step and the estimate.

Each macro step costs three steps of every instance and a save and restore of the system; the counts of
accepted and rejected steps, the instances' steps and the step sizes taken are in summary.json
(``stepping``).
"""
from __future__ import annotations

import math
from typing import Any

from ..instances.failure import Call, Failure
from ..messages.errors import RunError
from .algorithm import Algorithm, Clock, InstanceIO, Row, StepDone
from .iterated import IteratedStep
from .settings import AdaptiveSpec, IterationSpec
from .stepper import Stepper


SAFETY, FAC_MIN, FAC_MAX = 0.9, 0.2, 5.0


class Adaptive(Algorithm):
    """Step doubling and a PI controller over one kind of macro step (see the module's docstring)."""

    def __init__(self, spec: AdaptiveSpec, iteration: IterationSpec | None = None, *, iterated: bool = False,
                 jacobi: bool = False) -> None:
        """``spec.coupling`` names the step taken; ``iterated``: it solves the coupling loops (``iteration``
        its settings), else one pass, in Jacobi's order where ``jacobi`` (stepping.table.make says which)."""
        self.spec0 = spec
        self.iteration = iteration or IterationSpec()
        self.iterates, self.jacobi = iterated, jacobi
        self.iterated: IteratedStep | None = None
        self.accepted = self.rejected = 0
        self.h_min_taken, self.h_max_taken = math.inf, 0.0
        self.initial_iterations = 0

    def initialize(self, ios: list[InstanceIO], t0: float, check_inputs: bool = True) -> None:
        if self.iterates:
            from .iterated import Iterated
            it = Iterated(self.iteration)
            it.feeds = self.feeds
            it.initialize(ios, t0, check_inputs)
            self.initial_iterations = it.initial_iterations

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        self.clock, self.layout = clock, layout
        self.spec = self.spec0.resolved(clock.step)
        self.stepper = Stepper(ios, clock, layout, done, check_inputs, self.feeds)
        self.stepper.allow_rollback()
        if self.iterates:
            self.iterated = IteratedStep(self.stepper, self.iteration)
        linear = self.iterates and self.iteration.inputs == "linear"
        self.q = 3.0 if linear else 2.0
        assert self.spec.initial_step is not None
        self.h = self.spec.initial_step
        self.err_prev = 1.0
        self.inputs_changed()

    def inputs_changed(self) -> None:
        """The coupling variables of the copies as they are now, who feeds whom as the execution gives it."""
        self.stepper.feeds = self.feeds
        ios = self.stepper.ios
        owner = {id(io.out_val): io.out_val for io in ios}
        seen: dict[tuple[int, int], tuple[Any, int]] = {}
        for io in ios:
            for c in io.copies:
                if id(c.src) in owner:
                    seen.setdefault((id(c.src), c.slot), (c.src, c.slot))
        self.coupled = list(seen.values())
        if self.iterated is not None:
            self.iterated.refresh()

    def _step(self, k: int, t: float, h: float) -> Failure | None:
        if self.iterated is not None:
            return self.iterated.step(k, t, h)
        if self.jacobi:
            return self.stepper.pass_jacobi(k, t, h)
        return self.stepper.pass_gauss_seidel(k, t, h)

    def _values(self) -> list[float]:
        return [src[slot] for src, slot in self.coupled]

    def _error(self, y1: list[float], y2: list[float]) -> float:
        sp = self.spec
        if not y1:
            return 0.0
        acc = 0.0
        for a, b in zip(y1, y2):
            w = sp.atol + sp.rtol * max(abs(a), abs(b))
            acc += ((b - a) / w) ** 2
        return math.sqrt(acc / len(y1))

    def advance(self, k0: int, k1: int) -> Failure | None:
        c = self.clock
        for k in range(k0, k1):
            fail = self.interval(k, c.time(k), c.time(k + 1)) or self.stepper.stepped(k)
            if fail is not None:
                return fail
        return None

    def interval(self, k: int, t: float, t_end: float) -> Failure | None:
        """The macro steps from t_k to t_{k+1} [s]."""
        sp, st = self.spec, self.stepper
        assert sp.min_step is not None and sp.max_step is not None
        hmin, hmax = sp.min_step, sp.max_step
        rejected_here = False
        while t < t_end:
            h = self.h
            remaining = t_end - t
            eps = 1e-9 * h    # (t + h may miss t_end by rounding: such a step is the last one)
            last = remaining <= h + eps or (remaining <= 1.1 * h and remaining <= hmax + eps)
            if last:
                h = remaining
            memo = self.iterated.memo() if self.iterated is not None else None
            try:
                saved = st.save()
            except RunError as exc:
                return Failure(k, exc.instance or st.ios[0].name, Call.COUPLING, str(exc), t)
            try:
                fail, err = self._trial(k, t, h, saved, memo)
                if fail is not None:
                    return fail
                if err > 1.0:
                    self._roll_back(saved, memo)
                    self.rejected += 1
                    rejected_here = True
                    self.h = max(hmin, h * min(1.0, max(FAC_MIN, SAFETY * err ** (-1.0 / self.q))))
                    continue
            except RunError as exc:
                return Failure(k, exc.instance or st.ios[0].name, Call.COUPLING, str(exc), t)
            finally:
                st.free(saved)
            self._accepted(h, err, last, rejected_here)   # the two half steps' state is the system's now
            rejected_here = False
            t = t_end if last else t + h
        return None

    def _roll_back(self, saved: Any, memo: Any) -> None:
        self.stepper.restore(saved)
        if memo is not None and self.iterated is not None:
            self.iterated.restore_memo(memo)

    def _trial(self, k: int, t: float, h: float, saved: Any, memo: Any) -> tuple[Failure | None, float]:
        """The step over h, then back and the two half steps: (a failure or the end of the simulation,
        the error estimate).  An estimate above 1 at min_step (or not finite) is the failure."""
        st, sp = self.stepper, self.spec
        fail = self._step(k, t, h)
        if fail is not None or st.ended() is not None:
            return fail or self._ended(k, t + h), 0.0
        y1 = self._values()
        self._roll_back(saved, memo)
        half = 0.5 * h
        fail = self._step(k, t, half)
        if fail is None and st.ended() is None:
            fail = self._step(k, t + half, h - half)
        if fail is not None or st.ended() is not None:
            return fail or self._ended(k, t + h), 0.0
        err = self._error(y1, self._values())
        assert sp.min_step is not None
        if (err > 1.0 and h <= sp.min_step * (1.0 + 1e-9)) or not math.isfinite(err):
            return Failure(k, st.ios[0].name, Call.COUPLING,
                           f"step-size control: the error estimate {err:.3g} exceeds the tolerance (rtol "
                           f"{sp.rtol:g}, atol {sp.atol:g}) at the step {h:.6g} s (min_step {sp.min_step:g} s) "
                           f"from t = {t:.9g} s", t), err
        return None, err

    def _accepted(self, h: float, err: float, last: bool, rejected_here: bool) -> None:
        """Count the step and choose the next one (the PI controller)."""
        sp, q = self.spec, self.q
        assert sp.min_step is not None and sp.max_step is not None
        self.accepted += 1
        self.h_min_taken, self.h_max_taken = min(self.h_min_taken, h), max(self.h_max_taken, h)
        fac = SAFETY * max(err, 1e-10) ** (-0.7 / q) * self.err_prev ** (0.4 / q)
        fac = min(FAC_MAX, max(FAC_MIN, fac))
        if rejected_here:
            fac = min(fac, 1.0)
        h_next = h * fac
        if last and h < self.h and fac >= 1.0:   # a step cut short to land: the controller's own step stays
            h_next = max(h_next, self.h)
        self.h = min(sp.max_step, max(sp.min_step, h_next))
        self.err_prev = max(err, 1e-4)

    def _ended(self, k: int, t: float) -> Failure:
        io = self.stepper.ended()
        assert io is not None
        last = io.fast.last_time
        return Failure(k, io.name, Call.TERMINATED, last.value if last is not None else t, t)

    def settings(self) -> AdaptiveSpec:
        """The settings it runs with: its defaults filled in once it is set up."""
        return getattr(self, "spec", self.spec0)

    def summary(self) -> dict[str, Any] | None:
        out: dict[str, Any] = {
            "accepted_steps": self.accepted,
            "rejected_steps": self.rejected,
            "instance_steps": getattr(getattr(self, "stepper", None), "n_do_steps", 0),
            "smallest_step": self.h_min_taken if self.accepted else None,
            "largest_step": self.h_max_taken if self.accepted else None}
        if self.iterated is not None:
            out["iteration"] = self.iteration.as_dict()
            out["initial_iterations"] = self.initial_iterations
            out["loops"] = [lp.stats() for lp in self.iterated.old.values()]
        return out
