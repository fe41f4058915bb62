"""Sweeps and Monte Carlo studies on Dask: many full co-simulations, each point in a worker process.

A sweep file (``scenarios/sweep-*.toml``)::

    base = "paper/g1.toml"        # a scenario or protocol file (its runs: learn, frozen, foam, ...)
    variant = "freeze"            # optional: a variant the base declares
    runs = ["learn", "frozen", "foam"]   # optional: which of its runs (default all)
    seed = 1                      # for the random draws
    samples = 8                   # random draws per grid point (default 1)
    metrics = ["foam.rmse_e1", "gamma_star"]   # the columns to plot (the table keeps every metric)
    [grid]                        # the cartesian product of these
    "plant.foam_da1+plant.foam_da2" = [0.2, 0.4, 0.8]   # '+' links parameters to one value
    [random]                      # drawn with the seed, `samples` times per grid point
    "plant.foam_t_on" = { dist = "uniform", low = 7.0, high = 10.0 }
    "controller.l1" = { dist = "normal", mean = 0.16, std = 0.004 }

Every point runs the base's runs with its parameter values; the results are one row per point (the
parameters, status, reason, metrics) in ``results.parquet`` and ``results.csv``, plots in ``figures/``.
Each finished point is written at once to ``points/<id>.json``: a sweep interrupted and started again
with the same output folder skips the points already done and gives the same final table.  Points are
drawn in the parent from the seed, so the results do not depend on the number of workers.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import shutil
import sys
import tempfile
import time
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .cosim.errors import CosimError, ScenarioError

DISTRIBUTIONS = {"uniform": ("low", "high"), "normal": ("mean", "std"), "lognormal": ("mean", "sigma"),
                 "choice": ("values",)}
_KEYS = {"description", "base", "variant", "runs", "seed", "samples", "metrics", "grid", "random", "keep_runs"}


@dataclass
class SweepSpec:
    file: str
    base: str
    variant: str | None = None
    runs: list[str] | None = None
    seed: int = 0
    samples: int = 1
    metrics: list[str] = field(default_factory=list)
    grid: dict[str, list[Any]] = field(default_factory=dict)       # "a.x+b.y" -> values
    random: dict[str, dict[str, Any]] = field(default_factory=dict)
    keep_runs: bool = False
    description: str = ""


def load_sweep(path: str | os.PathLike) -> SweepSpec:
    """Read and check a sweep file; errors name the file, the field and the reason."""
    path = Path(path)
    f = str(path)
    if not path.is_file():
        raise ScenarioError(f, "", "file not found")
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f, "", f"not valid TOML ({exc})") from None
    for k in doc:
        if k not in _KEYS:
            raise ScenarioError(f, k, f"unknown key (allowed: {', '.join(sorted(_KEYS))})")
    base = doc.get("base")
    if not isinstance(base, str) or not (path.parent / base).is_file():
        raise ScenarioError(f, "base", f"{base!r}: the scenario file to sweep is missing")
    spec = SweepSpec(f, str((path.parent / base).resolve()), doc.get("variant"), doc.get("runs"),
                     description=str(doc.get("description", "")))
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f, "seed", f"{seed!r}: must be an integer >= 0")
    spec.seed = seed
    samples = doc.get("samples", 1)
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ScenarioError(f, "samples", f"{samples!r}: must be an integer >= 1")
    spec.samples = samples
    metrics = doc.get("metrics", [])
    if not isinstance(metrics, list) or not all(isinstance(m, str) for m in metrics):
        raise ScenarioError(f, "metrics", "must be an array of metric names")
    spec.metrics = metrics
    if spec.runs is not None and (not isinstance(spec.runs, list) or not all(isinstance(r, str) for r in spec.runs)):
        raise ScenarioError(f, "runs", "must be an array of run names")
    keep = doc.get("keep_runs", False)
    if not isinstance(keep, bool):
        raise ScenarioError(f, "keep_runs", "must be true or false")
    spec.keep_runs = keep
    grid = doc.get("grid", {})
    if not isinstance(grid, dict):
        raise ScenarioError(f, "grid", "must be a table \"instance.param\" = [values]")
    for key, values in grid.items():
        _refs(f, f"grid.{key}", key)
        if not isinstance(values, list) or not values:
            raise ScenarioError(f, f"grid.{key}", "must be a non-empty array of values")
        spec.grid[key] = list(values)
    rnd = doc.get("random", {})
    if not isinstance(rnd, dict):
        raise ScenarioError(f, "random", "must be a table \"instance.param\" = {dist = ..., ...}")
    for key, d in rnd.items():
        fld = f"random.{key}"
        _refs(f, fld, key)
        if not isinstance(d, dict) or d.get("dist") not in DISTRIBUTIONS:
            raise ScenarioError(f, fld, f"needs dist = one of {', '.join(DISTRIBUTIONS)}")
        need = DISTRIBUTIONS[d["dist"]]
        extra = set(d) - set(need) - {"dist"}
        if extra:
            raise ScenarioError(f, f"{fld}.{sorted(extra)[0]}", f"unknown key for dist = {d['dist']!r}")
        for k in need:
            if k not in d:
                raise ScenarioError(f, f"{fld}.{k}", f"missing (dist = {d['dist']!r} needs {', '.join(need)})")
        if d["dist"] == "uniform" and not d["low"] < d["high"]:
            raise ScenarioError(f, f"{fld}.high", "must be above low")
        if d["dist"] in ("normal",) and not d["std"] >= 0:
            raise ScenarioError(f, f"{fld}.std", "must be >= 0")
        spec.random[key] = dict(d)
    # the base must parse (model names are not built here), and the variant and runs must exist
    from .cosim.protocol import plan_runs

    _, runs, _ = plan_runs(spec.base, lambda name: Path(name), spec.variant)
    if spec.runs:
        names = [r.name for r in runs]
        for r in spec.runs:
            if r not in names:
                raise ScenarioError(f, "runs", f"{r!r} is not a run of {spec.base} ({', '.join(names)})")
    return spec


def _refs(file: str, fld: str, key: str) -> list[str]:
    refs = key.split("+")
    for r in refs:
        if r.count(".") < 1 or not all(r.split(".", 1)):
            raise ScenarioError(file, fld, f"{r!r} is not of the form \"instance.param\"")
    return refs


def draw_points(spec: SweepSpec) -> list[dict[str, Any]]:
    """Every point: {'id': i, 'params': {'instance.param': value}}; random values drawn from the seed."""
    rng = np.random.default_rng(spec.seed)
    grid_keys = list(spec.grid)
    combos = list(itertools.product(*(spec.grid[k] for k in grid_keys))) if grid_keys else [()]
    out = []
    for combo in combos:
        for _ in range(spec.samples):
            params: dict[str, Any] = {}
            for key, value in zip(grid_keys, combo):
                for ref in key.split("+"):
                    params[ref] = value
            for key, d in spec.random.items():
                if d["dist"] == "uniform":
                    v = float(rng.uniform(d["low"], d["high"]))
                elif d["dist"] == "normal":
                    v = float(rng.normal(d["mean"], d["std"]))
                elif d["dist"] == "lognormal":
                    v = float(rng.lognormal(d["mean"], d["sigma"]))
                else:
                    v = d["values"][int(rng.integers(len(d["values"])))]
                for ref in key.split("+"):
                    params[ref] = v
            out.append({"id": len(out), "params": params})
    return out


# ---------------------------------------------------------------------- one point (in a worker)
def run_point(point: dict[str, Any], base: str, variant: str | None, runs: list[str] | None,
              fmus: dict[str, str], out_dir: str, keep_runs: bool = False,
              archive_limits: dict[str, str] | None = None) -> dict[str, Any]:
    """Run one point (the base's runs with the point's parameters) and return its row: id, parameters,
    status ('ok', 'diverged', 'failed'), reason and metrics.  Never raises: a failure is a row.
    ``archive_limits``: the submitting process's command-line archive limits (a worker may be elsewhere)."""
    from .analysis import disturbance_analysis, divergence, load_signals, run_summary
    from .cosim.archive import ENV_RATIO, ENV_SIZE
    from .cosim.protocol import run_protocol

    for k in (ENV_SIZE, ENV_RATIO):     # the submitter's, not those of an earlier sweep on this worker
        if archive_limits and k in archive_limits:
            os.environ[k] = archive_limits[k]
        else:
            os.environ.pop(k, None)

    row: dict[str, Any] = {"point": point["id"], **point["params"], "status": "ok", "reason": ""}
    work = Path(out_dir) / "runs" / f"{point['id']:05d}" if keep_runs else Path(tempfile.mkdtemp(prefix="wmr-sweep-"))
    t0 = time.perf_counter()
    try:
        results = run_protocol(base, work, lambda name: Path(fmus[name]) if name in fmus else None,
                               variant=variant, overrides=point["params"], progress=False, only=runs)
        sigs = {}
        for name, res in results.items():
            if res.status != "ok" and row["status"] == "ok":   # the first failed run's message is the reason
                row["status"], row["reason"] = "failed", f"{name}: {res.message}"
                if not (work / name / "signals.npy").is_file():
                    continue
            sig = load_signals(work / name)
            sigs[name] = sig
            goal = _goal(work / name)
            s = run_summary(sig, goal, res.status)
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
        if sigs.get("frozen") is not None and sigs.get("foam") is not None:
            d = disturbance_analysis(sigs["frozen"], sigs["foam"], **_weights(work / "foam"))
            for k in ("gamma_star", "gamma_true", "gain_incremental"):
                row[k] = d[k] if d[k] is not None else math.nan
            row["foam_rise1"], row["foam_rise2"] = [math.nan if r is None else r for r in d["foam_rise"]]
            row["edge_peak_u"] = d["edge_peak_u"] if d["edge_peak_u"] is not None else math.nan
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
    from .components.controller import ControllerParams

    defaults = ControllerParams()
    w = {"Q": defaults.Q, "R": defaults.R}
    p = _controller_parameters(run_dir) or {}
    return {k: float(p.get(k, v)) for k, v in w.items()}


