"""What a point of a study measures of our robot's runs, for the sweeps, the robustness study and the
gamma search (the generic sweep, sweep.py, runs the points and takes the measure it is given): the
controller's metrics of each run (the tracking errors' RMSE, the final position, the time to the goal,
divergence), with a frozen and a foam run the disturbance analysis (gamma*, (53), with the run's own Q and
R): the robot's set of metrics, registered with the studies (:data:`METRIC_SET`)."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..studies import MetricSet, System, register_set

if TYPE_CHECKING:
    from .analysis import Signals


def measure(row: dict[str, Any], results: dict[str, Any], work: Path) -> None:
    """The metrics of the point's runs (in ``work``) into ``row`` (the sweep judged its status from the
    runs' own: :func:`wmr_cosim.studies.sweep.point_status`; a run whose analysis diverges makes an ok
    point diverged); then, with a frozen and a foam run, the disturbance analysis."""
    from ..cosim import RunStatus
    from .analysis import disturbance_analysis

    sigs: dict[str, Signals | None] = {}
    for name, res in results.items():
        if not RunStatus(res.status).measured and not (work / name / "signals.npy").is_file():
            continue   # (a run that failed before recording: nothing to measure)
        sigs[name] = _run_metrics(row, name, res, work / name)
    frozen, foam = sigs.get("frozen"), sigs.get("foam")
    if frozen is not None and foam is not None:
        d = disturbance_analysis(frozen, foam, **_weights(work / "foam"))
        for k in ("gamma_star", "gamma_true", "gain_incremental"):
            row[k] = d[k] if d[k] is not None else math.nan
        row["foam_rise1"], row["foam_rise2"] = [math.nan if r is None else r for r in d["foam_rise"]]
        row["edge_peak_u"] = d["edge_peak_u"] if d["edge_peak_u"] is not None else math.nan


#: The columns :func:`measure` adds of each run (``<run>.<name>``) and of a frozen and a foam run together.
RUN_COLUMNS = tuple(f"{m}{i}" for m in ("rmse_e", "rmse_edot", "rmse_e_true", "rmse_edot_true") for i in (1, 2)) + \
    ("final_x", "final_y", "t_goal", "goal_distance", "diverged")
ANALYSIS_COLUMNS = ("gamma_star", "gamma_true", "gain_incremental", "foam_rise1", "foam_rise2", "edge_peak_u")


def columns(runs: list[str]) -> list[str]:
    """Every column :func:`measure` may add to a point's row for these runs."""
    return [f"{run}.{c}" for run in runs for c in RUN_COLUMNS] + list(ANALYSIS_COLUMNS)


def _run_metrics(row: dict[str, Any], name: str, res: Any, run_dir: Path) -> Signals | None:
    """The metrics of run ``name`` (recorded in ``run_dir``) into ``row`` as ``<name>.<metric>``; a run
    that diverged makes the point diverged.  Returns the run's signals (None if it recorded nothing)."""
    from .analysis import divergence, load_signals, run_summary

    sig = load_signals(run_dir)
    s = run_summary(sig, _goal(run_dir), res.status)
    for i in (0, 1):
        row[f"{name}.rmse_e{i + 1}"] = s["rmse_e"][i] if s["rmse_e"] else math.nan
        row[f"{name}.rmse_edot{i + 1}"] = s["rmse_edot"][i] if s["rmse_edot"] else math.nan
        row[f"{name}.rmse_e_true{i + 1}"] = s["rmse_e_true"][i] if s.get("rmse_e_true") else math.nan
        row[f"{name}.rmse_edot_true{i + 1}"] = s["rmse_edot_true"][i] if s.get("rmse_edot_true") else math.nan
    fp = s.get("final_position") or [math.nan, math.nan]
    row[f"{name}.final_x"], row[f"{name}.final_y"] = fp
    row[f"{name}.t_goal"] = s["t_goal"] if s.get("t_goal") is not None else math.nan
    row[f"{name}.goal_distance"] = s.get("goal_distance", math.nan)
    row[f"{name}.diverged"] = bool(s["diverged"])
    if s["diverged"] and row["status"] == "ok":
        row["status"], row["reason"] = "diverged", f"{name}: {divergence(sig, res.status)}"
    return sig


def _controller_parameters(run_dir: Path) -> dict[str, Any] | None:
    """The parameters a run's scenario set on its controller (its ``scenario.json``), None if unreadable."""
    try:
        return json.loads((run_dir / "scenario.json").read_text())["instances"]["controller"]["parameters"]
    except (OSError, KeyError, ValueError, TypeError):
        return None


def _goal(run_dir: Path) -> tuple[float, float] | None:
    p = _controller_parameters(run_dir)
    try:
        if p is None or p.get("task", "goal") == "line":
            return None
        return float(p["goal_x"]), float(p["goal_y"])
    except (KeyError, ValueError, TypeError):
        return None


def _weights(run_dir: Path) -> dict[str, float]:
    """Q and R of a run's controller, the weights of (53): the values its scenario set (``scenario.json``),
    the controller's defaults (Table 1) for the others."""
    from ..components.controller import ControllerParams

    defaults = ControllerParams()
    w = {"Q": defaults.Q, "R": defaults.R}
    p = _controller_parameters(run_dir) or {}
    return {k: float(p.get(k, v)) for k, v in w.items()}


def robot_system() -> System:
    """Our robot as the system of a study: its model names resolve to its FMUs (the runner's
    ``resolve_model``, each built when a base first names it), every run is judged by
    :func:`~wmr_cosim.paper.analysis.judge_run`; its set of metrics is registered with this module."""
    from .. import runner
    from .analysis import judge_run

    return System(models=runner.resolve_model, judge=judge_run)


#: The robot's set of metrics (a sweep file's ``sets = ["robot"]``; the default of one that names no metric),
#: registered with the studies as this module is imported.
METRIC_SET = MetricSet("robot", measure, columns, "the robot's set of metrics", default=True)
register_set(METRIC_SET)
