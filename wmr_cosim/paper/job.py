"""``wmr-cosim paper``: every experiment of section 5 of the paper through the FMU co-simulation, the
analysis, the figures and the report.

The protocol is data: ``scenarios/paper.toml`` (shipped with the package) names one protocol file per task (``scenarios/paper/``),
each declaring its runs (learn, frozen, foam) and the variants.  Tasks run in parallel worker processes;
each task's runs run in order (the frozen and foam runs start from the learning run's final W and P).
The tasks file is read by tasks.py, the report written section by section by report.py.
"""
from __future__ import annotations

import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from ..cosim import LimitOverrides, RunStatus

from .analysis import (RUNS, Signals, fidelity, load_signals, position_error, requirement_verdicts, run_summary,
                       table1_disturbance_analysis)
from ..components import paper
from .report import claims, provenance, report_blocks
from .tasks import task_files
from .document import to_html, to_markdown

VARIANTS = ("freeze", "printed")


def run_line(variant: str, task: str, run: str, res: Any) -> str:
    """The progress line of one finished run: variant, task, run, status (the reason when it did not end
    'ok') and wall time (set-up and stepping) [s]."""
    how = res.status if res.status == RunStatus.OK else f"{res.status} ({res.message})"
    return f"wmr-cosim paper: {variant} {task} {run}: {how}, {res.setup_s + res.wall_s:.1f} s"


def build_fmus(fmi: int = 2, out_dir: Path | None = None, progress: bool = True) -> dict[str, Path]:
    """Our three FMUs of FMI version ``fmi`` (WmrPlant, WmrSensor, WmrController, or their FMI 3.0 versions)
    built into ``out_dir`` (default: where model names resolve, fmus.build.default_out_dir) where missing or
    out of date; {model: .fmu}.  When any has to be built (a first run, or its sources changed), one line
    on stderr says which and where first, unless ``progress`` is False: a build takes a while, and the job
    says nothing else until its first run ends.  CosimError (one line) when a build fails."""
    from ..cosim import CosimError
    from ..fmus.build import BuildError, build_all, default_out_dir, models_for, up_to_date

    out = Path(out_dir) if out_dir is not None else default_out_dir()
    models = models_for(fmi)
    stale = [m for m, current in up_to_date(out, models).items() if not current]
    if stale and progress:
        why = "first run" if not any((out / f"{m}.fmu").is_file() for m in stale) else "their sources changed"
        print(f"wmr-cosim paper: building the FMUs ({why}): {', '.join(stale)} into {out}", file=sys.stderr,
              flush=True)
    try:
        return build_all(out, models=models)
    except BuildError as exc:
        raise CosimError(f"building {', '.join(stale)}: {' '.join(str(exc).split())}") from None


