"""A disturbance pushed when the robot enters a region: a condition event.

The G1 go-to-goal run (20 s).  When point A enters the rectangle 1.2 < x < 2.0, 1.5 < y < 2.5 [m], a
disturbance torque of 1 N.m acts on wheel 1 (plant.tau_d1) for 1 s; the event log says when.  The
same run without the disturbance shows what it did to the path.

    python examples/disturbance_in_region.py
"""
from __future__ import annotations

import numpy as np

from wmr_cosim import Simulation

REGION = "plant.x_A > 1.2 and plant.x_A < 2.0 and plant.y_A > 1.5 and plant.y_A < 2.5"


def main() -> dict:
    base = Simulation.load("g1_learn.toml").experiment(stop=20.0)
    base.document["record"] = {"variables": ["plant.x_A", "plant.y_A", "plant.dF1"]}
    quiet = base.run()

    pushed = Simulation(base.document, file="disturbance_in_region")
    pushed.event(when=REGION, variable="plant.tau_d1", action="override", value=1.0)
    pushed.event(when=REGION, delay=1.0, variable="plant.tau_d1", action="reset")
    result = pushed.run()

    for e in result.events:
        print(f"t = {e['time']:6.3f} s  events[{e['event']}] {e['action']} {e.get('variable', '')} "
              f"{e.get('value', '')}")
    gap = np.hypot(result["plant.x_A"] - quiet["plant.x_A"], result["plant.y_A"] - quiet["plant.y_A"])
    print(f"the disturbance moved the path by up to {gap.max() * 100:.1f} cm; final position "
          f"({result['plant.x_A'][-1]:.3f}, {result['plant.y_A'][-1]:.3f}) m against "
          f"({quiet['plant.x_A'][-1]:.3f}, {quiet['plant.y_A'][-1]:.3f}) m undisturbed")
    return {"quiet": quiet, "pushed": result, "max_gap_m": float(gap.max())}


if __name__ == "__main__":
    main()
