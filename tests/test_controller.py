"""The controller: odometry, desired motion, adaptation window and the decisions of (51)."""
import math

import numpy as np
import pytest

from wmr_cosim.components import paper
from wmr_cosim.components.controller import CONTROLLER_OUTPUTS, Controller, ControllerParams
from wmr_cosim.components.direct_loop import run_direct
from wmr_cosim.components.planner import profile, profile_integral
from wmr_cosim.components.plant import Plant

IDX = {n: i for i, n in enumerate(CONTROLLER_OUTPUTS)}


def test_odometry_follows_the_true_pose_with_perfect_measurements():
    pl = Plant()
    c = Controller()
    c.reset(0.0, 0.0, 0.0, 0.0, 0.0)
    h = 0.002
    for k in range(5000):
        out = pl.step(k * h, h, 4.5 + math.sin(k * h), 4.2)
        co = c.step((k + 1) * h, h, out[0], out[1], out[2], out[3])
    x, y, b = co[IDX["x_hat"]], co[IDX["y_hat"]], co[IDX["beta_hat"]]
    assert math.hypot(x - out[4], y - out[5]) < 1e-5
    assert b == pytest.approx(out[6], abs=1e-9)   # heading is linear in the angles: exact


def test_line_task_desired_motion_is_the_closed_form():
    c = Controller(**paper.task_controller("LINE"))
    v_r = 0.4 / paper.WHEEL_RADIUS_M
    for t in (0.5, 5.0, 9.0, 15.0, 20.0):
        co = c.step(t, 0.002, 0.0, 0.0, 0.0, 0.0)
        assert co[IDX["alpha_dot_d1"]] == co[IDX["alpha_dot_d2"]] == pytest.approx(v_r * profile(t, 5, 15, 10))
        assert co[IDX["alpha_d1"]] == pytest.approx(v_r * profile_integral(t, 5, 15, 10))
        assert co[IDX["beta_dot_d"]] == 0.0


def test_goal_reached_sets_braking_time():
    r = run_direct(t_stop=50.0)
    sig = r.signals
    tg = sig["controller.t_goal"][-1]
    assert 35.0 < tg < 45.0
    t = sig["time"]
    prof = sig["controller.profile"]
    # (50) with b2 = t_G + 1: the profile is 1/2 (minus the start term) at t_G + 1 and 0 later
    k = int(round((tg + 1.0) / 0.002))
    assert prof[k] == pytest.approx(profile(t[k], 5.0, tg + 1.0, 10.0), rel=1e-12)
    assert prof[-1] < 1e-20


@pytest.fixture(scope="module")
def g1_runs():
    # the default reading, and the printed one: (51) with the Frobenius norm, stopping only P
    return {True: run_direct(t_stop=50.0).signals,
            False: run_direct(controller=ControllerParams(freeze_w_with_p=False, p_norm="frobenius"),
                              t_stop=50.0).signals}


def test_default_stops_W_once_P_has_collapsed(g1_runs):
    """Decisions 17-18: once the smallest eigenvalue of P has fallen to P0, W and P stop adapting."""
    sig = g1_runs[True]
    pn = sig["controller.P_norm"]
    collapsed = np.nonzero(pn <= paper.table1()["P0"])[0]
    assert collapsed.size, "P never collapsed"
    k0 = collapsed[0]
    t0 = sig["time"][k0]
    assert 4.0 < t0 < 8.0  # during the acceleration phase (b1 = 5 s)
    W = np.stack([sig[f"controller.W{i}"] for i in (1, 2, 3)], axis=1)
    assert np.all(W[k0 + 1:] == W[k0 + 1])             # constant afterwards
    assert np.any(W[k0] != W[0])                       # it did adapt before
    assert np.all(sig["controller.adapting"][k0 + 1:] == 0.0)


def test_printed_reading_keeps_adapting_W_in_the_window(g1_runs):
    sig = g1_runs[False]
    t = sig["time"]
    assert t[-1] == 50.0
    W1 = sig["controller.W1"]
    late = (t > 20.0) & (t < 38.0)
    assert np.ptp(W1[late]) > 0.0
    after = t > 39.01
    assert np.ptp(W1[after]) == 0.0                    # adaptation window 0-39 s