def _task_job(task: str, file: str, folder: str, variant: str, fmi: int = 2, progress: bool = False,
              archive_limits: LimitOverrides | None = None) -> dict[str, Any]:
    """One task's protocol in a worker process: {run: {status, message, wall_s, setup_s}}; ``fmi`` 3 runs it
    through the FMI 3.0 FMUs (runner.resolver, runner.carry_fmi3).  Each run is judged by
    analysis.divergence as it finishes; with ``progress``, its line (:func:`run_line`) goes to stderr.
    ``archive_limits``: the caller's, over the protocol's own (they come with the job: nothing else
    reaches the worker)."""
    from ..runner import carry_fmi3, resolver, run_protocol
    from .analysis import judge_run

    def report(run: str, res: Any) -> None:
        if progress:
            print(run_line(variant, task, run, res), file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    results = run_protocol(file, folder, resolver(fmi), variant=variant, progress=False,
                           carry=carry_fmi3 if fmi == 3 else None, on_run=report, judge=judge_run,
                           limits=archive_limits)
    return {"task": task, "variant": variant, "wall_s": time.perf_counter() - t0,
            "runs": {n: {"status": r.status, "message": r.message, "wall_s": r.wall_s, "setup_s": r.setup_s,
                         "steps": r.steps} for n, r in results.items()}}


def analyse(folder: Path, statuses: dict[str, dict[str, dict[str, Any]]]
            ) -> tuple[dict[str, Any], dict[str, dict[str, Signals | None]], dict[str, dict[str, Any]]]:
    """metrics.json content of one variant from its run folders; also the signals and the (52)/(53) curves."""
    signals: dict[str, dict[str, Signals | None]] = {}
    tasks: dict[str, Any] = {}
    dist: dict[str, Any] = {}
    out: dict[str, Any] = {"tasks": tasks, "gamma_star": {}, "gamma_true": {}, "gain_incremental": {}}
    for task in paper.TASKS:
        if task not in statuses:
            continue
        goal = paper.task_goal(task)
        signals[task] = {}
        tasks[task] = {}
        for run in RUNS:
            st = statuses[task].get(run, {"status": "missing"})
            sig = load_signals(folder / task / run)
            signals[task][run] = sig
            summ = run_summary(sig, goal, st["status"])
            summ["position_error_to_paper"] = position_error(task, summ.get("final_position")) if run == "learn" else None
            summ["requirements"] = requirement_verdicts(folder / task / run)
            tasks[task][run] = summ
        fr, fo = signals[task].get("frozen"), signals[task].get("foam")
        if fr is not None and fo is not None:
            d = table1_disturbance_analysis(fr, fo)
            dist[task] = d
            out["gamma_star"][task] = d["gamma_star"]
            out["gamma_true"][task] = d["gamma_true"]
            out["gain_incremental"][task] = d["gain_incremental"]
            tasks[task]["foam"]["foam_rise"] = d["foam_rise"]
            tasks[task]["foam"]["t_F"] = d["t_F"]
            tasks[task]["foam"]["edge_peak_u"] = d["edge_peak_u"]
            tasks[task]["foam"]["edge_peak_u_frozen"] = d["edge_peak_u_frozen"]
            tasks[task]["foam"]["foam_da"] = foam_change(folder / task / "foam")
    out["fidelity"] = {k: v for k, v in fidelity(tasks).items()}
    out["diverged_runs"] = [f"{t}.{r}" for t in tasks for r in RUNS if tasks[t].get(r, {}).get("diverged")]
    return out, signals, dist


def unfinished_runs(m: dict[str, Any]) -> list[str]:
    """The runs ("G1.frozen") of one variant's metrics that did not run to their end: failed (an FMU error,
    a non-finite value), interrupted, or missing."""
    return [f"{t}.{r}" for t, runs in m["tasks"].items() for r in RUNS
            if not _reached_stop(runs.get(r, {}).get("status", "missing"))]


def _reached_stop(status: str) -> bool:
    """A recorded status (or "missing") of a run that ran to its end (:attr:`RunStatus.reached_stop`)."""
    return status in RunStatus.__members__.values() and RunStatus(status).reached_stop


def exit_code(variants: dict[str, dict[str, Any]], variant: str) -> int:
    """The exit code of ``wmr-cosim paper`` from the metrics of each variant run ({variant: metrics}):
    1 when a run of the chosen ``variant`` (``--variant``, the one the report describes) diverged or did not
    finish, or a run of a compared variant did not finish (an error is an error whichever variant it is
    of); else 0.  A compared variant's diverged runs are a result the report shows and the command prints,
    not a failure of the job (the printed reading diverges on six of its runs)."""
    from ..exit_codes import OK, RUN_FAILED

    if variants[variant]["diverged_runs"] or any(unfinished_runs(m) for m in variants.values()):
        return RUN_FAILED
    return OK


def foam_change(run: Path) -> list[float] | None:
    """The friction change the foam run assumed, [da1, da2] [N.m], from its resolved scenario (None if not
    recorded)."""
    try:
        params = json.loads((run / "scenario.json").read_text())["instances"]["plant"]["parameters"]
        return [float(params["foam_da1"]), float(params["foam_da2"])]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _clean(x: Any) -> Any:
    """JSON without NaN/inf (null instead) and without numpy types."""
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if hasattr(x, "item"):
        return _clean(x.item())
    return x


def run_paper(out: str | os.PathLike = "results/paper", variant: str = "freeze", compare: bool = True,
              workers: int | None = None, manifest: str | os.PathLike | None = None,
              progress: bool | None = None, figures: bool = True, robustness: bool = False,
              robustness_grid: Any = None, fmi: int = 2, archive_limits: LimitOverrides | None = None
              ) -> dict[str, Any]:
    """Run every task of the manifest for ``variant`` (and, with ``compare``, the other variants too),
    analyse, draw the figures and write report.md, report.html and metrics.json into ``out``; ``fmi``
    3 runs the FMI 3.0 versions of the FMUs (the same numbers).  Unless ``progress`` is False, one line per
    finished run (variant, task, run, status, wall time) goes to stderr, also when it is not a terminal.

    With ``robustness``, also the robustness study and the study of when W stops adapting
    (robustness.py; ``robustness_grid`` a StudyGrid, default the full one) into ``out/robustness``.
    ``archive_limits``: the caller's archive limits (a command line's options), over each protocol's own,
    passed to every worker process with its job.  A second job into the same ``out`` is refused at once (a lock naming the holder's process)."""
    from ..cosim import OutputLock, make_folder

    out = make_folder(Path(out))
    with OutputLock(out):
        return _run_paper(out, variant, compare, workers, manifest, progress, figures, robustness,
                          robustness_grid, fmi, archive_limits)


def _run_paper(out: Path, variant: str, compare: bool, workers: int | None, manifest: str | os.PathLike | None,
               progress: bool | None, figures: bool, robustness: bool, robustness_grid: Any, fmi: int,
               archive_limits: LimitOverrides | None) -> dict[str, Any]:
    tasks = task_files(manifest)
    variants = [variant] + ([v for v in VARIANTS if v != variant] if compare else [])
    progress = progress is not False     # one line per finished run, also when stderr is not a terminal
    t0 = time.perf_counter()
    build_fmus(fmi, progress=progress)   # once, before the workers start
    folders = {v: out / "runs" if v == variant else out / "variants" / v / "runs" for v in variants}
    jobs = [(task, str(f), str(folders[v] / task), v, fmi, progress, archive_limits)
            for v in variants for task, f in tasks.items()]
    statuses: dict[str, dict[str, dict[str, Any]]] = {v: {} for v in variants}
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(_task_job, *job) for job in jobs]
        for fut in as_completed(futures):
            r = fut.result()
            statuses[r["variant"]][r["task"]] = r["runs"]
    study = study_fig = None
    if robustness:
        from .robustness import job_grid, run_study
        study = run_study(out / "robustness", job_grid(robustness_grid, manifest, tuple(tasks)), workers=workers,
                          progress=None if progress else False, archive_limits=archive_limits)
    results: dict[str, Any] = {}
    made_by = provenance()
    main: tuple[dict[str, dict[str, Signals | None]], dict[str, dict[str, Any]]] | None = None
    for v in variants:
        m, sig, dist = analyse(folders[v], statuses[v])
        m = _clean({"variant": v, "provenance": made_by, **m, **(study if study and v == variant else {})})
        m["claims"] = claims(m)
        results[v] = m
        target = out if v == variant else out / "variants" / v
        (target / "metrics.json").write_text(json.dumps(m, indent=2) + "\n")
        if v == variant:
            main = sig, dist
    files = []
    if figures and main is not None:
        from .figures import render_all
        files = render_all(*main, out / "figures")
        if study:
            from .figures import fig_robustness
            study_fig = fig_robustness(study["robustness"], out / "figures")
    wall = time.perf_counter() - t0
    blocks = report_blocks(results, variant, files, out, wall, study, study_fig)
    (out / "report.md").write_text(to_markdown(blocks, out))
    (out / "report.html").write_text(to_html(blocks, "wmr-cosim: the paper's experiments"))
    return {"metrics": results[variant], "variants": results, "wall_s": wall, "out": out, "figures": files}
