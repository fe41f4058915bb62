"""A Monte Carlo study in plain Python: the friction change (the foam's rise of a5, a6) drawn at random,
one short co-simulation per draw, the tracking error of each.

G1 for 20 s with the foam reached at 8.38 s; foam_da1, foam_da2 uniform on [0, 0.8] N.m (seeded).  For a
study of thousands of points in parallel, see `wmr-cosim sweep` (docs/sweeps.md).

    python examples/monte_carlo_friction.py
"""
from __future__ import annotations

import numpy as np

from wmr_cosim import Simulation


def main(n: int = 4, seed: int = 1, stop: float = 20.0) -> list[dict]:
    rng = np.random.default_rng(seed)
    base = Simulation.load("g1_learn.toml").experiment(stop=stop)
    base.document["record"] = {"variables": ["plant.x_A", "plant.y_A", "plant.dF*", "controller.e*"]}
    rows = []
    for da1, da2 in rng.uniform(0.0, 0.8, size=(n, 2)):
        sim = Simulation(base.document, file="monte_carlo_friction")
        for name, value in (("foam_on_time", True), ("foam_t_on", 8.38), ("foam_da1", float(da1)),
                            ("foam_da2", float(da2))):
            sim.parameter(f"plant.{name}", value)
        r = sim.run()
        rmse = [float(np.sqrt(np.mean(r[f"controller.e{i}"] ** 2))) for i in (1, 2)]
        rows.append({"foam_da1": float(da1), "foam_da2": float(da2), "rmse_e1": rmse[0], "rmse_e2": rmse[1],
                     "dF1_end": float(r["plant.dF1"][-1]), "dF2_end": float(r["plant.dF2"][-1]), "status": r.status})
    print(f"{'da1':>6s} {'da2':>6s} {'RMSE e1':>8s} {'RMSE e2':>8s}   [N.m, rad]")
    for row in rows:
        print(f"{row['foam_da1']:6.3f} {row['foam_da2']:6.3f} {row['rmse_e1']:8.4f} {row['rmse_e2']:8.4f}")
    return rows


if __name__ == "__main__":
    main()
