"""Jacobi with instances stepped at once (``[experiment] workers = N``, N > 1, algorithm "jacobi").

Every instance's inputs are set from the previous step's outputs, then the instances step, then every
output is read, as in the serial Jacobi step; what differs is only when the steps run.  Three kinds of
instance step at once, each its own way:

* an instance of a C FMU in this process steps in one of N lanes: the master's thread and N - 1 threads
  that live for the run (:class:`~.lanes.Lanes`), its step a foreign call that lets go of the GIL
  (:attr:`~..instances.contract.FastPath.threaded_step`); the instances are dealt to the lanes in the
  plan's order, one each in turn, the master's lane first; where steps are too short to pay the hand-off,
  or the cores are busy, the lanes run one after another on the master's thread (:class:`LaneChoice`
  measures which is faster as the run goes);
* an instance hosted in a child process (``isolate = true``) steps in two halves: the master writes the
  request to each of up to N children, and waits for their answers after its own lane's steps;
* an instance whose step needs this process's Python (a pythonfmu FMU, a Model Exchange instance) steps
  on the master's thread, after its lane: threads would give it nothing (the GIL), and the run's summary
  says why (``alone``).

Each FMU gets the same calls with the same values as in the serial run, so the results are the serial
Jacobi run's bit for bit.
"""
from __future__ import annotations

import functools
import time
from typing import Any, Callable

from ..instances.failure import Call, Failure
from .algorithm import Clock, InstanceIO, Row, StepDone
from .lanes import Lanes
from .stepper import SteppedAlgorithm



class ParallelJacobi(SteppedAlgorithm):
    """Jacobi, the instances' steps overlapping (see the module's docstring)."""

    def __init__(self, workers: int = 2) -> None:
        if workers < 1:
            raise ValueError(f"workers: {workers}: must be at least 1")
        self.workers = workers
        self.lanes: Lanes | None = None
        self.choice = LaneChoice()

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        super().setup(ios, clock, layout, done, check_inputs)
        self.split = [i for i, io in enumerate(ios) if io.fast.start_step is not None]
        threaded = [i for i, io in enumerate(ios) if io.fast.threaded_step is not None]
        n = min(self.workers, len(threaded))
        if n < 2:   # one lane: the master's thread alone
            threaded = []
        # lane 0 is the master's thread; the instances dealt to the lanes in turn
        self.lanes_members = [threaded[j::n] for j in range(n)] if threaded else []
        self.serial = [i for i, io in enumerate(ios) if io.fast.start_step is None and i not in threaded]
        self.spent = [0.0] * len(ios)   # [s] wall time from each step's start to its end (overlapping)
        self.index = {io.name: i for i, io in enumerate(ios)}
        for i in threaded:   # (from now on every step of theirs lets go of the GIL)
            ios[i].fast.do_step = ios[i].fast.threaded_step  # type: ignore[assignment]
        self.lanes = Lanes(n - 1) if threaded else None
        self.in_order = sorted(threaded)
        self.choice = LaneChoice()

    def finish(self) -> None:
        if self.lanes is not None:
            self.lanes.close()
            self.lanes = None

    def _lane(self, members: list[int], k: int, t: float, h: float,
              steps: list[Callable[..., Failure | None]]) -> Failure | None:
        """One lane's instances stepped one after another; the first failure."""
        spent, clock = self.spent, time.perf_counter
        for i, step in zip(members, steps):
            w = clock()
            fail = step(k, t, h)
            spent[i] += clock() - w
            if fail is not None:
                return fail
        return None

    def take(self, k: int, t: float, h: float) -> Failure | None:
        st, ios = self.stepper, self.stepper.ios
        for i in range(len(ios)):
            fail = st.set_inputs(i, k, t)
            if fail is not None:
                return fail
        st.T.value, st.H.value = t, h
        fail = self._steps(k, t, h)
        if fail is not None:
            return fail
        for i in range(len(ios)):
            fail = st.get_outputs(i, k, t + h)
            if fail is not None:
                return fail
        return None

    def _here(self, k: int, t: float, h: float) -> Failure | None:
        """The steps in this process: the lanes' (the threads' and the master's) at once, then those on the
        master's thread alone; of several failures, the one of the instance first in the plan."""
        st = self.stepper
        lanes, members = self.lanes, self.lanes_members
        first: Failure | None = None
        if lanes is not None:
            threads = self.choice.threads()
            w0 = time.perf_counter()
            if threads:
                steps = [[st._parts(i)[1] for i in m] for m in members]   # (made here: not in the threads)
                for j in range(1, len(members)):
                    lanes.start(j - 1, functools.partial(self._lane, members[j], k, t, h, steps[j]))
                try:
                    first = self._lane(members[0], k, t, h, steps[0])
                finally:
                    for j in range(1, len(members)):   # every lane answered before anything else happens
                        fail = lanes.wait(j - 1)
                        if fail is not None and (first is None or
                                                 self.index[fail.instance] < self.index[first.instance]):
                            first = fail
            else:   # the lanes one after another on the master's thread, in the plan's order
                first = self._lane(self.in_order, k, t, h, [st._parts(i)[1] for i in self.in_order])
            self.choice.took(threads, time.perf_counter() - w0)
            st.n_do_steps += sum(len(m) for m in members)
            if first is not None:
                return first
        spent, clock = self.spent, time.perf_counter
        for i in self.serial:
            w = clock()
            fail = st.do_step(i, k, t, h)
            spent[i] += clock() - w
            if fail is not None:
                return fail
        return None

    def _steps(self, k: int, t: float, h: float) -> Failure | None:
        """The isolated instances' steps, N children at once, and meanwhile (during the first N) the steps
        in this process (:meth:`_here`)."""
        st, ios = self.stepper, self.stepper.ios
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
                if first:
                    first = False
                    fail = self._here(k, t, h)
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
        lanes = getattr(self, "lanes_members", [])
        return {"workers": self.workers,
                "stepped_at_once": [ios[i].name for i in getattr(self, "split", [])],
                "in_threads": [[ios[i].name for i in m] for m in lanes],
                "in_this_process": [ios[i].name for i in getattr(self, "serial", [])],
                "alone": {ios[i].name: ios[i].fast.alone for i in getattr(self, "serial", []) if ios[i].fast.alone},
                "steps_in_threads": self.choice.in_threads,
                "steps_on_the_master_alone": self.choice.alone,
                "step_time_s": {io.name: round(w, 6) for io, w in zip(ios, getattr(self, "spent", []))}}



