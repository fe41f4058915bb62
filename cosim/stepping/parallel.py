"""Instances stepped at once (``[experiment] workers = N``, N > 1): Jacobi, and Gauss-Seidel by levels.

Jacobi sets every instance's inputs from the previous step's outputs, steps them, reads every output:
every instance may step at once.  Gauss-Seidel steps the instances in the plan's order, each seeing its
predecessors' outputs of this step; its pass is cut into levels (the plan's graph's
:attr:`.graph.FeedGraph.levels`, which ``check`` prints: instances of one level do not feed each other)
whose instances step at once, level after level: each level's inputs set, its steps, its outputs read.
What differs from the serial step is only when the steps run.  Three kinds of instance step at once, each
its own way:

* an instance of a C FMU in this process steps in one of N lanes: the master's thread and N - 1 threads
  that live for the run (:class:`~.lanes.Lanes`), its step a foreign call that lets go of the GIL
  (:attr:`~..instances.contract.FastPath.threaded_step`); a group's instances are dealt to the lanes in
  the plan's order, one each in turn, the master's lane first; where steps are too short to pay the
  hand-off, or the cores are busy, the lanes run one after another on the master's thread (which is
  faster is measured as the run goes: :class:`~..instances.handoff.Measured`);
* an instance hosted in a child process (``isolate = true``) steps in two halves: the master writes the
  request to each of up to N children, and waits for their answers after its own lane's steps;
* an instance whose step needs this process's Python (a pythonfmu FMU, a Model Exchange instance) steps
  on the master's thread, after its lane: threads would give it nothing (the GIL), and the run's summary
  says why (``alone``).

Each FMU gets the same calls with the same values in the same order as in the serial run, so the results
are the serial run's bit for bit; of several failures in one group, the one the serial run meets first is
reported.
"""
from __future__ import annotations

import functools
import time
from abc import abstractmethod
from typing import Any, Callable

from ..instances.failure import Call, Failure
from ..instances.handoff import Measured
from .algorithm import Clock, InstanceIO, Row, StepDone
from .lanes import Lanes
from .stepper import SteppedAlgorithm

#: The ways a group's lanes step: in their threads, or one after another on the master's thread.
THREADS, MASTER_ALONE = 0, 1


class Group:
    """Instances that step at once (a Jacobi step's, a Gauss-Seidel level's), sorted by how: ``split``
    (isolated: requested, then answered), ``lanes`` (C FMUs in this process: lane 0 the master's thread),
    ``serial`` (on the master's thread alone), each in the plan's order."""

    def __init__(self, members: list[int], ios: list[InstanceIO], workers: int) -> None:
        self.members = members
        self.split = [i for i in members if ios[i].fast.start_step is not None]
        threaded = [i for i in members if ios[i].fast.threaded_step is not None]
        n = min(workers, len(threaded))
        if n < 2:   # one lane: the master's thread, as the serial run
            threaded = []
        self.threaded = threaded
        self.lanes = [threaded[j::n] for j in range(n)] if threaded else []
        self.serial = [i for i in members if ios[i].fast.start_step is None and i not in threaded]
        self.choice = Measured(2)   # THREADS or MASTER_ALONE