# ---------------------------------------------------------------------- the sweep (in the parent)
def fmu_paths() -> dict[str, str]:
    """Our three FMUs, built if needed, as absolute paths (workers must see the same file system)."""
    from .runner import resolve_model

    return {m: str(resolve_model(m).resolve()) for m in ("WmrPlant", "WmrSensor", "WmrController")}


def dask_security(ca_file: str | None = None, cert: str | None = None, key: str | None = None) -> Any:
    """A ``distributed.security.Security`` for a ``tls://`` scheduler from PEM files (the CA that signed
    the scheduler's certificate, this client's certificate and its private key), requiring encryption;
    None when no file is given (Dask's configuration then applies).  CosimError if one is missing."""
    given = {"--tls-ca-file": ca_file, "--tls-cert": cert, "--tls-key": key}
    if not any(given.values()):
        return None
    for opt, f in given.items():
        if not f:
            raise CosimError(f"{opt}: missing (TLS needs --tls-ca-file, --tls-cert and --tls-key together)")
        if not Path(f).is_file():
            raise CosimError(f"{opt} {f}: file not found")
    from distributed.security import Security

    return Security(tls_ca_file=str(ca_file), tls_client_cert=str(cert), tls_client_key=str(key),
                    require_encryption=True)


def cluster_options(args: Any) -> dict[str, Any]:
    """The Dask keyword arguments of :func:`run_sweep` and ``gamma_search`` from the command line's options
    (``--workers``, ``--scheduler``, ``--dashboard``, ``--tls-ca-file``, ``--tls-cert``, ``--tls-key``)."""
    sec = dask_security(getattr(args, "tls_ca_file", None), getattr(args, "tls_cert", None),
                        getattr(args, "tls_key", None))
    if sec is not None and not (args.scheduler or "").startswith("tls://"):
        raise CosimError("--tls-ca-file/--tls-cert/--tls-key: need --scheduler tls://HOST:PORT")
    return {"workers": args.workers, "scheduler": args.scheduler, "security": sec,
            "dashboard": bool(getattr(args, "dashboard", False))}


