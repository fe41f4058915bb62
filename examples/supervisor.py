"""A supervisor in Python: a per-step callback that switches the goal when the robot enters a region.

The robot first heads for a waypoint W = (1.0, 2.0) m; a callback, called after every step, reads the
position of point A and, once A enters the region y > 0.5 m, sets the controller's goal (a tunable
parameter) to G1 = (2, 5) m.  The same callback also observes: it keeps the closest approach to W.

    python examples/supervisor.py
"""
from __future__ import annotations

import math

from wmr_cosim import Simulation

WAYPOINT = (1.0, 2.0)   # [m]
GOAL = (2.0, 5.0)       # [m]
Y_REGION = 0.5          # [m]: the region y > Y_REGION


def main(stop: float = 40.0) -> dict:
    sim = Simulation.load("g1_learn.toml").experiment(stop=stop)
    sim.parameter("controller.goal_x", WAYPOINT[0]).parameter("controller.goal_y", WAYPOINT[1])
    sim.document["record"] = {"variables": ["plant.x_A", "plant.y_A"]}
    state = {"switched_at": None, "closest_m": math.inf}

    def supervisor(run) -> None:            # a manipulator: changes the goal once
        x, y = run.get("plant.x_A"), run.get("plant.y_A")
        d = math.hypot(x - WAYPOINT[0], y - WAYPOINT[1])
        state["closest_m"] = min(state["closest_m"], d)   # (an observer would only read)
        if state["switched_at"] is None and y > Y_REGION:
            run.set("controller.goal_x", GOAL[0])
            run.set("controller.goal_y", GOAL[1])
            state["switched_at"] = run.time

    result = sim.run(on_step=supervisor)
    x, y = result["plant.x_A"][-1], result["plant.y_A"][-1]
    print(f"goal switched at t = {state['switched_at']:.3f} s (A entered y > {Y_REGION} m); "
          f"final position ({x:.3f}, {y:.3f}) m, {math.hypot(x - GOAL[0], y - GOAL[1]):.3f} m from the goal")
    return {"result": result, **state}


if __name__ == "__main__":
    main()