class LaneChoice:
    """Whether a step's lanes run in their threads or one after another on the master's thread: the
    results are the same either way (each FMU gets the same calls), so the faster one is taken.  Threads
    gain where a step computes long enough to pay the hand-off (about 20 us there and back here) and
    cores are free; on the master's thread alone wins where steps are short or the machine is busy.  The
    choice is measured: ``PROBE`` steps in threads, then ``PROBE`` on the master alone, the faster mean
    kept for ``KEEP`` steps, then measured again (a machine's load changes during a run)."""

    PROBE = 16
    KEEP = 2048

    def __init__(self) -> None:
        self.phase = 0          # steps into the current cycle of probe, probe, keep
        self.sums = [0.0, 0.0]  # [s] the probes' wall times: threads, master alone
        self.keep_threads = True
        self.in_threads = 0     # steps taken each way
        self.alone = 0

    def threads(self) -> bool:
        """Whether the next step runs the lanes in their threads."""
        if self.phase < self.PROBE:
            return True
        if self.phase < 2 * self.PROBE:
            return False
        return self.keep_threads

    def took(self, threads: bool, seconds: float) -> None:
        """A step took ``seconds`` [s] of wall time, in threads or not."""
        if threads:
            self.in_threads += 1
        else:
            self.alone += 1
        if self.phase < 2 * self.PROBE:
            self.sums[0 if threads else 1] += seconds
            if self.phase == 2 * self.PROBE - 1:
                self.keep_threads = self.sums[0] <= self.sums[1]
                self.sums = [0.0, 0.0]
        self.phase = (self.phase + 1) % (2 * self.PROBE + self.KEEP)