def cleartext_warning(address: str) -> str | None:
    """A one-line warning for a scheduler reached in clear text beyond this machine (``tcp://`` to an
    address other than the loopback), or None."""
    from urllib.parse import urlsplit

    if not address.startswith("tcp://"):
        return None
    host = urlsplit(address).hostname or ""
    if host == "localhost" or host.startswith("127.") or host == "::1":
        return None
    return (f"wmr-cosim: warning: {address} is neither encrypted nor authenticated, and a Dask scheduler runs "
            "whatever it is sent: use tls:// unless every host that can reach it is trusted (docs/security.md)")


class Cluster:
    """A Dask client: a local cluster of ``workers`` processes (one thread each), or an existing
    scheduler at ``address`` (``tcp://`` or, with certificates, ``tls://``).

    The local cluster listens on the loopback address only (scheduler, workers and the scheduler's HTTP
    endpoint); its dashboard is off unless ``dashboard`` is true, and then it too listens on the loopback
    address only, and its address is printed on stderr.  ``security`` (a ``distributed.security.Security``,
    see :func:`dask_security`) gives the certificates for a ``tls://`` scheduler; without it Dask's own
    configuration (``distributed.comm.tls.*``) applies.  A Dask scheduler runs whatever code it is sent:
    see docs/security.md.
    """

    def __init__(self, workers: int | None = None, address: str | None = None, security: Any = None,
                 dashboard: bool = False) -> None:
        import logging

        from distributed import Client, LocalCluster

        t0 = time.perf_counter()
        self.cluster = None
        self.scratch: Path | None = None
        if address:
            warning = cleartext_warning(address)
            if warning:
                print(warning, file=sys.stderr)
            try:
                self.client = Client(address, timeout="10s", security=security)
            except Exception as exc:
                hint = ""
                if address.startswith("tls://") and security is None:
                    hint = "; a tls:// scheduler needs --tls-ca-file, --tls-cert and --tls-key (or Dask's configuration)"
                raise CosimError(f"--scheduler {address}: cannot connect ({' '.join(str(exc).split())}){hint}") from None
        else:
            # the scheduler's HTTP endpoint always runs: on the loopback address, at a free port, and it
            # serves the dashboard only when asked for (":0" would listen on every interface); the workers'
            # scratch folder is this cluster's own, removed on close (Dask leaves its default,
            # dask-scratch-space in the temporary folder, behind)
            self.scratch = Path(tempfile.mkdtemp(prefix="wmr-dask-"))
            try:
                sched = {"local_directory": str(self.scratch)}
                if not dashboard:
                    sched["dashboard_address"] = "127.0.0.1:0"
                self.cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                                            processes=True, host="127.0.0.1",
                                            dashboard_address="127.0.0.1:0" if dashboard else None,
                                            scheduler_kwargs=sched, local_directory=str(self.scratch),
                                            silence_logs=logging.ERROR)
                self.client = Client(self.cluster)
            except BaseException:
                if self.cluster is not None:
                    self.cluster.close()
                shutil.rmtree(self.scratch, ignore_errors=True)
                raise
        self.dashboard = self.client.dashboard_link if dashboard else None
        if self.dashboard:
            print(f"dask dashboard: {self.dashboard}", file=sys.stderr)
        self.startup_s = time.perf_counter() - t0

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        if self.scratch is not None:
            shutil.rmtree(self.scratch, ignore_errors=True)

    def __enter__(self) -> "Cluster":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def run_points(points: list[dict[str, Any]], base: str, variant: str | None, runs: list[str] | None,
               out: Path, cluster: Cluster, keep_runs: bool = False, progress: bool | None = None,
               label: str = "sweep") -> list[dict[str, Any]]:
    """Run the points not yet in ``out/points`` on the cluster; returns every point's row, by id."""
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
    fmus = fmu_paths()
    bar = None
    if progress is None:
        progress = sys.stderr.isatty()
    if progress and todo:
        from tqdm import tqdm
        bar = tqdm(total=len(points), initial=len(rows), desc=label, unit="run", file=sys.stderr)
    failed = sum(1 for r in rows.values() if r["status"] != "ok")
    from .cosim.archive import command_line_limits

    limits = command_line_limits()
    # a point may name its own base (a study over several tasks in one submission)
    futures = [cluster.client.submit(run_point, p, p.get("base", base), variant, runs, fmus, str(out), keep_runs, limits,
                                     key=f"{label}-{out.name}-{p['id']}-{_digest(p)}", pure=False) for p in todo]
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


