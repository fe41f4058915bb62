"""Changing parameters during a run: `set` events and Run.set between steps.

Only parameters the FMU declares tunable can change during a run (FMI 2.0).  In the controller these are
the goal, the adaptation switch and window, and the attenuation gamma; a fixed parameter such as R is
refused before the run starts, in one line (shown below).  First, gamma goes from 11 to 8 at t = 5 s:
the worst-case disturbance player (46) scales as 1/gamma^2, so its ratio to the control changes by
(11/8)^2 from the next sample.

Here the critic learns as in G1 (its weights move from 0.05 around t = 5 s, W1 ending at about 0.084),
but a `set` event switches its adaptation off the first time W1 exceeds 0.07 (the controller's next
sample is its last update), so the weights hold from there; at 15 s the script itself moves the goal,
between two steps.

    python examples/change_during_run.py
"""
from __future__ import annotations

import numpy as np

from wmr_cosim import ScenarioError, Simulation


def gamma_change(stop: float = 6.0) -> dict:
    """dF_hat1 / u1 with gamma set from 11 to 8 at 5 s, and without the change."""
    out: dict = {}
    for name, change in (("with", True), ("without", False)):
        sim = Simulation.load("g1_learn.toml").experiment(stop=stop)
        sim.document["record"] = {"variables": ["controller.u1", "controller.dF_hat1"]}
        if change:
            sim.event(time=5.0, variable="controller.gamma", action="set", value=8.0)
        r = sim.run()
        with np.errstate(divide="ignore", invalid="ignore"):
            out[name] = r["controller.dF_hat1"] / r["controller.u1"]
        out["time"] = r["time"]
    return out


def main(stop: float = 20.0) -> dict:
    g = gamma_change()
    sim = Simulation.load("g1_learn.toml").experiment(stop=stop)
    sim.document["record"] = {"variables": ["plant.x_A", "plant.y_A", "controller.W*"]}
    sim.event(when="controller.W1 > 0.07", variable="controller.adapt", action="set", value=False)

    try:   # R is fixed: refused at check, as `wmr-cosim check` refuses it
        Simulation(sim.document).event(time=5.0, variable="controller.R", action="set", value=8.0).check()
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
    return {"result": result, "refused": refused, "gamma": g}


if __name__ == "__main__":
    main()
