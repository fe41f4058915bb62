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
