"""How robust the paper's controller is, beyond the paper: the whole protocol (learn, frozen, foam) of
every task re-run on perturbed plants and sensors, and the study of when W stops adapting.

Axes (each alone, the others at their defaults):

* ``mismatch``: a left/right mismatch m of the rolling resistance, a5 = a (1 + m/2), a6 = a (1 - m/2)
  with a = 4.3001 N.m of Table 1, so (a5 - a6) / a = m and the mean is unchanged; the controller keeps
  the nominal model.
* ``heading``: the initial heading beta0 [deg] of the robot (plant and odometry alike; the paper gives
  only the start point).
* ``noise``: encoder noise, a Gaussian jitter of the edge position of ``noise_std`` counts (seeded).
* ``bump``: a bump at the foam's edge, a5 and a6 raised by a further ``foam_bump`` [N.m] for
  ``foam_bump_time`` seconds from the foam's onset (the real robot's control peaked at the edge).

The freeze study scores readings of when W stops adapting: the threshold P0 of the freeze rule (51)
(smallest eigenvalue of P <= P0 stops W and P), and, as the alternative, a fixed freeze time T (W and P
adapt over 0-T s, P0 = 0).  Each reading runs every task on the nominal plant and at a 5 % mismatch,
and is scored on the 32 cells of Tables 2 and 3, on the number of diverged runs, and on robustness
to the 5 % mismatch.

Every point is a sweep point (``sweep.run_point``) on the project's Dask cluster: the points run in
parallel and each finished point is saved at once (``points/<id>.json``), so an interrupted study
resumes where it stopped.
"""
from __future__ import annotations

import json
import math
import os
import shutil
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from .analysis import fidelity
from ..components import paper
from ..cosim import LimitOverrides
from .tasks import manifest_path, task_files

RUNS = ("learn", "frozen", "foam")
_A = paper.table1()["a"][4]          # nominal a5 = a6 [N.m]
_P0 = paper.table1()["P0"]


@dataclass
class StudyGrid:
    """The values of each axis and the readings of the freeze study.  Units: mismatch [-] (0.05 = 5 %),
    heading [deg], noise [counts], P0 [-], freeze times [s]."""

    tasks: tuple[str, ...] = paper.TASKS
    mismatch: tuple[float, ...] = (0.0, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2)
    heading_deg: tuple[float, ...] = (0.0, 10.0, 20.0, 30.0)
    noise_counts: tuple[float, ...] = (0.0, 0.25, 0.5, 1.0)
    noise_seed: int = 1
    bump_Nm: tuple[float, ...] = (0.0, 1.7, 3.4)
    bump_time: float = 0.2
    p0: tuple[float, ...] = (1e-4, 2e-4, 5e-4, 1e-3, 2e-3)
    freeze_times: tuple[float, ...] = (6.0, 8.0, 10.0)
    freeze_mismatch: float = 0.05
    freeze: bool = True
    axes: tuple[str, ...] = ("mismatch", "heading", "noise", "bump")
    manifest: str | None = None      # the tasks file (default scenarios/paper.toml)


def job_grid(grid: StudyGrid | None, manifest: str | os.PathLike | None, tasks: tuple[str, ...]) -> StudyGrid:
    """The study grid of a paper job run on the tasks file ``manifest`` naming ``tasks``: ``grid`` (default
    the full one) on that file and, when the grid names no file itself, on those of its tasks the file names."""
    grid = grid if grid is not None else StudyGrid()
    if grid.manifest is not None:
        return grid
    return replace(grid, manifest=None if manifest is None else str(manifest),
                   tasks=tuple(t for t in grid.tasks if t in tasks))


def mismatch_params(m: float) -> dict[str, float]:
    """a5, a6 of the plant for a left/right mismatch m: a (1 + m/2), a (1 - m/2) [N.m]."""
    if m == 0.0:
        return {}
    return {"plant.a5": _A * (1.0 + 0.5 * m), "plant.a6": _A * (1.0 - 0.5 * m)}


def heading_params(deg: float) -> dict[str, float]:
    """The initial heading of the plant and of the controller's odometry [rad] from degrees."""
    if deg == 0.0:
        return {}
    b = math.radians(deg)
    return {"plant.beta0": b, "controller.beta0": b}


def noise_params(std: float, seed: int) -> dict[str, Any]:
    """Encoder noise of ``std`` counts with a fixed seed."""
    if std == 0.0:
        return {}
    return {"sensor.noise_std": std, "sensor.noise_seed": seed}


def bump_params(bump: float, duration: float) -> dict[str, float]:
    """A bump of ``bump`` N.m at the foam's edge for ``duration`` seconds."""
    if bump == 0.0:
        return {}
    return {"plant.foam_bump": bump, "plant.foam_bump_time": duration}


def reading_params(kind: str, value: float) -> dict[str, Any]:
    """A reading of when W stops: ('P0', threshold) or ('T', freeze time [s], P0 = 0)."""
    if kind == "P0":
        return {} if value == _P0 else {"controller.P0": value}
    return {"controller.P0": 0.0, "controller.adapt_t_end": value}


