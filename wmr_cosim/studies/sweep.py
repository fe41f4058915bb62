"""Sweeps and Monte Carlo studies on Dask: many full co-simulations, each point in a worker process.

The sweep file and its points are sweep_file.py's, the cluster cluster.py's, what travels to the workers
shipment.py's, the metrics metrics.py's (and the named sets of metrics an application registers there),
the figures plots.py's, the system the points run (its model names, how its runs are judged) system.py's;
this module runs the points (:func:`run_point`, in a worker: the base's runs with the point's parameters,
their files from the worker's cache, then the measure it is given) and the sweep (:func:`run_sweep`).

Every point runs the base's runs with its parameter values; the results are one row per point (the
parameters, status, reason, metrics) in ``results.parquet`` and ``results.csv``, plots in ``figures/``.
Each finished point is written at once to ``points/<id>.json``: a sweep interrupted and started again
with the same output folder skips the points already done and gives the same final table.  Points are
drawn in the parent from the seed, so the results do not depend on the number of workers.
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import math
import os
import shutil
import sys
import tarfile
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .cluster import Cluster, check_worker_count
from ..cosim import CosimError, LimitOverrides, RunStatus, count
from .shipment import Shipment, ShippingCost, pack, ship, unship, worker_cache
from .sweep_file import SweepSpec, check_parameters, draw_points, load_sweep, read_base
from .metrics import SETS, SweepMeasure, check_metrics
from .plots import plot_sweep
from .system import System


#: The reason of a point whose worker died each time it ran it (Dask's ``allowed-failures`` over).
KILLED = "its worker died while running it, again when it was run on another"
#: What a point measures of its runs: ``measure(row, results, folder)`` (a named set's, the file's metrics).
Measure = Callable[[dict[str, Any], dict[str, Any], Path], None]


# ---------------------------------------------------------------------- one point (in a worker)
@dataclass(frozen=True)
class Study:
    """What every point of one submission shares, sent with each point (small: the files it names travel
    once per worker, see shipment.py): the shipment (the bases' documents and what their files are), the
    variant and runs of the bases to run, whether to send each point's run folders back (``keep_runs``),
    the submitter's archive limits (a command line's options, over each scenario's own: they travel with
    the point, since a worker may be another machine), what a point measures and how its runs are judged
    (the system's judge)."""

    shipment: Shipment
    base: str
    variant: str | None = None
    runs: list[str] | None = None
    keep_runs: bool = False
    archive_limits: LimitOverrides | None = None
    measure: Measure | None = None
    judge: Callable[[Any], Any] | None = None


def run_point(point: dict[str, Any], study: Study, cache: Path | None = None) -> tuple[dict[str, Any], bytes | None]:
    """Run one point (its base's runs, the study's by default, with the point's parameters) and return its
    row (id, parameters, status 'ok', 'diverged' or 'failed', reason, and what the study's measure adds:
    ``measure(row, results, folder)`` puts the runs' metrics into the row and may set the status and
    reason) and, with ``keep_runs``, its run folders as a gzipped tar.  The runs read their FMUs and input
    tables from ``cache`` (this Dask worker's cache of shipped files by default) and write into a folder
    beside it, removed after the point; every path of the cache in a reason is the driver's again, so a
    row does not depend on the worker.  Never raises: a failure is a row."""
    from ..cosim import run_protocol

    row = _row(point)
    cache = cache if cache is not None else worker_cache()
    # beside the cache, in the worker's own folder: what a killed worker leaves goes with that folder
    work = Path(tempfile.mkdtemp(prefix="wmr-sweep-", dir=cache.parent))
    unlocalise: Callable[[str], str] = str
    runs: bytes | None = None
    t0 = time.perf_counter()
    try:
        proto, unlocalise = study.shipment.protocol(point.get("base", study.base), study.archive_limits, cache)
        results = run_protocol(proto, work, proto.resolver, variant=study.variant, overrides=point["params"],
                               progress=False, only=study.runs, judge=study.judge)
        row["status"], row["reason"] = point_status(results)    # (whatever the measure adds)
        if study.measure is not None:
            study.measure(row, results, work)
        requirement_columns(row, results)
    except CosimError as exc:
        row["status"], row["reason"] = "failed", str(exc)
    except KeyError as exc:    # a failed run that did not record what the metrics need: keep its reason
        if row["status"] == "ok":
            row["status"], row["reason"] = "failed", f"KeyError: {exc}"
    except Exception as exc:  # a point must never take the sweep down
        row["status"], row["reason"] = "failed", f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    finally:
        if study.keep_runs:
            runs = _packed(work)
        shutil.rmtree(work, ignore_errors=True)
    row["reason"] = unlocalise(row["reason"])
    row["wall_s"] = time.perf_counter() - t0
    return row, runs


def point_status(results: dict[str, Any]) -> tuple[str, str]:
    """A point's status and reason from its runs, in order: the first run a study cannot measure
    (:attr:`RunStatus.measured`) makes it diverged (the system's judge rejected the run) or failed, with
    that run's message; otherwise ok."""
    for name, res in results.items():
        status = RunStatus(res.status)
        if not status.measured:
            return (RunStatus.DIVERGED if status is RunStatus.DIVERGED else RunStatus.FAILED), f"{name}: {res.message}"
    return RunStatus.OK, ""


def requirement_columns(row: dict[str, Any], results: dict[str, Any]) -> None:
    """Each run's requirements into ``row``: ``<run>.<requirement>.robustness`` (in its unit; +-inf for a
    requirement on Booleans alone) and ``<run>.<requirement>.verdict`` (holds, violated, undecided)."""
    for run, res in results.items():
        for v in res.requirements:
            row[f"{run}.{v['name']}.robustness"] = v["robustness"]
            row[f"{run}.{v['name']}.verdict"] = v["verdict"]


def _row(point: dict[str, Any], status: str = "ok", reason: str = "") -> dict[str, Any]:
    """A point's row before its metrics: id, parameters, status and reason."""
    return {"point": point["id"], **point["params"], "status": status, "reason": reason}


def _packed(folder: Path) -> bytes:
    """A folder's files as a gzipped tar (what a worker sends back of a point's runs)."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz", compresslevel=1) as tar:
        for f in sorted(folder.rglob("*")):
            tar.add(f, arcname=f.relative_to(folder).as_posix(), recursive=False)
    return buf.getvalue()


def _unpacked(data: bytes, dest: Path) -> None:
    """The run folders a worker sent back, into ``dest`` (replaced): only plain files and folders inside it."""
    shutil.rmtree(dest, ignore_errors=True)
    dest.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as tar:
        tar.extractall(dest, filter="data")


# ---------------------------------------------------------------------- the sweep (in the parent)
def run_points(points: list[dict[str, Any]], base: str, variant: str | None, runs: list[str] | None,
               out: Path, cluster: Cluster, keep_runs: bool = False, progress: bool | None = None,
               label: str = "sweep", archive_limits: LimitOverrides | None = None, *, system: System,
               measure: Measure | None, shipped: Callable[[ShippingCost], None] | None = None
               ) -> list[dict[str, Any]]:
    """Run the points not yet in ``out/points`` on the cluster; returns every point's row, by id.

    The bases (``base``, or a point's own ``base``) are read here, and every file they name (and the FMU of
    each model name they use, from ``system.models``) is sent to every worker once, by content
    (shipment.py): no worker reads a file of this machine's.  ``shipped`` is told what that cost.
    ``archive_limits`` (a caller's, over each scenario's own), ``measure`` (see :func:`run_point`) and the
    system's judge go with every point.  A point whose worker dies is run again on another (Dask's
    ``allowed-failures``: once on our local cluster); one that kills its worker each time is a failed row.  ``progress``: a bar with
    the time left on a terminal, a line every 5 % of the points (or minute) otherwise; None: on a terminal
    only."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    pts_dir = out / "points"
    rows = _points_done(pts_dir, points)
    todo = [p for p in points if p["id"] not in rows]
    if not todo:
        return [rows[p["id"]] for p in points]
    from ..scenario_files import shipped_folder

    shipment, blobs = pack([p.get("base", base) for p in todo], system.models, shipped_folder())
    shipment, cost = ship(cluster.client, shipment, blobs)
    if shipped is not None:
        shipped(cost)
    study = Study(shipment, base, variant, runs, keep_runs, archive_limits, measure, system.judge)
    failed = sum(1 for r in rows.values() if r["status"] != "ok")
    bar = Progress(label, len(points), len(rows), progress)
    # a point may name its own base (a study over several tasks in one submission)
    futures = {cluster.client.submit(run_point, p, study, key=f"{label}-{out.name}-{p['id']}-{_digest(p, archive_limits)}",
                                     pure=False): p for p in todo}
    try:
        for fut in as_completed(futures):
            try:
                row, kept = fut.result()
            except KilledWorker:
                row = _row(futures[fut], "failed", KILLED)
                row["wall_s"], kept = math.nan, None
            if kept is not None:
                _unpacked(kept, out / "runs" / f"{row['point']:05d}")
            tmp = pts_dir / f"{row['point']:05d}.json.tmp"   # whole, then renamed: a point on disk is complete
            tmp.write_text(json.dumps(row, default=_jsonable))
            os.replace(tmp, pts_dir / f"{row['point']:05d}.json")
            rows[row["point"]] = row
            failed += row["status"] != "ok"
            bar.update(failed)
    finally:
        bar.close()
        for fut in futures:
            fut.cancel()
        unship(cluster.client, shipment)
    return [rows[p["id"]] for p in points]


