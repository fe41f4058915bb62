"""The table figures against hand computation."""
import math

import numpy as np

from wmr_cosim.components.metrics import rmse, run_metrics


def test_rmse_is_over_every_sample():
    assert rmse(np.array([3.0, 4.0, 0.0])) == math.sqrt(25.0 / 3.0)   # dropping a sample changes it
    assert rmse(np.array([2.0])) == 2.0


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