def reading_label(kind: str, value: float) -> str:
    default = " (Table 1, the default)" if kind == "P0" and value == _P0 else ""
    return f"P0 = {value:g}{default}" if kind == "P0" else f"fixed freeze at T = {value:g} s"


def plan(grid: StudyGrid) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The distinct points of the study (a point: id, base protocol file, parameters) and, per axis
    value or reading, the point id of each task."""
    from ..cosim import ScenarioError

    files = task_files(grid.manifest)
    missing = [t for t in grid.tasks if t not in files]
    if missing:
        raise ScenarioError(str(manifest_path(grid.manifest)), "tasks",
                            f"the robustness study needs {', '.join(missing)}, which this file does not name")
    points: list[dict[str, Any]] = []
    index: dict[str, int] = {}

    def point(task: str, params: dict[str, Any]) -> int:
        key = task + repr(sorted(params.items()))
        if key not in index:
            index[key] = len(points)
            points.append({"id": len(points), "task": task, "base": str(files[task]), "params": dict(params)})
        return index[key]

    layout: dict[str, Any] = {}
    axes = {"mismatch": [(v, mismatch_params(v)) for v in grid.mismatch],
            "heading": [(v, heading_params(v)) for v in grid.heading_deg],
            "noise": [(v, noise_params(v, grid.noise_seed)) for v in grid.noise_counts],
            "bump": [(v, bump_params(v, grid.bump_time)) for v in grid.bump_Nm]}
    for name in grid.axes:
        layout[name] = [{"value": v, "points": {t: point(t, p) for t in grid.tasks}} for v, p in axes[name]]
    if grid.freeze:
        readings = [("P0", v) for v in grid.p0] + [("T", v) for v in grid.freeze_times]
        layout["freeze"] = [{"kind": k, "value": v, "label": reading_label(k, v),
                             "nominal": {t: point(t, reading_params(k, v)) for t in grid.tasks},
                             "mismatch": {t: point(t, {**reading_params(k, v), **mismatch_params(grid.freeze_mismatch)})
                                          for t in grid.tasks}}
                            for k, v in readings]
    return points, layout


# ---------------------------------------------------------------------- scoring
def _tasks_of(rows: dict[int, dict[str, Any]], ids: dict[str, int]) -> dict[str, dict[str, Any]]:
    """The {task: {run: {rmse_e, rmse_edot, diverged}}} form of analysis.fidelity from sweep rows."""
    out: dict[str, dict[str, Any]] = {}
    for task, pid in ids.items():
        r = rows[pid]
        out[task] = {}
        for run in RUNS:
            vals = [r.get(f"{run}.rmse_e1"), r.get(f"{run}.rmse_e2"), r.get(f"{run}.rmse_edot1"), r.get(f"{run}.rmse_edot2")]
            ok = all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals)
            out[task][run] = {"rmse_e": vals[:2] if ok else None, "rmse_edot": vals[2:] if ok else None,
                              "rmse_e_true": [r.get(f"{run}.rmse_e_true1"), r.get(f"{run}.rmse_e_true2")],
                              # a run that failed (a non-finite value stopped it) counts as diverged
                              "diverged": bool(r.get(f"{run}.diverged", True))}
    return out


def _diverged(tasks: dict[str, dict[str, Any]]) -> list[str]:
    return [f"{t}.{run}" for t in tasks for run in RUNS if tasks[t][run]["diverged"]]


def _finite_max(xs: list[Any]) -> float | None:
    ok = [float(x) for x in xs if isinstance(x, (int, float)) and math.isfinite(x)]
    return max(ok) if ok else None


def summarise(rows: dict[int, dict[str, Any]], layout: dict[str, Any], grid: StudyGrid) -> dict[str, Any]:
    """metrics.json's ``robustness`` and ``freeze_study`` from the rows of the points."""
    out: dict[str, Any] = {"tasks": list(grid.tasks)}
    for name in ("mismatch", "heading", "noise", "bump"):
        if name not in layout:
            continue
        entries = []
        for e in layout[name]:
            tasks = _tasks_of(rows, e["points"])
            entries.append({
                "value": e["value"], "diverged_runs": _diverged(tasks), "all_converge": not _diverged(tasks),
                # the largest RMSE of e over both wheels per task and run (measured signal; rad)
                "rmse_e_max": {t: {run: _finite_max(tasks[t][run]["rmse_e"] or [math.inf]) for run in RUNS}
                               for t in tasks},
                "rmse_e_true_max": {t: {run: _finite_max(tasks[t][run]["rmse_e_true"] or []) for run in RUNS}
                                    for t in tasks},
                "fidelity_cells": {(c["task"] + "." + c["run"] + "." + c["cell"]): c["ratio"]
                                   for c in fidelity(tasks)["cells"] if c["task"] in tasks},
                # the foam run's peak |u| within 2 s of the foam's edge [N.m]
                "edge_peak_u": {t: rows[pid].get("edge_peak_u") for t, pid in e["points"].items()},
                # gamma* (53) at 50 s of the task's foam run against its frozen run [-]
                "gamma_star": {t: rows[pid].get("gamma_star") for t, pid in e["points"].items()},
                "points": e["points"],
            })
        out[name] = entries
        # the largest swept value up to which (inclusive) every run of every task converged
        last = None
        for e in sorted(entries, key=lambda e: e["value"]):
            if not e["all_converge"]:
                break
            last = e["value"]
        key = {"mismatch": "max_mismatch_all_converge", "heading": "max_heading_deg_all_converge",
               "noise": "max_noise_counts_all_converge", "bump": "max_bump_Nm_all_converge"}[name]
        out[key] = last
    freeze = None
    if "freeze" in layout:
        readings = []
        for e in layout["freeze"]:
            nom, mis = _tasks_of(rows, e["nominal"]), _tasks_of(rows, e["mismatch"])
            fn, fm = fidelity(nom), fidelity(mis)
            readings.append({"kind": e["kind"], "value": e["value"], "label": e["label"],
                             "within_1_5": fn["within_1_5"], "within_2_5": fn["within_2_5"],
                             "rms_log_factor": fn["rms_log_factor"], "diverged_runs": _diverged(nom),
                             "mismatch_diverged_runs": _diverged(mis), "mismatch_within_1_5": fm["within_1_5"],
                             "n_cells": fn["n_cells"]})
        freeze = {"mismatch": grid.freeze_mismatch, "readings": readings, **decide(readings)}
    return {"robustness": out, "freeze_study": freeze}