def test_no_adaptation_keeps_initial_weights():
    W0 = (0.09, 0.07, 0.08)
    r = run_direct(controller=ControllerParams(adapt=False, W_init=W0), t_stop=10.0)
    for i in (1, 2, 3):
        assert np.all(r.signals[f"controller.W{i}"] == W0[i - 1])


def test_frozen_runs_with_learned_weights_reach_the_goal(g1_runs):
    sig = g1_runs[True]
    W = tuple(float(sig[f"controller.W{i}"][-1]) for i in (1, 2, 3))
    P = tuple(float(sig[f"controller.P{n}"][-1]) for n in ("11", "12", "13", "22", "23", "33"))
    r = run_direct(controller=ControllerParams(adapt=False, W_init=W, P_init=P), t_stop=50.0)
    x, y = r.signals["plant.x_A"][-1], r.signals["plant.y_A"][-1]
    assert math.hypot(x - 2, y - 5) < 0.03


def test_printed_player_sign_diverges():
    """Decision 1: (46) as printed is positive feedback."""
    r = run_direct(controller=ControllerParams(player_form="printed"), t_stop=10.0)
    e = np.abs(r.signals["controller.e1"])
    assert r.status == "diverged" or e[-1] > 1.0


def test_state_round_trip_is_exact():
    c = Controller()
    c.reset(0.0, 0.0, 0.0, 0.0, 0.0)
    h = 0.002
    meas = [(0.01 * k * k * h, 0.009 * k * k * h, 0.02 * k * h, 0.018 * k * h) for k in range(2000)]
    for k in range(1, 1000):
        c.step(k * h, h, *meas[k])
    s = c.get_state()
    a = [c.step(k * h, h, *meas[k]) for k in range(1000, 2000)]
    c.set_state(s)
    assert [c.step(k * h, h, *meas[k]) for k in range(1000, 2000)] == a


def test_adaptation_stops_when_the_norm_of_P_equals_P0():
    """(51) adapts while the norm of P is above P0: at exactly P0 nothing adapts (W and P both frozen,
    decision 18); a hair below P(0)'s norm, the first step adapts."""
    p_init = ControllerParams().P_init[0]   # P(0) = p I: its smallest eigenvalue is p
    at = run_direct(controller=ControllerParams(P0=p_init), t_stop=0.1)
    below = run_direct(controller=ControllerParams(P0=p_init * (1 - 1e-12)), t_stop=0.1)
    assert at.signals["controller.P_norm"][0] == p_init
    assert np.all(at.signals["controller.adapting"] == 0.0)
    assert below.signals["controller.adapting"][0] == 1.0
    W0 = ControllerParams().W_init
    for i in (1, 2, 3):
        assert np.all(at.signals[f"controller.W{i}"] == W0[i - 1])


@pytest.mark.parametrize("form", [dict(), dict(player_form="printed", player_gamma_power=1),
                                  dict(h_state_cost_sign=-1.0, h_gamma_power=1, Q=2.0, R=0.25)])
def test_retune_equals_a_controller_built_with_the_new_parameters(form):
    """retune recomputes the gains of the players (46) and the Hamiltonian's weights (49) from every
    parameter they depend on (R, Q, gamma, the forms and powers), as a new controller would have them."""
    base = ControllerParams(**form)
    new = ControllerParams(**{**base.as_dict(), "gamma": 8.0})
    c = Controller(base)
    before = (c._ku, c._kd, c._hq, c._hg)
    c.retune(new)
    fresh = Controller(new)
    assert (c._ku, c._kd, c._hq, c._hg) == (fresh._ku, fresh._kd, fresh._hq, fresh._hg)
    assert (c._ku, c._kd, c._hq, c._hg) != before and c.p is new


def test_state_restored_into_a_new_controller_continues_the_run_on_the_line():
    """A state taken while the LINE profile (50) runs (its stop time b2 is finite) restored into a fresh
    controller continues exactly as the original, past b2."""
    p = ControllerParams(task="line", b1=0.1, line_b2=0.5, c=10.0)
    h = 0.002
    meas = [(0.01 * k * k * h, 0.009 * k * k * h, 0.02 * k * h, 0.018 * k * h) for k in range(600)]
    c = Controller(p)
    c.reset(0.0, 0.0, 0.0, 0.0, 0.0)
    for k in range(1, 150):
        c.step(k * h, h, *meas[k])
    s = c.get_state()
    rest = [c.step(k * h, h, *meas[k]) for k in range(150, 600)]
    other = Controller(p)
    other.reset(0.0, 1.0, 1.0, 1.0, 1.0)
    other.set_state(s)
    assert list(other.outputs()) == s["out"]
    assert [other.step(k * h, h, *meas[k]) for k in range(150, 600)] == rest


