"""The paper's printed constants and results (Tables 1-3, final positions, reported levels).

The numbers live in ``paper_results.json`` beside this module (a copy of the project's transcription of
the paper); nothing here retypes them.  Units: rad, rad/s, m, s, N.m.
"""
from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

_PATH = Path(__file__).with_name("paper_results.json")

#: Wheel radius r [m] (Pioneer 2-DX, 165 mm wheel diameter); the paper does not print it.
WHEEL_RADIUS_M = 0.0825
#: Half axle length l1 [m] (wheel track about 0.32 m); the paper does not print it.
HALF_AXLE_M = 0.16


@lru_cache(maxsize=1)
def results() -> dict[str, Any]:
    """The whole transcription of the paper as a dict (a cached, shared object: do not mutate)."""
    with _PATH.open(encoding="utf-8") as fh:
        return json.load(fh)


def table1() -> dict[str, Any]:
    """Table 1 'Constants used in verification' (a, cF, Lambda, goals, gains, Q, R, gamma, W0, P0, h, ...)."""
    return results()["table1_constants"]


def rmse_table(task: str) -> dict[str, list[float]]:
    """Table 2 (G1-G3) or Table 3 (LINE): run -> [e_1, e_2, e_dot_1, e_dot_2] RMSE values [rad, rad/s]."""
    if task == "LINE":
        return results()["table3_rmse"]["LINE"]
    return results()["table2_rmse"][task]


TASKS = ("G1", "G2", "G3", "LINE")


def task_controller(task: str) -> dict[str, Any]:
    """Controller parameter overrides of one of the paper's tasks: a go-to-goal G1-G3 or the LINE."""
    if task == "LINE":
        line = results()["line_task"]
        return {"task": "line", "b1": line["b1"], "line_b2": line["b2"], "c": line["c"]}
    goals = table1()["goals"]
    if task not in goals:
        raise KeyError(f"unknown task {task!r}: one of {', '.join(TASKS)}")
    gx, gy = goals[task]
    return {"task": "goal", "goal_x": float(gx), "goal_y": float(gy)}


def task_goal(task: str) -> tuple[float, float] | None:
    """The goal point G [m] of a go-to-goal task, None for the LINE (KeyError for an unknown task)."""
    c = task_controller(task)
    return (c["goal_x"], c["goal_y"]) if c["task"] == "goal" else None