def _scores(r: dict[str, Any]) -> tuple[tuple, tuple, tuple]:
    """(fidelity, divergence, robustness), each larger = better, compared lexicographically."""
    rms = r["rms_log_factor"] if r["rms_log_factor"] is not None else math.inf
    return ((r["within_1_5"], -rms), (-len(r["diverged_runs"]),),
            (-len(r["mismatch_diverged_runs"]), r["mismatch_within_1_5"]))


def compare(r: dict[str, Any], readings: list[dict[str, Any]]) -> str:
    """'better / equal / worse' on each of the three scores against the default reading."""
    default = next((d for d in readings if d["kind"] == "P0" and d["value"] == _P0), None)
    if default is None:
        return "-"
    if r is default:
        return "(the default)"
    word = lambda a, b: "better" if a > b else "equal" if a == b else "worse"  # noqa: E731
    return " / ".join(word(a, b) for a, b in zip(_scores(r), _scores(default)))


def decide(readings: list[dict[str, Any]]) -> dict[str, Any]:
    """The default reading (P0 of Table 1) is replaced only by a reading better on all three scores:
    fidelity (cells within 1.5x, then the rms log-factor), divergence (fewer diverged runs; equal counts
    as not worse) and robustness to the mismatch (fewer diverged runs, then more cells within 1.5x).
    Precisely: strictly better fidelity and robustness, and no more diverged runs (no reading can beat
    zero)."""
    default = next((r for r in readings if r["kind"] == "P0" and r["value"] == _P0), None)
    if default is None:
        return {"default": None, "better_on_all_three": [], "change_default": False}
    d = _scores(default)
    better = []
    for r in readings:
        if r is default:
            continue
        s = _scores(r)
        if s[0] > d[0] and s[1] >= d[1] and s[2] > d[2]:
            better.append(r["label"])
    return {"default": default["label"], "better_on_all_three": better, "change_default": bool(better)}


def run_study(out: Path, grid: StudyGrid | None = None, workers: int | None = None,
              progress: bool | None = None, archive_limits: LimitOverrides | None = None) -> dict[str, Any]:
    """Run the study's points on a local Dask cluster into ``out`` (resumable) and summarise them;
    ``archive_limits`` (the caller's, over each task's own) go with every point."""
    from ..studies import Cluster, run_points
    from . import robot_measures
    from .robot_measures import robot_system

    grid = grid or StudyGrid()
    points, layout = plan(grid)
    out.mkdir(parents=True, exist_ok=True)
    stamp = out / "plan.json"
    key = json.dumps(points, sort_keys=True)
    if stamp.is_file() and stamp.read_text() != key:   # another grid: its saved points do not apply
        shutil.rmtree(out / "points", ignore_errors=True)
    stamp.write_text(key)
    with Cluster(workers) as cl:
        rows_list = run_points(points, points[0]["base"], "freeze", None, out, cl, progress=progress, label="robustness",
                               archive_limits=archive_limits, system=robot_system(),
                               measure=robot_measures.measure)
    rows = {r["point"]: r for r in rows_list}
    s = summarise(rows, layout, grid)
    s["robustness"]["n_points"] = len(points)
    s["robustness"]["bump_time"] = grid.bump_time
    s["robustness"]["n_runs"] = len(points) * len(RUNS)
    return s
