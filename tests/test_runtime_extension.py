"""The master's core takes new parts without a change to it: an observer, an algorithm and a manipulator,
each a small class written here (as a user would in a file of their own), used through the public
Execution and the Python API.  System: the Reference FMUs Dahlquist (x' = -k x) -> Feedthrough ->
Feedthrough, 200 steps of 1 ms."""
from __future__ import annotations

import numpy as np
import pytest

from reference_fmus import fmu
from wmr_cosim import Simulation
from wmr_cosim import cosim
from wmr_cosim.cosim.stepping.algorithm import Algorithm
from wmr_cosim.cosim.stepping.generated import GaussSeidel
from wmr_cosim.cosim.instances.failure import Call, Failure
from wmr_cosim.cosim.runtime.manipulators import Manipulator
from wmr_cosim.cosim.runtime.observers import Observer

IN, OUT = "Float64_continuous_input", "Float64_continuous_output"


def _chain(stop: float = 0.2) -> Simulation:
    sim = Simulation(file="chain.toml").experiment(start=0.0, stop=stop, step=0.001)
    sim.instance("d", fmu("fmi2", "Dahlquist")).instance("a", fmu("fmi2", "Feedthrough"))
    sim.instance("b", fmu("fmi2", "Feedthrough"))
    sim.connect("d.x", f"a.{IN}").connect(f"a.{OUT}", f"b.{IN}")
    return sim.record("d.x", f"a.{OUT}", f"b.{OUT}", csv=False)


class StepCounter(Observer):
    """Counts the steps it sees and notes the times (an observer that must see every step)."""

    per_step = True

    def __init__(self) -> None:
        self.steps, self.times = 0, []

    def stepped(self, ex, k: int) -> None:
        self.steps += 1
        self.times.append(ex.time)


def test_an_observer_registered_from_the_api_sees_every_step_and_changes_nothing():
    quiet = _chain().run()
    counter = StepCounter()
    with _chain().start() as run:
        run.execution.add_observer(counter)
        run.step_to(0.05)
        assert counter.steps == 50 and counter.times[-1] == pytest.approx(0.05)
        r = run.finish()
    assert counter.steps == 200 and counter.times == [pytest.approx(k * 0.001) for k in range(1, 201)]
    assert np.array_equal(r.signals, quiet.signals)


class BoundaryWatcher(Observer):
    """An observer that needs the run only at every 64th step: the loop runs uninterrupted in between."""

    def __init__(self) -> None:
        self.seen: list[int] = []

    def boundary(self, k: int) -> int:
        return (k // 64 + 1) * 64

    def stepped(self, ex, k: int) -> None:
        self.seen.append(k)


def test_an_observer_is_called_where_it_asks_and_at_the_end():
    w = BoundaryWatcher()
    with cosim.Execution(_chain().check()) as ex:
        ex.add_observer(w)
        ex.initialize()
        assert ex.simulate_until() == "ok"
    assert w.seen == [64, 128, 192, 200]


class ReversedJacobi(Algorithm):
    """Jacobi written from scratch, not generated, the instances taken last to first: a plain loop over the
    instances' fast paths (the algorithm interface's contract, items 2 and 3)."""

    name = "reversed-jacobi"

    def setup(self, ios, clock, layout, done, check_inputs=True):
        self.ios, self.clock, self.done = list(reversed(ios)), clock, done
        import ctypes
        self.T, self.H = ctypes.c_double(0.0), ctypes.c_double(clock.step)

    def inputs_changed(self):
        pass

    def advance(self, k0, k1):
        c = self.clock
        for k in range(k0, k1):
            self.T.value = c.time(k)
            for io in self.ios:
                for pos, arr, i, f, o in io.copies:
                    io.in_val[pos] = arr[i] * f + o
                if io.copies and io.set_inputs():
                    return Failure(k, io.name, Call.SET_REAL, 3)
            for io in self.ios:
                fp = io.fast
                s = fp.do_step(fp.c, self.T, self.H, *fp.step_tail)
                if s:
                    return Failure(k, io.name, Call.DO_STEP, s)
            for io in self.ios:
                if io.n_out.value and io.get_outputs():
                    return Failure(k + 1, io.name, Call.GET_REAL, 3)
            fail = self.done(k + 1, False)   # (the recording takes the row where it records one)
            if fail is not None:
                return fail
        return None


def test_a_new_algorithm_in_one_class_equals_the_built_in_one_of_the_same_order_of_work():
    """Jacobi's order of instances does not matter (every input from the previous step): the hand-written
    reversed Jacobi equals the generated Jacobi bit for bit, and differs from Gauss-Seidel."""
    jac = _chain().experiment(algorithm="jacobi")
    ours = cosim.run(jac.check(), None, algorithm=ReversedJacobi())
    built_in = cosim.run(jac.check(), None)
    gs = cosim.run(_chain().check(), None, algorithm=GaussSeidel())
    assert ours.status == built_in.status == "ok" and ours.steps == 200
    assert ours.final == built_in.final
    assert ours.final["b." + OUT] != gs.final["b." + OUT]        # Jacobi lags two steps behind d.x
    assert gs.final["b." + OUT] == gs.final["d.x"]


class Holder(Manipulator):
    """Holds a's input at 0.5 from step 100 on, through the execution's public set."""

    def next_action(self, k: int):
        return 100 if k <= 100 else None

    def act(self, ex, k: int) -> bool:
        if k == 100:
            ex.set(f"a.{IN}", 0.5)
        return False


def test_a_new_manipulator_acts_where_it_says():
    """The override of a's connected input from t = 0.1 s equals the same override as a timed event."""
    with cosim.Execution(_chain().check()) as ex:
        ex.initialize()
        ex.add_manipulator(Holder())
        ex.simulate_until()
        ours = ex.close()
    sim = _chain()
    sim.event(time=0.1, variable=f"a.{IN}", action="override", value=0.5)
    timed = cosim.run(sim.check(), None)
    assert ours.status == "ok" and ours.final == timed.final and ours.final[f"b.{OUT}"] == 0.5


class Prober(Observer, Manipulator):
    """Notes what each kind of part is given, and what of the run it can reach."""

    def __init__(self) -> None:
        self.seen: dict[str, set[str]] = {}

    def _note(self, kind: str, view) -> None:
        self.seen[kind] = {n for n in ("clock", "time", "get", "reader", "set", "release", "stop", "access",
                                       "instances", "plan", "algorithm", "add_observer", "close")
                           if hasattr(view, n)}

    def stepped(self, ex, k: int) -> None:
        self._note("observer", ex)

    def act(self, ex, k: int) -> bool:
        self._note("manipulator", ex)
        return False


def test_observers_and_manipulators_see_narrow_views_of_the_run():
    """An observer reads (the grid, the time, values); a manipulator reads and changes variables and may end
    the run; neither reaches the execution's instances, plan, algorithm or its other parts."""
    obs, man = Prober(), Prober()
    with cosim.Execution(_chain().check()) as ex:
        ex.add_observer(obs)
        ex.add_manipulator(man)
        ex.initialize()
        ex.step(3)
    assert obs.seen["observer"] == {"clock", "time", "get"}
    assert man.seen["manipulator"] == {"clock", "time", "get", "reader", "set", "release", "stop"}
