"""Discrete-time models from pulse responses taken with rollback (cosim/linearisation/realisation.py and
the execution's saved points): the C plant as a co-simulation FMU against the zero-order-hold
discretisation (python-control's c2d) of its Model Exchange linearisation; the realisation against
known systems; going back to a point repeats the run bit for bit; what cannot go back is refused."""
from __future__ import annotations


import control
import numpy as np
import pytest

from wmr_cosim.api import Simulation
from wmr_cosim.cosim import CosimError, Execution, Linearizer, Request
from wmr_cosim.cosim.linearisation.realisation import realise

H_STEP = 0.002
INPUTS = ["plant.torque_right", "plant.torque_left"]
OUTPUTS = ["plant.omega_right", "plant.omega_left"]


def _plant(interface: str, **parameters) -> Simulation:
    return Simulation().instance("plant", "WmrCPlant", fields={"interface": interface}, torque_right=0.5,
                                 torque_left=0.4, **parameters).experiment(start=0.0, stop=5.0, step=H_STEP)


def _markov(A: np.ndarray, B: np.ndarray, C: np.ndarray, n: int) -> np.ndarray:
    """h[1..n] = C A^(k-1) B."""
    out, Ak = [], np.eye(len(A))
    for _ in range(n):
        out.append(C @ Ak @ B)
        Ak = Ak @ A
    return np.array(out)


def test_the_c_plant_by_rollback_is_the_zoh_discretisation_of_its_model_exchange_linearisation():
    """At t = 4 s under constant torques the wheels run at their steady speeds (the wheel dynamics' time
    constant is about 0.15 s): the point is an equilibrium of the speeds, so the responses are those of
    one linear system."""
    me = Linearizer(_plant("model-exchange").check(), Request(at=4.0, inputs=INPUTS, outputs=OUTPUTS)).run().model
    zoh = control.c2d(me.statespace(), H_STEP, "zoh")
    cs = Linearizer(_plant("co-simulation", rk4_substeps=20).check(),
                    Request(at=4.0, inputs=INPUTS, outputs=OUTPUTS, steps=100)).run().model
    assert cs.dt == H_STEP and len(cs.states) == 2   # the speeds: the angles, position, heading are unseen
    assert cs.method == "eigensystem realisation of order 2 from pulse responses of 100 steps"
    assert cs.singular_values[2] < 1e-6 * cs.singular_values[0]
    np.testing.assert_array_equal(cs.D, np.zeros((2, 2)))   # an input set at t_k shows at t_k+1 at the earliest
    h_zoh, h_cs = _markov(zoh.A, zoh.B, zoh.C, 200), _markov(cs.A, cs.B, cs.C, 200)
    assert np.abs(h_cs - h_zoh).max() <= 1e-6 * np.abs(h_zoh).max()
    speeds = np.sort(np.linalg.eigvals(zoh.A))[:2]   # (the others are the integrators' 1)
    np.testing.assert_allclose(np.sort(cs.eigenvalues().real), speeds.real, rtol=1e-7)


def test_the_realisation_recovers_a_known_system_and_its_order():
    sysd = control.c2d(control.ss([[-1.0, 0.5], [0.0, -2.0]], [[1.0], [1.0]], [[1.0, 0.0]], [[0.0]]), 0.1, "zoh")
    n = 40
    H = np.zeros((1, 1, n + 1))
    H[0, 0, 1:] = _markov(sysd.A, sysd.B, sysd.C, n)[:, 0, 0]
    m = realise(H, 0.1, ["u"], ["y"])
    assert len(m.states) == 2 and m.dt == 0.1
    np.testing.assert_allclose(np.sort(m.eigenvalues().real), np.sort(np.linalg.eigvals(sysd.A)), rtol=1e-9)
    np.testing.assert_allclose(_markov(m.A, m.B, m.C, n)[:, 0, 0], H[0, 0, 1:], rtol=1e-9, atol=1e-14)
    assert len(realise(H, 0.1, ["u"], ["y"], order=1).states) == 1
    with pytest.raises(CosimError, match="more than"):
        realise(H, 0.1, ["u"], ["y"], order=25)


def _execution(sim: Simulation) -> Execution:
    ex = Execution(sim.check(), None)
    ex.initialize()
    return ex