def _points_done(folder: Path, points: list[dict[str, Any]]) -> dict[int, dict[str, Any]]:
    """The rows of the points already in ``folder`` (made if missing), by id; a half-written one is removed
    (it runs again)."""
    folder.mkdir(parents=True, exist_ok=True)
    rows: dict[int, dict[str, Any]] = {}
    for p in points:
        f = folder / f"{p['id']:05d}.json"
        if f.is_file():
            try:
                rows[p["id"]] = json.loads(f.read_text())
            except json.JSONDecodeError:
                f.unlink()
    return rows


class Progress:
    """Progress over a study's points: a tqdm bar with the time left on a terminal; otherwise (a batch
    job's log) one line at the first point, then every 5 % of the points or every minute, with the time
    left estimated from the points finished in this session.  ``show``: None for a terminal only, False for
    none."""

    def __init__(self, label: str, total: int, done: int, show: bool | None) -> None:
        self.label, self.total, self.done, self.start = label, total, done, done
        self.t0 = self.last = time.monotonic()
        tty = sys.stderr.isatty()
        self.bar: Any = None
        self.lines = bool(show) and not tty
        if tty and show is not False:
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=done, desc=label, unit="point", file=sys.stderr)
        self.every = max(1, total // 20)

    def update(self, failed: int) -> None:
        self.done += 1
        if self.bar is not None:
            self.bar.set_postfix(failed=failed)
            self.bar.update(1)
        elif self.lines:
            now = time.monotonic()
            ran = self.done - self.start
            if ran == 1 or ran % self.every == 0 or self.done == self.total or now - self.last >= 60:
                self.last = now
                print(self.line(failed, now), file=sys.stderr, flush=True)

    def line(self, failed: int, now: float) -> str:
        """"sweep: 12/40 points (1 failed), 1 min 3 s, about 2 min 27 s left"."""
        elapsed = now - self.t0
        ran = self.done - self.start
        left = "" if self.done == self.total or ran == 0 else \
            f", about {_duration(elapsed / ran * (self.total - self.done))} left"
        return f"{self.label}: {self.done}/{count(self.total, 'point')} ({failed} failed), {_duration(elapsed)}{left}"

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _duration(s: float) -> str:
    """'45 s', '3 min 5 s', '2 h 10 min'."""
    s = round(s)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    return f"{s // 3600} h {s % 3600 // 60} min"


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
              security: Any = None, dashboard: bool = False, archive_limits: LimitOverrides | None = None,
              system: System | None = None):
    """Run a sweep file; write results.parquet, results.csv, sweep.json and figures/ into ``out``.
    Returns the table (a pandas DataFrame, one row per point, ordered by point).  ``security`` and
    ``dashboard``: see :class:`Cluster`; ``archive_limits``: the caller's archive limits (a command line's
    options), over each point's scenario's own, sent to the workers with every point; ``system``: the
    system the points run (its model names, its judge of a run: :class:`System`; none by default, every FMU
    named by its path).  The file is checked whole (its parameters and metrics against the base's runs)
    before the results folder is made."""
    from ..cosim import OutputLock, make_folder

    if cluster is None:
        check_worker_count(workers)
    spec = load_sweep(path)
    points = draw_points(spec)
    system = system if system is not None else System()
    measure, units = _measure(spec, system, archive_limits)
    out = make_folder(Path(out) if out is not None else Path("results") / Path(path).stem)
    with OutputLock(out):  # a second sweep into the same folder is refused at once
        return _run_sweep(spec, points, system, measure, units, out, workers, scheduler, progress, cluster, security,
                          dashboard, archive_limits)