class ParallelStepping(SteppedAlgorithm):
    """The steps of groups of instances overlapping (see the module's docstring); a subclass says the
    groups (:meth:`groups`) and the step (:meth:`take`)."""

    def __init__(self, workers: int = 2) -> None:
        if workers < 1:
            raise ValueError(f"workers: {workers}: must be at least 1")
        self.workers = workers
        self.pool: Lanes | None = None
        self.parts: list[Group] = []

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        super().setup(ios, clock, layout, done, check_inputs)
        self.spent = [0.0] * len(ios)   # [s] wall time from each step's start to its end (overlapping)
        self.walls = 0.0                # [s] wall time of the groups' steps
        self.index = {io.name: i for i, io in enumerate(ios)}
        self._group(ios)

    def _group(self, ios: list[InstanceIO]) -> None:
        """The groups for the instances' connections as they are now; the threads they need."""
        self.parts = [Group(m, ios, self.workers) for m in self.groups(ios)]
        for g in self.parts:
            for i in g.threaded:   # (from now on every step of theirs lets go of the GIL)
                ios[i].fast.do_step = ios[i].fast.threaded_step  # type: ignore[assignment]
        threads = max((len(g.lanes) - 1 for g in self.parts), default=0)
        if self.pool is None or self.pool.n < threads:
            if self.pool is not None:
                self.pool.close()
            self.pool = Lanes(threads) if threads > 0 else None

    @abstractmethod
    def groups(self, ios: list[InstanceIO]) -> list[list[int]]:
        """The groups of instances that step at once, in the order they step."""

    def finish(self) -> None:
        if self.pool is not None:
            self.pool.close()
            self.pool = None

    # ------------------------------------------------------------------ a group's steps
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

    def _first(self, a: Failure | None, b: Failure | None) -> Failure | None:
        """Of two failures of one group's steps, the one of the instance first in the plan."""
        if a is None or (b is not None and self.index[b.instance] < self.index[a.instance]):
            return b
        return a

    def _here(self, g: Group, k: int, t: float, h: float) -> Failure | None:
        """A group's steps in this process: the lanes' (the threads' and the master's) at once, then those on
        the master's thread alone; the failure the serial run would meet first."""
        st, pool = self.stepper, self.pool
        first: Failure | None = None
        if g.lanes:
            way = g.choice.way()
            w0 = time.perf_counter()
            if way == THREADS and pool is not None:
                steps = [[st._parts(i)[1] for i in m] for m in g.lanes]   # (made here: not in the threads)
                for j in range(1, len(g.lanes)):
                    pool.start(j - 1, functools.partial(self._lane, g.lanes[j], k, t, h, steps[j]))
                try:
                    first = self._lane(g.lanes[0], k, t, h, steps[0])
                finally:
                    for j in range(1, len(g.lanes)):   # every lane answered before anything else happens
                        first = self._first(first, pool.wait(j - 1))
            else:   # the lanes one after another on the master's thread, in the plan's order
                first = self._lane(g.threaded, k, t, h, [st._parts(i)[1] for i in g.threaded])
            g.choice.took(way, time.perf_counter() - w0)
            st.n_do_steps += len(g.threaded)
        spent, clock = self.spent, time.perf_counter
        for i in g.serial:
            if first is not None and i > self.index[first.instance]:
                break
            w = clock()
            fail = st.do_step(i, k, t, h)
            spent[i] += clock() - w
            first = self._first(first, fail)
        return first

    def _steps(self, g: Group, k: int, t: float, h: float) -> Failure | None:
        """A group's steps: its isolated instances N children at once, and meanwhile (during the first N)
        the steps in this process (:meth:`_here`); the failure the serial run would meet first."""
        st, ios = self.stepper, self.stepper.ios
        n = self.workers
        first: Failure | None = None
        here_done = False
        clock = time.perf_counter
        spent = self.spent
        w_group = clock()
        for b in range(0, max(1, len(g.split)), n):
            # (after a failure, only the children the serial run steps before it)
            batch = [i for i in g.split[b:b + n] if first is None or i < self.index[first.instance]]
            w0 = clock()
            started: list[int] = []   # the steps requested and not yet answered
            try:
                for i in batch:
                    f = ios[i].fast
                    assert f.start_step is not None
                    f.start_step(f.c, st.T, st.H)
                    started.append(i)
                if not here_done:
                    here_done = True
                    first = self._first(first, self._here(g, k, t, h))
                while started:
                    i = started.pop(0)
                    f = ios[i].fast
                    assert f.finish_step is not None
                    s = f.finish_step(False)
                    spent[i] += clock() - w0
                    st.n_do_steps += 1
                    if s:
                        first = self._first(first, Failure(k, ios[i].name, Call.DO_STEP, s, t))
            except BaseException:   # a child that died, a Ctrl-C: the other steps started are answered first
                self._drain(started)
                raise
        self.walls += clock() - w_group
        return first

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

    def _pass(self, g: Group, k: int, t: float, h: float) -> Failure | None:
        """One group's inputs, steps and outputs; the failure the serial pass over its instances in the
        plan's order (set, step, get each) would meet first."""
        st = self.stepper
        members = g.members
        cut, fail_set = len(members), None
        for n, i in enumerate(members):
            fail_set = st.set_inputs(i, k, t)
            if fail_set is not None:   # the instances before it step and give their outputs first
                cut = n
                break
        stepped = members[:cut]
        fail_step = self._steps(g if cut == len(members) else Group(stepped, st.ios, 1), k, t, h) if stepped else None
        for i in stepped:
            if fail_step is not None and i >= self.index[fail_step.instance]:
                return fail_step
            fail = st.get_outputs(i, k, t + h)
            if fail is not None:
                return fail
        return fail_step or fail_set

    # ------------------------------------------------------------------ the counts
    def summary(self) -> dict[str, Any] | None:
        ios = self.stepper.ios if hasattr(self, "stepper") else []
        names = lambda idx: [ios[i].name for i in idx]   # noqa: E731
        parts = self.parts
        serial = [i for g in parts for i in g.serial]
        busy = sum(getattr(self, "spent", []))
        walls = getattr(self, "walls", 0.0)
        return {"workers": self.workers,
                "stepped_at_once": names(i for g in parts for i in g.split),
                "in_threads": [names(m) for g in parts for m in g.lanes],
                "in_this_process": names(serial),
                "alone": {ios[i].name: ios[i].fast.alone for i in serial if ios[i].fast.alone},
                "steps_in_threads": sum(g.choice.taken[THREADS] for g in parts),
                "steps_on_the_master_alone": sum(g.choice.taken[MASTER_ALONE] for g in parts),
                "step_time_s": {io.name: round(w, 6) for io, w in zip(ios, getattr(self, "spent", []))},
                # the instances' step times over the wall time of the steps: 1 none overlapped, N all N at once
                "overlap": round(busy / walls, 3) if walls > 0.0 else None}


