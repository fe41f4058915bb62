"""One macro step over the instances at any time and any step size: what the algorithms that iterate, roll
back and change the step build on (the fixed-step ones generate their whole loop, cosim.stepping.generated).
Each instance's part of a step (its inputs, its step, its outputs) is the generated loop's own code, one
function each (``generated.compile_instance``: one definition of a step's work), so that a pass here gives
the generated Gauss-Seidel or Jacobi step bit for bit.

A :class:`Stepper` knows the instances (their :class:`~.algorithm.InstanceIO`), the row the outputs go to
and who feeds whom (:class:`~.graph.FeedGraph`: the plan's graph, as the execution hands it to the
algorithm, :attr:`~.algorithm.Algorithm.feeds`).  It saves and restores the whole system for a rollback
(:meth:`Stepper.save`, :meth:`Stepper.restore`): the FMU states and the row of outputs the copies read.
"""
from __future__ import annotations

import ctypes
from abc import abstractmethod
from typing import Any, Callable

from ..instances.failure import Call, Failure
from ..messages.errors import RunError
from .algorithm import Algorithm, Clock, InstanceIO, Row, StepDone
from .generated import compile_instance
from .graph import FeedGraph


class Stepper:
    """Steps over the instances one at a time (see the module's docstring)."""

    def __init__(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
                 check_inputs: bool = True, feeds: FeedGraph | None = None) -> None:
        self.ios, self.clock, self.layout, self.done, self.check_inputs = ios, clock, layout, done, check_inputs
        self.feeds = feeds
        self.T, self.H = ctypes.c_double(0.0), ctypes.c_double(0.0)
        self.n_do_steps = 0
        # each instance's functions and the copies they were made for
        self._made: list[tuple[Any, tuple[Callable[..., Failure | None], ...]]] = [(None, ())] * len(ios)

    @property
    def graph(self) -> FeedGraph:
        """Who feeds whom now (:attr:`.algorithm.Algorithm.feeds`, which the execution sets)."""
        if self.feeds is None or self.feeds.names != tuple(io.name for io in self.ios):
            raise RuntimeError("the algorithm was not given the graph of its instances (Algorithm.feeds: the "
                               "execution sets it)")
        return self.feeds

    # ------------------------------------------------------------------ one instance
    def _parts(self, i: int) -> tuple[Callable[..., Failure | None], ...]:
        """Instance i's generated part of a step (:func:`.generated.compile_instance`), made again when its
        copies changed (events, the script: the execution gives every instance a new list)."""
        io = self.ios[i]
        copies, fns = self._made[i]
        if copies is not io.copies:   # a new list: made again only where its copies differ
            if copies != io.copies or not fns:
                fns = compile_instance(i, io, self.T, self.H, self.check_inputs)
            self._made[i] = (io.copies, fns)
        return fns

    def set_inputs(self, i: int, k: int, t: float, given: dict[int, float] | None = None) -> Failure | None:
        """Instance i's inputs of step k (from t [s]): tables, copies (``given``: position -> value in
        place of a copy's), the set, the other connections."""
        return self._parts(i)[0](k, t, given)

    def do_step(self, i: int, k: int, t: float, h: float) -> Failure | None:
        """Instance i from t over h [s]."""
        self.n_do_steps += 1
        return self._parts(i)[1](k, t, h)

    def get_outputs(self, i: int, k: int, t: float) -> Failure | None:
        """Instance i's Float64 outputs at t [s] into the row (a failure counts as after step k)."""
        return self._parts(i)[2](k, t)

    def ended(self, members: list[int] | range | None = None) -> InstanceIO | None:
        """The first of these instances (all: None) that ended the simulation in its last step."""
        for i in (range(len(self.ios)) if members is None else members):
            term = self.ios[i].fast.terminated
            if term is not None and term.value:
                return self.ios[i]
        return None

    # ------------------------------------------------------------------ one pass
    def pass_gauss_seidel(self, k: int, t: float, h: float, members: list[int] | range | None = None
                          ) -> Failure | None:
        """Set, step, get, instance after instance (Gauss-Seidel) over ``members`` (all: None)."""
        for i in (range(len(self.ios)) if members is None else members):
            fail = self.set_inputs(i, k, t) or self.do_step(i, k, t, h) or self.get_outputs(i, k, t + h)
            if fail is not None:
                return fail
        return None

    def pass_jacobi(self, k: int, t: float, h: float, members: list[int] | range | None = None,
                    given: dict[int, dict[int, float]] | None = None) -> Failure | None:
        """Set all, step all, get all (Jacobi) over ``members``; ``given``: instance -> the input values
        that replace copies (the iterated coupling's unknowns)."""
        idx = list(range(len(self.ios)) if members is None else members)
        for i in idx:
            fail = self.set_inputs(i, k, t, given.get(i) if given else None)
            if fail is not None:
                return fail
        for i in idx:
            fail = self.do_step(i, k, t, h)
            if fail is not None:
                return fail
        for i in idx:
            fail = self.get_outputs(i, k, t + h)
            if fail is not None:
                return fail
        return None

    # ------------------------------------------------------------------ the point reached
    def stepped(self, k: int) -> Failure | None:
        """Step k done: the run told that t_{k+1} is reached (the recording takes its row there), as the
        generated loop tells it; then the end of a simulation an FMU ended."""
        ended = self.ended()
        fail = self.done(k + 1, ended is not None)
        if fail is not None:
            return fail
        if ended is not None:
            last = ended.fast.last_time
            return Failure(k + 1, ended.name, Call.TERMINATED,
                           last.value if last is not None else self.clock.time(k + 1))
        return None

    # ------------------------------------------------------------------ rollback
    def allow_rollback(self, members: list[int] | range | None = None) -> None:
        for i in (range(len(self.ios)) if members is None else members):
            fn = self.ios[i].allow_rollback
            if fn is not None:
                fn()

    def save(self, members: list[int] | range | None = None) -> tuple[list[tuple[int, Any]], bytes]:
        """The states of these instances (all: None) and the row's bytes."""
        states = []
        for i in (range(len(self.ios)) if members is None else members):
            io = self.ios[i]
            if not io.can_roll_back or io.get_state is None:
                raise RunError(f"{io.name}: the algorithm rolls steps back, and this instance cannot save its "
                               "state (canGetAndSetFMUstate)", io.name)
            states.append((i, io.get_state()))
        return states, bytes(self.layout.buf)

    def restore(self, saved: tuple[list[tuple[int, Any]], bytes]) -> None:
        """Back to a state :meth:`save` gave (it stays valid)."""
        states, row = saved
        for i, st in states:
            set_state = self.ios[i].set_state
            assert set_state is not None
            set_state(st)
        ctypes.memmove(self.layout.buf, row, len(row))

    def free(self, saved: tuple[list[tuple[int, Any]], bytes]) -> None:
        for i, st in saved[0]:
            free_state = self.ios[i].free_state
            assert free_state is not None
            free_state(st)


class SteppedAlgorithm(Algorithm):
    """A fixed-step algorithm whose steps a :class:`Stepper` takes instance by instance (the iterated coupling,
    instances at their own rates, instances stepped at once): step k, then its row; a subclass gives the
    step (:meth:`take`) and whatever it keeps beside the stepper (:meth:`setup`, calling this one)."""

    def setup(self, ios: list[InstanceIO], clock: Clock, layout: Row, done: StepDone,
              check_inputs: bool = True) -> None:
        self.clock = clock
        self.stepper = Stepper(ios, clock, layout, done, check_inputs, self.feeds)

    def inputs_changed(self) -> None:
        """Who feeds whom as the execution gives it now; nothing else to redo where every step reads the
        copies as they are (a subclass that keeps more redoes it, after this)."""
        self.stepper.feeds = self.feeds

    def advance(self, k0: int, k1: int) -> Failure | None:
        c = self.clock
        for k in range(k0, k1):
            fail = self.take(k, c.time(k), c.length(k)) or self.stepper.stepped(k)
            if fail is not None:
                return fail
        return None

    @abstractmethod
    def take(self, k: int, t: float, h: float) -> Failure | None:
        """Step k, from t [s] over the base step h [s]."""