def test_going_back_to_a_saved_point_repeats_the_run_bit_for_bit():
    ex = _execution(_plant("co-simulation"))
    try:
        ex.step_to(0.5)
        point = ex.save_point()
        ex.set("plant.torque_right", 0.9)
        ex.step(50)
        first = [ex.get(r) for r in OUTPUTS + ["plant.pos_x"]]
        ex.restore_point(point)
        assert ex.time == 0.5
        ex.set("plant.torque_right", 0.9)
        ex.step(50)
        assert [ex.get(r) for r in OUTPUTS + ["plant.pos_x"]] == first
        ex.restore_point(point)
        ex.step(50)   # without the change: another trajectory
        assert [ex.get(r) for r in OUTPUTS + ["plant.pos_x"]] != first
        ex.free_point(point)
    finally:
        ex.close()


def test_a_bias_adds_to_what_a_connection_carries_until_released():
    """a's applied disturbance (its input dist_right, 0.3 N.m) drives b's right torque."""
    sim = Simulation().instance("a", "WmrCPlant", dist_right=0.3).instance("b", "WmrCPlant") \
        .connect("a.dist_total_right", "b.torque_right").experiment(start=0.0, stop=1.0, step=H_STEP)
    ex = _execution(sim)
    try:
        ex.step(5)
        assert ex.get("b.torque_right") == 0.3
        ex.bias("b.torque_right", 0.25)
        ex.bias("b.torque_right", 0.125)   # biases add up
        ex.step(1)
        assert ex.get("b.torque_right") == 0.3 + 0.375
        ex.release("b.torque_right")
        ex.step(1)
        assert ex.get("b.torque_right") == 0.3
        with pytest.raises(CosimError, match="no Real input or output on a connection"):
            ex.bias("a.torque_left", 1.0)
    finally:
        ex.close()


def test_what_cannot_go_back_is_refused(tmp_path):
    ex = Execution(_plant("co-simulation").check(), tmp_path / "out")
    ex.initialize()
    try:
        with pytest.raises(CosimError, match="results folder"):
            ex.save_point()
    finally:
        ex.close()
    sim = _plant("co-simulation").experiment(algorithm="iterated")
    ex = _execution(sim)
    try:
        with pytest.raises(CosimError, match="keeps more than the outputs"):
            ex.save_point()
    finally:
        ex.close()
    sim = _plant("co-simulation").require("fast", "always plant.omega_right < 1e6 rpm")
    plan = sim.check()
    ex = Execution(plan, None)
    ex.initialize()
    try:
        with pytest.raises(CosimError, match="condition events, requirements"):
            ex.save_point()
    finally:
        ex.close()


def test_the_end_of_the_run_frees_the_saved_states_before_the_instances():
    """A point still saved when the run ends (a failure in the responses ends it): each instance's state is
    freed while the instance lives, then the instance; freeing the point after is a no-op, restoring it
    refused."""
    ex = _execution(_plant("co-simulation"))
    calls: list[str] = []
    inst = ex.instances["plant"]
    free_state, shutdown = inst.free_state, inst.shutdown
    inst.free_state = lambda st: (calls.append("free_state"), free_state(st))[1]   # type: ignore[method-assign]
    inst.shutdown = lambda: (calls.append("shutdown"), shutdown())[1]               # type: ignore[method-assign]
    ex.step(5)
    point = ex.save_point()
    ex.step(5)
    ex.close()
    assert calls == ["free_state", "shutdown"]
    ex.free_point(point)
    assert calls == ["free_state", "shutdown"] and point.states == {}


def test_freeing_a_point_after_the_run_ended_does_not_call_into_the_freed_fmu():
    """fmi2FreeFMUstate after fmi2FreeInstance called into the library FMPy had unloaded: a segmentation
    fault (in a shell, so that a crash shows as the return code)."""
    import subprocess
    import sys

    script = ("from wmr_cosim.api import Simulation\nfrom wmr_cosim.cosim import CosimError, Execution\n"
              "sim = Simulation().instance('plant', 'WmrCPlant', fields={'interface': 'co-simulation'})"
              ".experiment(start=0.0, stop=1.0, step=0.002)\n"
              "ex = Execution(sim.check(), None)\nex.initialize()\nex.step(5)\npoint = ex.save_point()\nex.step(5)\n"
              "ex.close()\nex.free_point(point)\n"
              "try:\n    ex.restore_point(point)\nexcept CosimError as exc:\n    print('refused:', exc)\n")
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, (p.returncode, p.stderr[-3000:])
    assert "refused: the run has ended" in p.stdout, p.stdout