class ParallelJacobi(ParallelStepping):
    """Jacobi, every instance's step overlapping (see the module's docstring)."""

    def groups(self, ios: list[InstanceIO]) -> list[list[int]]:
        return [list(range(len(ios)))]

    def take(self, k: int, t: float, h: float) -> Failure | None:
        st, ios = self.stepper, self.stepper.ios
        for i in range(len(ios)):
            fail = st.set_inputs(i, k, t)
            if fail is not None:
                return fail
        st.T.value, st.H.value = t, h
        g = self.parts[0]
        fail = self._steps(g, k, t, h)
        if fail is not None:
            return fail
        for i in range(len(ios)):
            fail = st.get_outputs(i, k, t + h)
            if fail is not None:
                return fail
        return None


class ParallelGaussSeidel(ParallelStepping):
    """Gauss-Seidel, level by level, the steps of each level's instances overlapping (see the module's
    docstring)."""

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        self.fed_by: list[set[int]] = []
        super().setup(ios, clock, layout, done, check_inputs)

    def groups(self, ios: list[InstanceIO]) -> list[list[int]]:
        graph = self.stepper.graph
        self.fed_by = graph.depends
        return graph.levels

    def inputs_changed(self) -> None:
        """The copies changed (an event, the script): the levels again where who feeds whom changed."""
        super().inputs_changed()
        if self.stepper.graph.depends != self.fed_by:
            self._group(self.stepper.ios)

    def take(self, k: int, t: float, h: float) -> Failure | None:
        st = self.stepper
        st.T.value, st.H.value = t, h
        for g in self.parts:
            fail = self._pass(g, k, t, h)
            if fail is not None:
                return fail
        return None

    def summary(self) -> dict[str, Any] | None:
        own = super().summary()
        assert own is not None
        ios = self.stepper.ios if hasattr(self, "stepper") else []
        return {**own, "levels": [[ios[i].name for i in g.members] for g in self.parts]}
