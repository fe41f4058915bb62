"""The table figures against hand computation."""
import math

import numpy as np

from wmr_cosim.components.metrics import rmse, run_metrics


def test_rmse_is_over_every_sample():
    assert rmse(np.array([3.0, 4.0, 0.0])) == math.sqrt(25.0 / 3.0)   # dropping a sample changes it
    assert rmse(np.array([2.0])) == 2.0


def test_rmse_of_integer_samples_does_not_overflow():
    """Samples of an integer type (a counter) are squared as reals: 4e9^2 overflows int64."""
    assert rmse(np.array([4_000_000_000, 0], dtype=np.int64)) == 4e9 / math.sqrt(2.0)
    assert rmse([3, 4]) == math.sqrt(12.5)


def test_run_metrics_by_hand():
    n = 5
    sig = {"controller.e1": np.array([1.0, -1.0, 1.0, -1.0, 0.5]), "controller.e2": np.zeros(n),
           "controller.edot1": np.array([0.0, 0.0, 0.0, 0.0, 2.0]), "controller.edot2": np.ones(n),
           "controller.t_goal": np.array([-1.0] * 4 + [3.5]), "plant.x_A": np.arange(n) * 0.5,
           "plant.y_A": np.arange(n) * 1.0, "controller.W1": np.ones(n), "controller.W2": np.ones(n) * 2,
           "controller.W3": np.ones(n) * 3}
    m = run_metrics(sig, goal=(2.0, 4.0))
    assert m["rmse_e"] == [math.sqrt(4.25 / 5), 0.0] and m["rmse_edot"] == [math.sqrt(4.0 / 5), 1.0]
    assert m["final_position"] == [2.0, 4.0] and m["goal_distance"] == 0.0 and m["t_goal"] == 3.5
    assert m["final_W"] == [1.0, 2.0, 3.0] and not m["diverged"]


def _signals(e1, e2):
    n = len(e1)
    z = np.zeros(n)
    return {"controller.e1": np.array(e1), "controller.e2": np.array(e2), "controller.edot1": z,
            "controller.edot2": z, "controller.t_goal": -np.ones(n), "plant.x_A": z, "plant.y_A": z,
            "controller.W1": z, "controller.W2": z, "controller.W3": z}


def test_goal_time_final_weights_and_goal_distance_read_the_last_samples():
    """t_goal: the controller's goal time at the end (0 included) if the run has a goal and reached it;
    final W: the last sample of each weight; the distance to the goal from the final position, both axes."""
    sig = _signals([0.0] * 4, [0.0] * 4)
    sig["controller.t_goal"] = np.array([-1.0, -1.0, 0.0, 0.0])
    sig["controller.W1"] = np.array([5.0, 6.0, 7.0, 1.5])
    sig["controller.W2"] = np.array([5.0, 6.0, 7.0, 2.5])
    sig["controller.W3"] = np.array([5.0, 6.0, 7.0, 3.5])
    sig["plant.x_A"] = np.array([9.0, 9.0, 9.0, 1.0])
    sig["plant.y_A"] = np.array([9.0, 9.0, 9.0, 2.0])
    m = run_metrics(sig, goal=(4.0, 6.0))
    assert m["t_goal"] == 0.0 and m["final_W"] == [1.5, 2.5, 3.5]
    assert m["final_position"] == [1.0, 2.0] and m["goal_distance"] == 5.0
    sig["controller.t_goal"] = np.array([-1.0, -1.0, -1.0, 0.5])
    assert run_metrics(sig, goal=(4.0, 6.0))["t_goal"] == 0.5
    m = run_metrics(sig)                                   # no goal (the LINE): no goal time, no distance
    assert m["t_goal"] is None and "goal_distance" not in m
    sig["controller.t_goal"] = -np.ones(4)                 # never reached
    assert run_metrics(sig, goal=(4.0, 6.0))["t_goal"] is None


def test_rmse_of_a_diverged_run_is_inf_without_a_warning():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert rmse(np.array([1e200, 0.0])) == math.inf


def test_diverged_reads_the_last_sample_of_each_error():
    """'diverged' is |e_i| > 1 rad at the end: large errors before the last sample do not count, a large
    last sample of either wheel does; a non-finite value anywhere does."""
    big_early = [0.0, 3.0, 0.0, 3.0, 0.2]
    assert not run_metrics(_signals(big_early, [0.0] * 5))["diverged"]
    assert not run_metrics(_signals([0.0] * 5, big_early))["diverged"]
    assert run_metrics(_signals([0.0, 0.0, 0.0, 0.0, -1.5], [0.0] * 5))["diverged"]
    assert run_metrics(_signals([0.0] * 5, [0.0, 0.0, 0.0, 0.0, 1.01]))["diverged"]
    assert not run_metrics(_signals([0.0] * 5, [0.0, 0.0, 0.0, 0.0, 1.0]))["diverged"]
    assert run_metrics(_signals([0.0, math.nan, 0.0, 0.0, 0.0], [0.0] * 5))["diverged"]