def _digest(p: dict[str, Any]) -> str:
    return hashlib.sha1(json.dumps(p, sort_keys=True, default=str).encode()).hexdigest()[:8]


def _jsonable(x: Any) -> Any:
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return str(x)


def run_sweep(path: str | os.PathLike, out: str | os.PathLike | None = None, workers: int | None = None,
              scheduler: str | None = None, progress: bool | None = None, cluster: Cluster | None = None,
              security: Any = None, dashboard: bool = False):
    """Run a sweep file; write results.parquet, results.csv, sweep.json and figures/ into ``out``.
    Returns the table (a pandas DataFrame, one row per point, ordered by point).  ``security`` and
    ``dashboard``: see :class:`Cluster`."""
    from .cosim.recording import OutputLock, make_folder

    spec = load_sweep(path)
    out = make_folder(Path(out) if out is not None else Path("results") / Path(path).stem)
    with OutputLock(out):  # a second sweep into the same folder is refused at once
        return _run_sweep(spec, out, workers, scheduler, progress, cluster, security, dashboard)


def _run_sweep(spec: "SweepSpec", out: Path, workers: int | None, scheduler: str | None, progress: bool | None,
               cluster: "Cluster | None", security: Any, dashboard: bool):
    import pandas as pd

    points = draw_points(spec)
    meta = {"spec": asdict(spec), "points": points}
    meta_file = out / "sweep.json"
    if meta_file.is_file():
        old = json.loads(meta_file.read_text())
        if old.get("points") != json.loads(json.dumps(points)) or old["spec"]["base"] != spec.base:
            raise CosimError(f"{out}: holds the results of another sweep (different points); use another --out")
    meta_file.write_text(json.dumps(meta, indent=1) + "\n")
    own = cluster is None
    cl = cluster or Cluster(workers, scheduler, security, dashboard)
    try:
        rows = run_points(points, spec.base, spec.variant, spec.runs, out, cl, spec.keep_runs, progress)
    finally:
        if own:
            cl.close()
    df = pd.DataFrame(rows).sort_values("point").reset_index(drop=True)
    for name, write in (("results.parquet", df.to_parquet), ("results.csv", df.to_csv)):
        part = out / f"{name}.part"   # written whole, then renamed: a file that exists is complete
        write(part, index=False)
        os.replace(part, out / name)
    plot_sweep(df, spec, out / "figures")
    return df


