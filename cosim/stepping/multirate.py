"""Instances at their own rates (``[instances.X] step``): one pass per base step, Gauss-Seidel or Jacobi,
each instance stepping only at its own points (``algorithm`` stays "gauss-seidel" or "jacobi"; this is
the algorithm object the execution uses for them when some instance has a step of its own).

An instance with decimation d (its step = d times the experiment's step h) takes its steps from the
points t_{jd} over d h, and its outputs are read when a step completes (time t_{(j+1)d}) and hold in
between: the recording, at the base step, shows each output as last completed.

* Jacobi (libcosim's fixed-step algorithm with decimation factors): an instance steps at the base steps k
  with k mod d = 0, its inputs set there, before any instance steps, from the outputs as they are at t_k;
  the outputs completing at t_{k+1} are read after all have stepped.  (libcosim passes a value at the
  points common to both ends, which are the receiver's step points when, as the plan checks, connected
  rates divide one another.)
* Gauss-Seidel: in the plan's order, an instance takes its step from t_{jd} in the base step that ends
  it, k = (j+1)d - 1, with its inputs from the outputs as they are then: as in single-rate Gauss-Seidel, an
  instance's step from t to t + H sees the outputs its predecessors produced at t + H (a slow sensor after
  a fast plant samples the plant at the end of its own step, as it does when both run at its rate), and
  its successors see its outputs in the same base step.

With every decimation 1 the passes are the fixed-step algorithms' bit for bit.  Where a C compiler is at
hand they run in the compiled loop (:mod:`.native`), bit for bit these.

Events, tables and the script act on the base grid: a value set between an instance's points reaches it
at its next step (under Gauss-Seidel, the step taken at the end of the interval the value was set in).
Tabulated inputs are sampled at the start of the instance's step.
"""
from __future__ import annotations

import time
from typing import Any

from ..instances.failure import Failure
from .algorithm import Clock, InstanceIO, Row, StepDone
from .stepper import SteppedAlgorithm



class MultiRate(SteppedAlgorithm):
    """Gauss-Seidel or Jacobi with each instance at its own rate (see the module's docstring)."""

    def __init__(self, jacobi: bool = False) -> None:
        """Gauss-Seidel's order, or Jacobi's where ``jacobi``."""
        self.jacobi = jacobi
        self.steps: list[int] = []

    native = True                          # False: the passes in Python (a test's)
    loop_used = ""

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        super().setup(ios, clock, layout, done, check_inputs)
        self.dec = [io.decimation for io in ios]
        self.steps = [0] * len(ios)
        self.spent = [0.0] * len(ios)      # [s] wall time in each instance's steps
        self.compiled: Any = None

    def inputs_changed(self) -> None:
        super().inputs_changed()
        self.compiled = None

    def advance(self, k0: int, k1: int) -> Failure | None:
        """The passes in the compiled loop where it can be built (:mod:`.native`), else in Python."""
        if self.compiled is None:
            from . import native

            lib, why = native.library() if self.native else (None, "asked for")
            if lib is None:
                self.loop_used = f"{native.PYTHON} ({why})"
                return super().advance(k0, k1)
            self.loop_used = native.NATIVE
            st = self.stepper
            self.compiled = native.NativeLoop(lib, st.ios, self.jacobi, self.clock, st.done, st.check_inputs,
                                              rates=self.dec)
        try:
            return self.compiled(k0, k1)
        finally:
            for i, (n, w) in enumerate(self.compiled.counts()):
                self.steps[i] += n
                self.spent[i] += w

    def take(self, k: int, t: float, h: float) -> Failure | None:
        return self._jacobi(k, t, h) if self.jacobi else self._gauss_seidel(k, t, h)

    def _gauss_seidel(self, k: int, t: float, h: float) -> Failure | None:
        st, dec, steps, c = self.stepper, self.dec, self.steps, self.clock
        for i, d in enumerate(dec):
            if (k + 1) % d == 0:      # its step from t_{k+1-d} ends with this base step: taken now
                k0 = k + 1 - d
                t0 = t if d == 1 else c.start + k0 * c.step
                fail = st.set_inputs(i, k0, t0)
                if fail is None:
                    w = time.perf_counter()
                    fail = st.do_step(i, k0, t0, d * h)
                    self.spent[i] += time.perf_counter() - w
                fail = fail or st.get_outputs(i, k, t + h)
                if fail is not None:
                    return fail
                steps[i] += 1
        return None

    def _jacobi(self, k: int, t: float, h: float) -> Failure | None:
        st, dec, steps = self.stepper, self.dec, self.steps
        now = [i for i, d in enumerate(dec) if k % d == 0]
        for i in now:
            fail = st.set_inputs(i, k, t)
            if fail is not None:
                return fail
        for i in now:
            w = time.perf_counter()
            fail = st.do_step(i, k, t, dec[i] * h)
            self.spent[i] += time.perf_counter() - w
            if fail is not None:
                return fail
            steps[i] += 1
        for i, d in enumerate(dec):
            if (k + 1) % d == 0:
                fail = st.get_outputs(i, k, t + h)
                if fail is not None:
                    return fail
        return None

    def summary(self) -> dict[str, Any] | None:
        ios = self.stepper.ios if hasattr(self, "stepper") else []
        h = self.clock.step if hasattr(self, "clock") else 0.0
        rates = {"rates": {io.name: {"step": d * h, "decimation": d, "steps": n, "step_time_s": round(w, 6)}
                           for io, d, n, w in zip(ios, self.dec, self.steps, self.spent)}}
        return {**rates, "loop": self.loop_used} if self.loop_used else rates
