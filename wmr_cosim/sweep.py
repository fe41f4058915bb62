"""Sweeps and Monte Carlo studies on Dask: many full co-simulations, each point in a worker process.

The sweep file and its points are sweep_file.py's, the cluster cluster.py's, the figures sweep_plots.py's
and what a point measures of our robot robot_measures.py's; this module runs the points (:func:`run_point`,
in a worker: the base's runs with the point's parameters, then the measure it is given) and the sweep
(:func:`run_sweep`).

Every point runs the base's runs with its parameter values; the results are one row per point (the
parameters, status, reason, metrics) in ``results.parquet`` and ``results.csv``, plots in ``figures/``.
Each finished point is written at once to ``points/<id>.json``: a sweep interrupted and started again
with the same output folder skips the points already done and gives the same final table.  Points are
drawn in the parent from the seed, so the results do not depend on the number of workers.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .cluster import Cluster
from .cosim import CosimError, LimitOverrides
from . import robot_measures
from .sweep_file import SweepSpec, draw_points, load_sweep
from .sweep_metrics import SweepMeasure, check_metrics
from .sweep_plots import plot_sweep


#: What a point measures of its runs: ``measure(row, results, folder)`` (robot_measures.measure for ours).
Measure = Callable[[dict[str, Any], dict[str, Any], Path], None]


# ---------------------------------------------------------------------- one point (in a worker)
def run_point(point: dict[str, Any], base: str, variant: str | None, runs: list[str] | None,
              fmus: dict[str, str], out_dir: str, keep_runs: bool = False,
              archive_limits: LimitOverrides | None = None, measure: Measure | None = None) -> dict[str, Any]:
    """Run one point (the base's runs with the point's parameters) and return its row: id, parameters,
    status ('ok', 'diverged', 'failed'), reason and what ``measure`` adds (``measure(row, results, folder)``:
    the runs' metrics into the row; it may set the status and reason).  Never raises: a failure is a row.
    ``archive_limits``: the submitter's archive limits (a command line's options) over the scenario's own;
    they travel with the point, since a worker may be another process or another machine."""
    from .cosim import run_protocol

    row: dict[str, Any] = {"point": point["id"], **point["params"], "status": "ok", "reason": ""}
    work = Path(out_dir) / "runs" / f"{point['id']:05d}" if keep_runs else Path(tempfile.mkdtemp(prefix="wmr-sweep-"))
    t0 = time.perf_counter()
    try:
        results = run_protocol(base, work, lambda name: Path(fmus[name]) if name in fmus else None,
                               variant=variant, overrides=point["params"], progress=False, only=runs,
                               limits=archive_limits)
        if measure is not None:
            measure(row, results, work)
        failed = next((name for name, res in results.items() if res.status != "ok"), None)
        if failed is not None and row["status"] == "ok":   # (whatever the measure: the first run that failed)
            row["status"], row["reason"] = "failed", f"{failed}: {results[failed].message}"
    except CosimError as exc:
        row["status"], row["reason"] = "failed", str(exc)
    except KeyError as exc:    # a failed run that did not record what the metrics need: keep its reason
        if row["status"] == "ok":
            row["status"], row["reason"] = "failed", f"KeyError: {exc}"
    except Exception as exc:  # a point must never take the sweep down
        row["status"], row["reason"] = "failed", f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    finally:
        if not keep_runs:
            shutil.rmtree(work, ignore_errors=True)
    row["wall_s"] = time.perf_counter() - t0
    return row


# ---------------------------------------------------------------------- the sweep (in the parent)
def run_points(points: list[dict[str, Any]], base: str, variant: str | None, runs: list[str] | None,
               out: Path, cluster: Cluster, keep_runs: bool = False, progress: bool | None = None,
               label: str = "sweep", archive_limits: LimitOverrides | None = None, *, fmus: dict[str, str],
               measure: Measure | None) -> list[dict[str, Any]]:
    """Run the points not yet in ``out/points`` on the cluster; returns every point's row, by id.
    ``archive_limits`` (a caller's, over each scenario's own) are submitted with every point, as are
    ``fmus`` (model name -> the FMU file every worker reads) and ``measure`` (see :func:`run_point`)."""
    from distributed import as_completed

    pts_dir = out / "points"
    pts_dir.mkdir(parents=True, exist_ok=True)
    rows: dict[int, dict[str, Any]] = {}
    for p in points:
        f = pts_dir / f"{p['id']:05d}.json"
        if f.is_file():
            try:
                rows[p["id"]] = json.loads(f.read_text())
            except json.JSONDecodeError:
                f.unlink()  # a half-written point: run it again
    todo = [p for p in points if p["id"] not in rows]
    bar = None
    if progress is None:
        progress = sys.stderr.isatty()
    if progress and todo:
        from tqdm import tqdm
        bar = tqdm(total=len(points), initial=len(rows), desc=label, unit="run", file=sys.stderr)
    failed = sum(1 for r in rows.values() if r["status"] != "ok")
    # a point may name its own base (a study over several tasks in one submission)
    futures = [cluster.client.submit(run_point, p, p.get("base", base), variant, runs, fmus, str(out), keep_runs,
                                     archive_limits, measure, key=f"{label}-{out.name}-{p['id']}-{_digest(p, archive_limits)}",
                                     pure=False) for p in todo]
    try:
        for fut in as_completed(futures):
            row = fut.result()
            tmp = pts_dir / f"{row['point']:05d}.json.tmp"
            tmp.write_text(json.dumps(row, default=_jsonable))
            os.replace(tmp, pts_dir / f"{row['point']:05d}.json")
            rows[row["point"]] = row
            failed += row["status"] != "ok"
            if bar is not None:
                bar.set_postfix(failed=failed)
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        for fut in futures:
            fut.cancel()
    return [rows[p["id"]] for p in points]


def _digest(p: dict[str, Any], archive_limits: LimitOverrides | None = None) -> str:
    """A short digest of a point and the limits it runs with (two submissions differ in their task keys)."""
    what = [p, asdict(archive_limits) if archive_limits is not None else None]
    return hashlib.sha1(json.dumps(what, sort_keys=True, default=str).encode()).hexdigest()[:8]


def _jsonable(x: Any) -> Any:
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return str(x)


def run_sweep(path: str | os.PathLike, out: str | os.PathLike | None = None, workers: int | None = None,
              scheduler: str | None = None, progress: bool | None = None, cluster: Cluster | None = None,
              security: Any = None, dashboard: bool = False, archive_limits: LimitOverrides | None = None):
    """Run a sweep file; write results.parquet, results.csv, sweep.json and figures/ into ``out``.
    Returns the table (a pandas DataFrame, one row per point, ordered by point).  ``security`` and
    ``dashboard``: see :class:`Cluster`; ``archive_limits``: the caller's archive limits (a command line's
    options), over each point's scenario's own, sent to the workers with every point."""
    from .cosim import OutputLock, make_folder

    spec = load_sweep(path)
    out = make_folder(Path(out) if out is not None else Path("results") / Path(path).stem)
    with OutputLock(out):  # a second sweep into the same folder is refused at once
        return _run_sweep(spec, out, workers, scheduler, progress, cluster, security, dashboard, archive_limits)


def _measure(spec: SweepSpec, fmus: dict[str, str], archive_limits: LimitOverrides | None
             ) -> tuple[SweepMeasure, dict[str, str | None]]:
    """What each point measures (the named sets, the file's metrics) and the metrics' units, the metrics
    checked against what the base's runs record (their FMUs resolved): before any point runs."""
    from .cosim import check_protocol

    runs: dict[str, dict[str, str | None]] = {}
    if spec.measures:
        plans = check_protocol(spec.base, lambda name: Path(fmus[name]) if name in fmus else None, spec.variant,
                               only=spec.runs, limits=archive_limits)
        runs = {name: {col: c["unit"] for col, c in plan.columns().items()} for name, plan in plans.items()}
    units = check_metrics(spec.file, spec.measures, runs) if spec.measures else {}
    return SweepMeasure(tuple(spec.measures), tuple(spec.sets), tuple(runs)), units


def _run_sweep(spec: "SweepSpec", out: Path, workers: int | None, scheduler: str | None, progress: bool | None,
               cluster: "Cluster | None", security: Any, dashboard: bool, archive_limits: LimitOverrides | None):
    import pandas as pd

    points = draw_points(spec)
    fmus = robot_measures.fmu_paths()
    measure, units = _measure(spec, fmus, archive_limits)
    meta = {"spec": {**asdict(dataclasses.replace(spec, measures=[])),
                     "measures": {m.name: m.as_dict() for m in spec.measures}}, "units": units, "points": points}
    meta_file = out / "sweep.json"
    if meta_file.is_file():
        old = json.loads(meta_file.read_text())
        if old.get("points") != json.loads(json.dumps(points)) or old["spec"]["base"] != spec.base:
            raise CosimError(f"{out}: holds the results of another sweep (different points); use another --out")
    meta_file.write_text(json.dumps(meta, indent=1) + "\n")
    own = cluster is None
    cl = cluster or Cluster(workers, scheduler, security, dashboard)
    try:
        rows = run_points(points, spec.base, spec.variant, spec.runs, out, cl, spec.keep_runs, progress,
                          archive_limits=archive_limits, fmus=fmus, measure=measure)
    finally:
        if own:
            cl.close()
    df = pd.DataFrame(rows).sort_values("point").reset_index(drop=True)
    for name, write in (("results.parquet", df.to_parquet), ("results.csv", df.to_csv)):
        part = out / f"{name}.part"   # written whole, then renamed: a file that exists is complete
        write(part, index=False)
        os.replace(part, out / name)
    plot_sweep(df, spec, out / "figures", units)
    return df
