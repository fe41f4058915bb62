"""Figures of the paper's tables computed from recorded signals."""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def rmse(x: np.ndarray) -> float:
    """RMSE (54): sqrt(1/N sum x_i^2) over all N samples."""
    x = np.asarray(x, dtype=float)
    with np.errstate(over="ignore"):  # a diverged run's RMSE is inf, not a warning
        return float(np.sqrt(np.mean(x * x)))


def run_metrics(sig: Mapping[str, np.ndarray], goal: tuple[float, float] | None = None,
                ctrl: str = "controller", plant: str = "plant") -> dict[str, Any]:
    """The table figures of one run: RMSE of e and e_dot per wheel over all samples (Table 2/3), the
    final true position of point A, the time eps_G was first reached (None if never or no goal),
    final weights, and 'diverged' (a non-finite value or |e_i| above 1 rad at the end)."""
    e1, e2 = sig[f"{ctrl}.e1"], sig[f"{ctrl}.e2"]
    ed1, ed2 = sig[f"{ctrl}.edot1"], sig[f"{ctrl}.edot2"]
    tg = float(sig[f"{ctrl}.t_goal"][-1])
    final_e = (float(e1[-1]), float(e2[-1]))
    finite = all(bool(np.all(np.isfinite(a))) for a in (e1, e2, ed1, ed2))
    out: dict[str, Any] = {
        "rmse_e": [rmse(e1), rmse(e2)],
        "rmse_edot": [rmse(ed1), rmse(ed2)],
        "final_position": [float(sig[f"{plant}.x_A"][-1]), float(sig[f"{plant}.y_A"][-1])],
        "t_goal": tg if (goal is not None and tg >= 0.0) else None,
        "final_W": [float(sig[f"{ctrl}.W{i}"][-1]) for i in (1, 2, 3)],
        "diverged": (not finite) or max(abs(final_e[0]), abs(final_e[1])) > 1.0,
    }
    if goal is not None:
        x, y = out["final_position"]
        out["goal_distance"] = math.hypot(goal[0] - x, goal[1] - y)
    return out
