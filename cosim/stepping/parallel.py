"""Jacobi with instances stepped at once (``[experiment] workers = N``, N > 1, algorithm "jacobi").

Every instance's inputs are set from the previous step's outputs, then the instances step, then every
output is read, as in the serial Jacobi step; what differs is only when the steps run.  An instance hosted
in a child process (``isolate = true``) steps in two halves: the master writes the request to each of up
to N children, steps the instances in this process meanwhile (one after another: an FMU in this process
runs on the master's thread), and then waits for the children's answers.  Each FMU gets the same calls
with the same values as in the serial run, so the results are the serial Jacobi run's bit for bit.
"""
from __future__ import annotations

import time
from typing import Any

from ..instances.failure import Call, Failure
from .algorithm import Clock, InstanceIO, Row, StepDone
from .stepper import SteppedAlgorithm



class ParallelJacobi(SteppedAlgorithm):
    """Jacobi, the isolated instances' steps overlapping (see the module's docstring)."""

    def __init__(self, workers: int = 2) -> None:
        if workers < 1:
            raise ValueError(f"workers: {workers}: must be at least 1")
        self.workers = workers

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        super().setup(ios, clock, layout, done, check_inputs)
        self.split = [i for i, io in enumerate(ios) if io.fast.start_step is not None]
        self.serial = [i for i, io in enumerate(ios) if io.fast.start_step is None]
        self.spent = [0.0] * len(ios)   # [s] wall time from each step's start to its end (overlapping)

    def take(self, k: int, t: float, h: float) -> Failure | None:
        st, ios = self.stepper, self.stepper.ios
        for i in range(len(ios)):
            fail = st.set_inputs(i, k, t)
            if fail is not None:
                return fail
        st.T.value, st.H.value = t, h
        n = self.workers
        first = True
        spent, clock = self.spent, time.perf_counter
        for b in range(0, max(1, len(self.split)), n):
            batch = self.split[b:b + n]
            w0 = clock()
            started: list[int] = []   # the steps requested and not yet answered
            try:
                for i in batch:
                    f = ios[i].fast
                    assert f.start_step is not None
                    f.start_step(f.c, st.T, st.H)
                    started.append(i)
                if first:               # the instances in this process step while the first batch does
                    first = False
                    for i in self.serial:
                        w = clock()
                        fail = st.do_step(i, k, t, h)
                        spent[i] += clock() - w
                        if fail is not None:
                            self._drain(started)
                            return fail
                while started:
                    i = started.pop(0)
                    f = ios[i].fast
                    assert f.finish_step is not None
                    s = f.finish_step(False)
                    spent[i] += clock() - w0
                    st.n_do_steps += 1
                    if s:
                        self._drain(started)
                        return Failure(k, ios[i].name, Call.DO_STEP, s, t)
            except BaseException:   # a child that died, a Ctrl-C: the other steps started are answered first
                self._drain(started)
                raise
        for i in range(len(ios)):
            fail = st.get_outputs(i, k, t + h)
            if fail is not None:
                return fail
        return None

    def _drain(self, started: list[int]) -> None:
        """The answers of steps started and not answered before a failure (so that the children are idle
        again); ``started`` is emptied."""
        while started:
            i = started.pop(0)
            f = self.stepper.ios[i].fast
            if f.finish_step is not None:
                try:
                    f.finish_step(False)
                except Exception:   # (a child that died too: its own error is not the first)
                    pass

    def summary(self) -> dict[str, Any] | None:
        ios = self.stepper.ios if hasattr(self, "stepper") else []
        return {"workers": self.workers,
                "stepped_at_once": [ios[i].name for i in getattr(self, "split", [])],
                "in_this_process": [ios[i].name for i in getattr(self, "serial", [])],
                "step_time_s": {io.name: round(w, 6) for io, w in zip(ios, getattr(self, "spent", []))}}