def _measure(spec: SweepSpec, system: System, archive_limits: LimitOverrides | None
             ) -> tuple[SweepMeasure, dict[str, str | None]]:
    """What each point measures (the named sets, the file's metrics) and the metrics' units, the file
    checked against the base's runs (their FMUs resolved) before any point runs: the parameters its grid
    and draws set, and its metrics (see :func:`metrics.check_metrics`)."""
    from ..cosim import check_protocol

    base = read_base(spec.base, system.models, archive_limits)
    plans = check_protocol(base, variant=spec.variant, only=spec.runs)
    check_parameters(spec.file, {**{f"grid.{k}": k for k in spec.grid}, **{f"random.{k}": k for k in spec.random}},
                     plans)
    runs = {name: {col: c["unit"] for col, c in plan.columns().items()} for name, plan in plans.items()}
    spans = {name: plan.scenario.times()[:2] for name, plan in plans.items()}
    units = check_metrics(spec.file, spec.measures, runs, spans, _columns(spec, plans))
    return SweepMeasure(tuple(spec.measures), tuple(SETS[s] for s in spec.sets), tuple(runs)), units


def _columns(spec: SweepSpec, plans: dict[str, Any]) -> dict[str, str]:
    """The columns a point's row has besides the file's metrics -> what each holds (a metric of the same
    name would overwrite it)."""
    cols = {c: "the point's own" for c in ("point", "status", "reason", "wall_s")}
    cols.update({ref: "a parameter of the sweep" for key in (*spec.grid, *spec.random) for ref in key.split("+")})
    for s in spec.sets:
        cols.update({c: SETS[s].description for c in SETS[s].columns(list(plans))})
    for run, plan in plans.items():
        for r in plan.requirements:
            cols.update({f"{run}.{r.name}.{c}": "a requirement's" for c in ("robustness", "verdict")})
    return cols


def _run_sweep(spec: SweepSpec, points: list[dict[str, Any]], system: System, measure: SweepMeasure,
               units: dict[str, str | None], out: Path, workers: int | None, scheduler: str | None,
               progress: bool | None, cluster: "Cluster | None", security: Any, dashboard: bool,
               archive_limits: LimitOverrides | None):
    import pandas as pd

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

    def shipped(cost: ShippingCost) -> None:   # what sending the files cost, in sweep.json
        meta["shipping"] = {"bytes": cost.bytes, "seconds": round(cost.seconds, 6), "workers": {
            w: {"written": n, "cached": c, "seconds": round(t, 6)} for w, (n, c, t) in sorted(cost.workers.items())}}
        meta_file.write_text(json.dumps(meta, indent=1) + "\n")

    try:
        rows = run_points(points, spec.base, spec.variant, spec.runs, out, cl, spec.keep_runs, progress,
                          archive_limits=archive_limits, system=system, measure=measure, shipped=shipped)
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