def plot_sweep(df, spec: SweepSpec, out: Path) -> list[Path]:
    """Each chosen metric against each swept parameter (failed points marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    params = []
    for key in list(spec.grid) + list(spec.random):
        params.append(key.split("+")[0])
    metrics = spec.metrics or [c for c in ("foam.rmse_e1", "learn.rmse_e1", "gamma_star") if c in df.columns][:2]
    files = []
    for m in metrics:
        if m not in df.columns:
            continue
        for p in params:
            fig, ax = plt.subplots(figsize=(5.5, 3.8))
            ok = df["status"] == "ok"
            ax.plot(df.loc[ok, p], df.loc[ok, m], "o", ms=4, label="ok")
            if (~ok).any():
                ax.plot(df.loc[~ok, p], df.loc[~ok, m].fillna(0.0), "x", color="C3", label="failed / diverged")
            ax.set_xlabel(f"{p} [{_unit(p)}]")
            ax.set_ylabel(f"{m} [{_unit(m)}]")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
            fig.tight_layout()
            f = out / f"{m}_vs_{p}.png".replace("/", "_")
            fig.savefig(f, dpi=100)
            plt.close(fig)
            files.append(f)
    return files


_UNITS = {"rmse_e": "rad", "rmse_edot": "rad/s", "final_x": "m", "final_y": "m", "t_goal": "s", "goal_distance": "m",
          "gamma": "-", "gain": "-", "foam_rise": "N.m", "foam_da": "N.m", "foam_t_on": "s", "l1": "m", "r": "m",
          "a5": "N.m", "a6": "N.m", "goal_": "m", "W": "-"}


def _unit(name: str) -> str:
    last = name.rsplit(".", 1)[-1]
    for k, u in _UNITS.items():
        if last.startswith(k):
            return u
    return "-"
