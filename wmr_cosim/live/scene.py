"""What the live view draws beside the time plots: the path of ``[live] xy`` (two recorded position outputs,
x then y) and the task's goals on it.

The goals are our robot's: an instance with parameters ``goal_x`` and ``goal_y`` [m] (the controller's;
tunable, so a value set during a live run moves the goal) whose ``task``, where it has one, is "goal".
A live run reads them from the FMU; a finished run (``wmr-cosim view``) from its scenario.json and the
values its event table set.
"""
from __future__ import annotations

from typing import Any

#: The parameters of a goal point [m], x then y.
GOAL = ("goal_x", "goal_y")


def xy_of(plan: Any) -> dict[str, Any] | None:
    """``{"x": "inst.var", "y": "inst.var", "units": [ux, uy]}`` of a plan whose scenario names ``[live] xy``
    (None otherwise); both are recorded columns (the resolution checks it)."""
    xy = list(getattr(plan.scenario, "xy", []) or [])
    if len(xy) != 2:
        return None
    columns = plan.columns()
    return {"x": xy[0], "y": xy[1], "units": [columns.get(c, {}).get("unit") for c in xy]}


def goal_refs(plan: Any) -> list[tuple[str, str]]:
    """The goals of the plan's instances: ("inst.goal_x", "inst.goal_y") for each instance that has both
    parameters and whose ``task`` (where the scenario sets one) is "goal"."""
    out = []
    for name, ip in plan.instances.items():
        ours = {ip.our_name(v): v for v in ip.model.variables.values()}
        if not all(g in ours and ours[g].causality == "parameter" for g in GOAL):
            continue
        task = {ip.our_name(v): value for v, value in ip.parameters}.get("task", "goal")
        if task == "goal":
            out.append((f"{name}.{GOAL[0]}", f"{name}.{GOAL[1]}"))
    return out


def finished_scene(scenario: dict[str, Any], events: list[dict[str, Any]],
                   units: dict[str, str | None]) -> dict[str, Any] | None:
    """The ``xy`` of a finished run from its scenario.json (``document``'s ``[live] xy``; the goals from the
    instances' parameters, each as the last value its event table set) and its columns' ``units``; None
    where the scenario names no path or a name is not a recorded column."""
    doc = _table(scenario.get("document"))
    xy = _table(doc.get("live")).get("xy")
    if not (isinstance(xy, list) and len(xy) == 2 and all(isinstance(v, str) and v in units for v in xy)):
        return None
    goals = []
    for name, inst in _table(scenario.get("instances")).items():
        params = dict(_table(_table(inst).get("parameters")))
        for e in events:   # the values set during the run: the last one counts (the goal where the run ended)
            var = e.get("variable")
            if isinstance(var, str) and var.startswith(f"{name}.") and "value" in e:
                params[var[len(name) + 1:]] = e["value"]
        gx, gy = params.get(GOAL[0]), params.get(GOAL[1])
        if params.get("task", "goal") == "goal" and isinstance(gx, (int, float)) and isinstance(gy, (int, float)) \
                and not isinstance(gx, bool) and not isinstance(gy, bool):
            goals.append([float(gx), float(gy)])
    return {"x": xy[0], "y": xy[1], "units": [units.get(xy[0]), units.get(xy[1])], "goals": goals}


def _table(x: Any) -> dict[str, Any]:
    """``x`` where it is a table (a JSON object), else an empty one."""
    return x if isinstance(x, dict) else {}
