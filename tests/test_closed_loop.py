"""The direct loop against the paper: the G1 learning run, and determinism."""
import math

import numpy as np
import pytest

from wmr_cosim.components import paper
from wmr_cosim.components.direct_loop import run_direct
from wmr_cosim.components.metrics import rmse, run_metrics


@pytest.fixture(scope="module")
def g1():
    return run_direct(t_stop=50.0, h=0.002)


def test_g1_learning_run_reaches_the_goal(g1):
    assert g1.status == "ok"
    assert len(g1.signals["time"]) == 25001
    x, y = g1.signals["plant.x_A"][-1], g1.signals["plant.y_A"][-1]   # the true pose of A
    assert math.hypot(x - 2.0, y - 5.0) <= paper.table1()["eps_G"]


def test_g1_rmse_within_factor_1_5_of_table_2(g1):
    m = run_metrics(g1.signals, (2.0, 5.0))
    ours = m["rmse_e"] + m["rmse_edot"]
    ref = paper.rmse_table("G1")["learn"]
    for name, o, p in zip(("e1", "e2", "edot1", "edot2"), ours, ref):
        assert 1 / 1.5 <= o / p <= 1.5, f"{name}: ours {o:.4f}, paper {p:.4f}"
    assert rmse(g1.signals["controller.e1"]) == pytest.approx(m["rmse_e"][0])


def test_g1_cruising_control_near_4_Nm(g1):
    t = g1.signals["time"]
    cruise = (t > 6) & (t < 12)   # v_A = v* until the planner slows down near G
    u = 0.5 * (g1.signals["controller.u1"] + g1.signals["controller.u2"])[cruise]
    assert 3.5 < float(np.median(u)) < 4.8
    # dF_hat is R/gamma^2 = 1/242 of u (the paper: "250 times lower")
    ratio = g1.signals["controller.u1"][cruise] / g1.signals["controller.dF_hat1"][cruise]
    assert np.allclose(ratio, 242.0)


def test_runs_are_bit_identical():
    a = run_direct(t_stop=6.0)
    b = run_direct(t_stop=6.0)
    for k in a.signals:
        assert np.array_equal(a.signals[k], b.signals[k]), k


def test_disturbance_input_reaches_the_plant():
    r = run_direct(t_stop=12.0, disturbance=lambda t: (0.3, 0.3) if t >= 9.0 else (0.0, 0.0))
    dF = r.signals["plant.dF1"]
    t = r.signals["time"]
    assert np.all(dF[t <= 9.0] == 0.0) and np.all(dF[t > 9.0 + 1e-9] == 0.3)


def test_foam_raises_cruise_control_by_about_0_4():
    from wmr_cosim.components.plant import PlantParams
    ref = run_direct(t_stop=20.0)
    foam = run_direct(plant=PlantParams(foam_on_time=True, foam_t_on=8.38, foam_da1=0.4, foam_da2=0.4),
                      t_stop=20.0)
    t = ref.signals["time"]
    w = (t > 9) & (t < 12)
    du = (foam.signals["controller.u1"] - ref.signals["controller.u1"])[w]
    assert 0.3 < float(np.mean(du)) < 0.5
