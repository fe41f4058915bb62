"""The gamma search of section 2.1: suboptimal H-infinity control by successively reducing gamma.

For a protocol with a learning run, a frozen run and a foam run (scenarios/paper/g1.toml, say), gamma
(the controller's ``gamma``: it scales the disturbance player by 1/gamma^2 and the Hamiltonian's
disturbance term, so it matters mostly for small gamma) is set on a grid; each grid point runs the whole
protocol and yields gamma* of (53) and whether every run stayed stable.  The condition is: stable and
gamma* <= gamma.  Where the grid shows a single change from failing to holding, bisection narrows it
down; the answer is the smallest gamma found for which the condition holds.  Stability need not be
monotone in gamma, so the whole curve is reported.  gamma* scales as 1/|dF|, so the answer depends on
the assumed size of the friction change: the report says which.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from ..cosim import LimitOverrides
from ..studies import Cluster, run_points
from . import robot_measures
from .robot_measures import robot_system

DEFAULT_GRID = (0.25, 0.5, 1.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 20.0, 30.0)


def holds(row: dict[str, Any]) -> bool:
    """The H-infinity condition at one gamma: every run stable and gamma* <= gamma."""
    g = row.get("gamma_star")
    return row["status"] == "ok" and g is not None and not (isinstance(g, float) and math.isnan(g)) \
        and g <= row["controller.gamma"]


def gamma_search(scenario: str | os.PathLike, out: str | os.PathLike, grid: list[float] | None = None,
                 variant: str | None = "freeze", tol: float = 0.01, max_bisections: int = 12,
                 workers: int | None = None, scheduler: str | None = None, progress: bool | None = None,
                 security: Any = None, dashboard: bool = False, archive_limits: LimitOverrides | None = None
                 ) -> dict[str, Any]:
    """Grid, then bisection where the grid shows a single crossing; writes gamma_search.json, .csv and a
    figure into ``out``; returns the result.  ``security`` and ``dashboard``: see :class:`.cluster.Cluster`;
    ``archive_limits``: the caller's archive limits (a command line's options), over the protocol's own,
    sent to the workers with every point."""

    from ..cosim import CosimError, plan_runs, read_protocol
    from ..scenario_files import shipped_folder

    scenario = str(Path(scenario).resolve())
    # its base may be a shipped scenario (paper/g1.toml), found as `run` finds it
    proto = read_protocol(scenario, lambda name: Path(name), archive_limits, shipped_folder())
    sc, runs, _ = plan_runs(proto, None, None, archive_limits)
    names = [r.name for r in runs]
    for need in ("frozen", "foam"):
        if need not in names:
            raise CosimError(f"{scenario}: gamma-search needs a protocol with runs 'learn', 'frozen' and 'foam', "
                             f"such as scenarios/paper/g1.toml (this file has {', '.join(names)})")
    if variant is not None and variant not in sc.variants:
        raise CosimError(f"{scenario}: --variant {variant}: the protocol declares "
                         f"{', '.join(sc.variants) or 'no variants'}")
    sc, runs, vparams = plan_runs(proto, None, variant, archive_limits)
    grid = sorted(set(float(g) for g in (grid or DEFAULT_GRID)))
    if not grid or grid[0] <= 0:
        raise CosimError("gamma-search: the grid must hold values > 0")
    from ..cosim import OutputLock, make_folder

    out = make_folder(Path(out))
    with OutputLock(out):  # a second search into the same folder is refused at once
        return _search(scenario, out, runs, grid, variant, tol, max_bisections, workers, scheduler, progress,
                       security, dashboard, archive_limits)


def _search(scenario: str, out: Path, runs: list, grid: list[float], variant: str | None, tol: float,
            max_bisections: int, workers: int | None, scheduler: str | None, progress: bool | None,
            security: Any, dashboard: bool, archive_limits: LimitOverrides | None) -> dict[str, Any]:
    import pandas as pd

    friction = {k: v for r in runs if r.name == "foam" for k, v in r.parameters.items() if k.startswith("plant.foam")}
    rows: list[dict[str, Any]] = []
    study = {"archive_limits": archive_limits, "system": robot_system(), "measure": robot_measures.measure}
    with Cluster(workers, scheduler, security, dashboard) as cl:
        pts = [{"id": i, "params": {"controller.gamma": g}} for i, g in enumerate(grid)]
        rows = run_points(pts, scenario, variant, None, out, cl, progress=progress, label="gamma grid", **study)
        ok = [holds(r) for r in rows]
        changes = [i for i in range(1, len(ok)) if ok[i] != ok[i - 1]]
        bisected = False
        if len(changes) == 1 and not ok[changes[0] - 1] and ok[changes[0]]:
            lo, hi = grid[changes[0] - 1], grid[changes[0]]
            n = len(grid)
            for _ in range(max_bisections):
                if hi - lo <= tol * hi:
                    break
                mid = 0.5 * (lo + hi)
                r = run_points([{"id": n, "params": {"controller.gamma": mid}}], scenario, variant, None, out, cl,
                               progress=False, label="gamma bisection", **study)[0]
                rows.append(r)
                n += 1
                if holds(r):
                    hi = mid
                else:
                    lo = mid
            bisected = True
    rows.sort(key=lambda r: r["controller.gamma"])
    passing = [r["controller.gamma"] for r in rows if holds(r)]
    result = {
        "scenario": scenario, "variant": variant, "friction_change": friction,
        "grid": grid, "bisected": bisected,
        "smallest_gamma": min(passing) if passing else None,
        "monotone": len([i for i in range(1, len(rows)) if holds(rows[i]) != holds(rows[i - 1])]) <= 1,
        "curve": [{"gamma": r["controller.gamma"], "gamma_star": r.get("gamma_star"), "stable": r["status"] == "ok",
                   "holds": holds(r), "status": r["status"], "reason": r["reason"]} for r in rows],
        "note": ("gamma* of (53) is the whole cost over the energy of the disturbance estimate, so it scales as "
                 "1/|dF|: this answer holds for the assumed friction change " +
                 ", ".join(f"{k} = {v}" for k, v in friction.items()) + ", not for any."),
    }
    (out / "gamma_search.json").write_text(json.dumps(result, indent=1, default=str) + "\n")
    pd.DataFrame(result["curve"]).to_csv(out / "gamma_search.csv", index=False)
    _plot(result, out / "gamma_search.png")
    return result


def _plot(result: dict[str, Any], path: Path) -> None:
    from matplotlib.figure import Figure   # (no pyplot: the process's backend is left as it is)

    c = result["curve"]
    g = [p["gamma"] for p in c]
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    ax.plot(g, [p["gamma_star"] if p["gamma_star"] is not None else math.nan for p in c], "o-", ms=4,
            label="gamma* (53)")
    ax.plot(g, g, "k--", lw=0.8, label="gamma* = gamma")
    bad = [p for p in c if not p["stable"]]
    if bad:
        ax.plot([p["gamma"] for p in bad], [0.0] * len(bad), "x", color="C3", label="unstable")
    if result["smallest_gamma"] is not None:
        ax.axvline(result["smallest_gamma"], color="C2", lw=0.8, label=f"smallest gamma = {result['smallest_gamma']:.3g}")
    ax.set_xlabel("gamma [-]")
    ax.set_ylabel("gamma* [-]")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
