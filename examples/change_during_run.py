"""Changing parameters during a run: `set` events and Run.set between steps.

Only parameters the FMU declares tunable can change during a run (FMI 2.0).  In the controller these are
the goal and the adaptation switch and window; the attenuation gamma is a fixed parameter, so a run
that changes gamma is refused before it starts, in one line (shown below).  To compare gammas, run
once per value (examples/monte_carlo_friction.py shows the loop).

Here the critic learns as in G1 (its weights move from 0.05 around t = 5 s, W1 ending at about 0.084),
but a `set` event switches its adaptation off the first time W1 exceeds 0.07 (the controller's next
sample is its last update), so the weights hold from there; at 15 s the script itself moves the goal,
between two steps.

    python examples/change_during_run.py
"""
from __future__ import annotations

import numpy as np

from wmr_cosim import ScenarioError, Simulation


def main(stop: float = 20.0) -> dict:
    sim = Simulation.load("g1_learn.toml").experiment(stop=stop)
    sim.document["record"] = {"variables": ["plant.x_A", "plant.y_A", "controller.W*"]}
    sim.event(when="controller.W1 > 0.07", variable="controller.adapt", action="set", value=False)

    try:   # gamma is fixed: refused at check, as `wmr-cosim check` refuses it
        Simulation(sim.document).event(time=5.0, variable="controller.gamma", action="set", value=8.0).check()
    except ScenarioError as exc:
        print(f"refused: {exc.field}: {exc.reason}")
        refused = exc

    with sim.start() as run:
        run.step_to(15.0)
        run.set("controller.goal_x", 1.5)          # tunable: acts from the next step
        result = run.finish()

    t, w = result["time"], np.column_stack([result[f"controller.W{i}"] for i in (1, 2, 3)])
    t_off = result.events[0]["time"]
    print(f"adaptation switched off at t = {t_off:.3f} s; W = {np.round(w[-1], 4).tolist()} at the end, "
          f"moved by {np.ptp(w[t > t_off + 0.01], axis=0).max():.3g} after that")
    return {"result": result, "refused": refused}


if __name__ == "__main__":
    main()