def test_state_before_the_first_step_restored_into_a_controller_that_has_run():
    """The state of a go-to-goal controller right after reset (no profile stop time: b2 = inf, kept as
    None so the state is plain JSON) restored into one that has run continues as the original."""
    import json

    p = ControllerParams(**paper.task_controller("G1"))
    h = 0.002
    meas = [(0.01 * k * k * h, 0.009 * k * k * h, 0.02 * k * h, 0.018 * k * h) for k in range(200)]
    c = Controller(p)
    c.reset(0.0, 0.0, 0.0, 0.0, 0.0)
    s = c.get_state()
    assert s["b2"] is None
    assert json.loads(json.dumps(s, allow_nan=False)) == s
    rest = [c.step(k * h, h, *meas[k]) for k in range(1, 200)]
    other = Controller(p)
    other.reset(0.0, 0.0, 0.0, 0.0, 0.0)
    for k in range(1, 50):
        other.step(k * h, h, *meas[k])
    other.set_state(json.loads(json.dumps(s)))
    assert other.get_state() == s
    assert [other.step(k * h, h, *meas[k]) for k in range(1, 200)] == rest


def test_task_controller_gives_each_goal_of_table1_and_refuses_an_unknown_task():
    goals = paper.table1()["goals"]
    for task in ("G1", "G2", "G3"):
        assert paper.task_controller(task) == {"task": "goal", "goal_x": float(goals[task][0]),
                                               "goal_y": float(goals[task][1])}
        assert ControllerParams(**paper.task_controller(task)).goal_x == float(goals[task][0])
    assert paper.task_controller("LINE")["task"] == "line"
    with pytest.raises(KeyError, match="unknown task 'G4': one of G1, G2, G3, LINE"):
        paper.task_controller("G4")


def test_a_normalised_regressor_is_divided_by_one_plus_its_squared_norm():
    """sigma1 = 'normalised': sigma / (1 + sigma' sigma) goes to (51) instead of sigma."""
    h = 0.002
    meas = [(0.01 * k * k * h, 0.009 * k * k * h, 0.02 * k * h, 0.018 * k * h) for k in range(40)]
    pending = {}
    for form in ("sigma", "normalised"):
        c = Controller(ControllerParams(sigma1=form, adapt=False))   # (the same W: the same sigma)
        c.reset(0.0, 0.0, 0.0, 0.0, 0.0)
        for k in range(1, 40):
            c.step(k * h, h, *meas[k])
        pending[form] = c.pending
    sg = pending["sigma"][:3]
    nn = 1.0 + sum(v * v for v in sg)
    assert abs(sg[1]) > 1e-6 and abs(sg[0]) > 1e-6 and abs(sg[2]) > 1e-6
    assert pending["normalised"][:3] == pytest.approx([v / nn for v in sg], rel=1e-12)
    assert pending["normalised"][3:] == pending["sigma"][3:]


def test_task_goal_is_the_goal_of_table1_and_none_for_the_line():
    assert paper.task_goal("G1") == (2.0, 5.0) and paper.task_goal("G2") == (2.0, -3.0)
    assert paper.task_goal("G3") == (4.0, 0.0) and all(type(v) is float for v in paper.task_goal("G3"))
    assert paper.task_goal("LINE") is None
    with pytest.raises(KeyError, match="unknown task 'line'"):
        paper.task_goal("line")


def test_direct_loop_defaults_to_the_papers_50_s_and_names_itself_in_a_bad_step():
    from wmr_cosim.components.validation import ParameterError

    assert run_direct(record=False).steps == 25_000
    with pytest.raises(ParameterError, match=r"^direct loop: step size h = 0\.0 s: must be finite and > 0$"):
        run_direct(h=0.0)
