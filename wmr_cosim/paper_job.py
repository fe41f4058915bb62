"""``wmr-cosim paper``: every experiment of section 5 of the paper through the FMU co-simulation, the
analysis, the figures and the report.

The protocol is data: ``scenarios/paper.toml`` (shipped with the package) names one protocol file per task (``scenarios/paper/``),
each declaring its runs (learn, frozen, foam) and the variants.  Tasks run in parallel worker processes;
each task's runs run in order (the frozen and foam runs start from the learning run's final W and P).
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

from .cosim.status import RunStatus

from .analysis import (RUNS, fidelity, load_signals, position_error, run_summary,
                       table1_disturbance_analysis)
from .components import paper
from .paper_report import claims, provenance
from .paper_tasks import DEFAULT_MANIFEST, task_files  # noqa: F401  (DEFAULT_MANIFEST: also read from here)
from .report import fmt, to_html, to_markdown

VARIANTS = ("freeze", "printed")


def run_line(variant: str, task: str, run: str, res: Any) -> str:
    """The progress line of one finished run: variant, task, run, status (the reason when it did not end
    'ok') and wall time (set-up and stepping) [s]."""
    how = res.status if res.status == RunStatus.OK else f"{res.status} ({res.message})"
    return f"wmr-cosim paper: {variant} {task} {run}: {how}, {res.setup_s + res.wall_s:.1f} s"


def _task_job(task: str, file: str, folder: str, variant: str, fmi: int = 2, progress: bool = False
              ) -> dict[str, Any]:
    """One task's protocol in a worker process: {run: {status, message, wall_s, setup_s}}; ``fmi`` 3 runs it
    through the FMI 3.0 FMUs (runner.resolver, runner.carry_fmi3).  Each run is judged by
    analysis.divergence as it finishes; with ``progress``, its line (:func:`run_line`) goes to stderr."""
    from .runner import carry_fmi3, resolver, run_protocol

    def report(run: str, res: Any) -> None:
        if progress:
            print(run_line(variant, task, run, res), file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    results = run_protocol(file, folder, resolver(fmi), variant=variant, progress=False,
                           carry=carry_fmi3 if fmi == 3 else None, on_run=report)
    return {"task": task, "variant": variant, "wall_s": time.perf_counter() - t0,
            "runs": {n: {"status": r.status, "message": r.message, "wall_s": r.wall_s, "setup_s": r.setup_s,
                         "steps": r.steps} for n, r in results.items()}}


def analyse(folder: Path, statuses: dict[str, dict[str, dict[str, Any]]]) -> tuple[dict[str, Any], dict, dict]:
    """metrics.json content of one variant from its run folders; also the signals and the (52)/(53) curves."""
    signals: dict[str, dict[str, Any]] = {}
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
              robustness_grid: Any = None, fmi: int = 2) -> dict[str, Any]:
    """Run every task of the manifest for ``variant`` (and, with ``compare``, the other variants too),
    analyse, draw the figures and write report.md, report.html and metrics.json into ``out``; ``fmi``
    3 runs the FMI 3.0 versions of the FMUs (the same numbers).  Unless ``progress`` is False, one line per
    finished run (variant, task, run, status, wall time) goes to stderr, also when it is not a terminal.

    With ``robustness``, also the robustness study and the study of when W stops adapting
    (robustness.py; ``robustness_grid`` a StudyGrid, default the full one) into ``out/robustness``.
    A second job into the same ``out`` is refused at once (a lock naming the holder's process)."""
    from .cosim.recording import OutputLock, make_folder

    out = make_folder(Path(out))
    with OutputLock(out):
        return _run_paper(out, variant, compare, workers, manifest, progress, figures, robustness,
                          robustness_grid, fmi)


def _run_paper(out: Path, variant: str, compare: bool, workers: int | None, manifest: str | os.PathLike | None,
               progress: bool | None, figures: bool, robustness: bool, robustness_grid: Any, fmi: int
               ) -> dict[str, Any]:
    from .runner import resolver

    resolve_model = resolver(fmi)
    tasks = task_files(manifest)
    variants = [variant] + ([v for v in VARIANTS if v != variant] if compare else [])
    progress = progress is not False     # one line per finished run, also when stderr is not a terminal
    t0 = time.perf_counter()
    for model in ("WmrPlant", "WmrSensor", "WmrController"):  # build once, before the workers start
        resolve_model(model)
    folders = {v: out / "runs" if v == variant else out / "variants" / v / "runs" for v in variants}
    jobs = [(task, str(f), str(folders[v] / task), v, fmi, progress) for v in variants for task, f in tasks.items()]
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
                          progress=None if progress else False)
    results: dict[str, Any] = {}
    made_by = provenance()
    main_signals = main_dist = None
    for v in variants:
        m, sig, dist = analyse(folders[v], statuses[v])
        m = _clean({"variant": v, "provenance": made_by, **m, **(study if study and v == variant else {})})
        m["claims"] = claims(m)
        results[v] = m
        target = out if v == variant else out / "variants" / v
        (target / "metrics.json").write_text(json.dumps(m, indent=2) + "\n")
        if v == variant:
            main_signals, main_dist = sig, dist
    files = []
    if figures and main_signals is not None:
        from .figures import render_all
        files = render_all(main_signals, main_dist, out / "figures")
        if study:
            from .figures import fig_robustness
            study_fig = fig_robustness(study["robustness"], out / "figures")
    wall = time.perf_counter() - t0
    blocks = report_blocks(results, variant, files, out, wall, study, study_fig)
    (out / "report.md").write_text(to_markdown(blocks, out))
    (out / "report.html").write_text(to_html(blocks, "wmr-cosim: the paper's experiments"))
    return {"metrics": results[variant], "variants": results, "wall_s": wall, "out": out, "figures": files}


# ---------------------------------------------------------------------- the report
def not_reproduced(m: dict[str, Any], study: dict[str, Any] | None) -> list[str]:
    """The items of 'What is not reproduced': each failing claim of the static error, gamma* and the edge
    peak with its figure and its cause, then what the paper does not print."""
    from .paper_report import gamma_miss

    cl = {c["id"]: c for c in m["claims"]}
    items = []
    if "G1.static" in cl and not cl["G1.static"]["holds"]:
        items.append(cl["G1.static"]["text"] + ". The friction (36) is smooth (a tanh): the model has no stiction "
                     "to hold the wheels against the control after braking, so our errors decay.")
    g = gamma_miss(m, (study or {}).get("robustness"))
    if g:
        items.append(g)
    edge = [c["text"] for c in m["claims"] if c["id"].endswith(".edge_peak") and not c["holds"]]
    if edge:
        items.append(f"The peak of the control at the foam's edge, in {len(edge)} of "
                     f"{sum(1 for c in cl if c.endswith('.edge_peak'))} tasks: " + "; ".join(edge) + ". The model's "
                     "friction change is a 0.1 s ramp of a5, a6 without a bump"
                     + (": the bump sweep of the robustness section measures one." if study else
                        "; `--robustness` measures an edge bump."))
    items += ["The initial heading is not printed in the paper; we start at beta0 = 0. "
              + ("The robustness section measures how the results move with it." if study else
                 "`--robustness` measures how the results move with it."),
              "r = 0.0825 m and l1 = 0.16 m are not printed in the paper (Pioneer 2-DX values)."]
    return items


def report_blocks(results: dict[str, Any], variant: str, figures: list[Path], out: Path, wall: float,
                  study: dict[str, Any] | None = None, study_figure: Path | None = None) -> list:
    """The report as blocks (report.py).  Every pass/fail statement is a claim of ``results[variant]
    ['claims']``, generated from the number it states."""
    from .figures import caption
    from .paper_report import cells_table, outside_cells, robustness_blocks, summary_blocks

    m = results[variant]
    tasks = m["tasks"]
    cl = {c["id"]: c for c in m["claims"]}
    rep = paper.results()["reported_figures"]
    b: list = [("h1", "The paper's experiments, reproduced by co-simulation")]
    pv = m.get("provenance") or {}
    b.append(("ul", [f"Paper: '{pv.get('paper', '-')}'", f"Tool: {pv.get('tool', '-')}",
                     f"Git commit: {pv.get('git_commit', 'unknown')}", f"Date: {pv.get('date', '-')}"]))
    b.append(("p", f"Variant **{variant}** (reading of (51): "
                   f"{'W and P stop once the smallest eigenvalue of P falls to P0' if variant == 'freeze' else 'the Frobenius norm of P against P0, only P stops'}"
                   f"; see docs/decisions.md). Every run: 50 s at h = 2 ms through the three FMUs (WmrPlant, "
                   f"WmrSensor, WmrController) under the project's master, Gauss-Seidel plant -> sensor -> "
                   f"controller, from (0, 0) at t = 0 with heading beta0 = 0. All runs took {wall:.1f} s."))
    tm = tasks.get("G1", next(iter(tasks.values())))["learn"].get("t_move")
    b.append(("p", f"Nothing moves in the first seconds of the plots: the velocity profile (50) is a logistic "
                   f"step at b1 = {paper.table1()['b1']:g} s with slope c = {paper.table1()['c']:g} 1/s, so the "
                   f"desired speed of A first reaches 1 % of v* at t = {fmt(tm, 2)} s (measured on "
                   f"`runs/G1/learn`); before that the errors, the control and the weights stay at zero."))
    # ---- verdict
    b += summary_blocks(m)
    # ---- tables 2 and 3
    note = ("'ours' is the RMSE (54) of the measured signals over all 25,001 samples, what the paper's tables "
            "hold and what 'ratio' compares; 'true' is the same RMSE of the true errors from the plant's wheel "
            "angles and speeds (alpha_d - alpha, alpha_dot_d - alpha_dot). The filter (43) delays the measured "
            "angle, so at cruise the measured error is larger than the true one.")
    b.append(("h2", "Table 2: go-to-goal, RMSE (54)"))
    h, rows = cells_table(m, ("G1", "G2", "G3"))
    b += [("table", h, rows), ("p", note)]
    b.append(("h2", "Table 3: straight line, RMSE (54)"))
    h, rows = cells_table(m, ("LINE",))
    b.append(("table", h, rows))
    # ---- cells outside 1.5x
    h, rows, notes = outside_cells(m, (study or {}).get("robustness"))
    b.append(("h2", "Cells outside 1.5x of the paper, and what we measured about them"))
    if rows:
        b.append(("table", h, rows))
    else:
        b.append(("p", "None."))
    b.append(("p", "'needs' says whether our value would have to be smaller or larger to match. Stiction is not "
                   "in the model and was not measured here. " + " ".join(notes)))
    # ---- positions
    b.append(("h2", "Final position of point A and time to reach eps_G"))
    fp = paper.results()["final_positions"]
    rows = []
    for t in ("G1", "G2", "G3", "LINE"):
        if t not in tasks:
            continue
        for run in RUNS:
            r = tasks[t][run]
            pos = r.get("final_position")
            rows.append([t, run, "-" if pos is None else f"({pos[0]:.4f}, {pos[1]:.4f})",
                         f"({fp[t][0]:.4f}, {fp[t][1]:.4f})" if t in fp and run == "learn" else "-",
                         fmt(r.get("goal_distance")), fmt(r.get("t_goal"), 2), fmt(r.get("diverged"))])
    b.append(("table", ["task", "run", "final (x_A, y_A) [m]", "paper [m]", "distance to G [m]", "t_goal [s]",
                        "diverged"], rows))
    b.append(("ul", [cl[k]["text"] for k in cl if k.endswith(".position")]
              + [f"The paper's robot reached the proximity of G1 at about {rep['G1_time_near_goal_s']:.0f} s."]))
    # ---- control levels
    b.append(("h2", "Control levels"))
    rows = []
    for t in tasks:
        fr, fo = tasks[t]["frozen"], tasks[t]["foam"]
        rise = fo.get("foam_rise")
        pair = lambda x, d=2: fmt(x[0], d) + " / " + fmt(x[1], d) if x else "-"  # noqa: E731
        rows.append([t, pair(fr.get("cruise_u")), pair(fr.get("peak_u")), pair(rise, 3),
                     fmt(rep["foam_control_rise_line_Nm"] if t == "LINE" else rep["foam_control_rise_goal_Nm"], 1),
                     fmt(fo.get("edge_peak_u"), 2), fmt(fo.get("edge_peak_u_frozen"), 2),
                     fmt(rep["foam_control_peak_Nm"], 1), pair(fo.get("final_u"))])
    b.append(("table", ["task", "cruising u, wheel 1 / 2 (frozen run) [N.m]", "peak of abs(u) (frozen run) [N.m]",
                        "rise on foam (mean over 0.6-2.6 s after t_F) [N.m]", "paper's rise [N.m]",
                        "foam run: peak of abs(u) within 2 s of t_F [N.m]", "frozen run, same window [N.m]",
                        "paper's peak at the edge [N.m]", "u at 50 s, foam [N.m]"], rows))
    b.append(("ul", [cl[k]["text"] for k in cl if ".rise" in k or k.endswith(".edge_peak")]))
    b.append(("p", f"The paper: cruising control about {rep['line_cruise_control_Nm']:.0f} N.m (line) and a "
                   f"static control of {rep['G1_static_control_Nm'][0]} / {rep['G1_static_control_Nm'][1]} N.m "
                   f"after G1. The peaks of the frozen runs are those of the start (acceleration phase); at the "
                   f"foam's edge our control rises only by the ramped friction change, because the model's "
                   f"friction change is a ramp of a5, a6 without a bump."))
    # ---- weights
    rows = [[t] + [fmt(w, 4) for w in (tasks[t]["learn"].get("final_W") or [None] * 3)] for t in tasks]
    b += [("h2", "Learned critic weights"), ("table", ["task", "W1", "W2", "W3"], rows),
          ("p", f"The paper: the weights change in the acceleration phase and settle at about "
                f"{rep['final_weights_approx']}.")]
    # ---- H infinity
    b.append(("h2", "The H-infinity condition"))
    rows = []
    for t in tasks:
        fo = tasks[t]["foam"]
        rows.append([t, fmt(m["gamma_star"].get(t), 2), fmt(rep["gamma_star_bound"].get(t), 0),
                     fmt(m["gamma_true"].get(t), 2), fmt(m["gain_incremental"].get(t), 3), fmt(fo.get("t_F"), 3)])
    b.append(("table", ["task", "gamma* at 50 s (53)", "paper: gamma* below", "(53) with the injected dF",
                        "incremental gain", "t_F [s]"], rows))
    b.append(("ul", [cl[k]["text"] for k in cl if ".gamma" in k]))
    b.append(("p", "gamma* of (53) divides the whole cost of the foam run, int (s'Qs + u'Ru) dt, by the energy "
                   "int dF_est'dF_est dt of the disturbance estimate dF_est (52) (the difference of the controls "
                   "with and without the foam, zero before t_F; not the controller's maximising player dF_hat of "
                   "(46)), both from t = 0 to 50 s. Its denominator grows with the "
                   "square of the assumed friction change (a5, a6 + 0.4 N.m; + 0.5 N.m on the line), so gamma* is a "
                   "statement about that change, not about any. A simulation knows "
                   "the injected disturbance: '(53) with the injected dF' replaces the estimate by the truth, and the "
                   "incremental gain sqrt(int |z_foam - z_frozen|^2 / int |dF|^2), |z|^2 = s'Qs + u'Ru, is the L2 "
                   "gain from the friction change to the change of the controlled output."))
    # ---- variants
    if len(results) > 1:
        rows = []
        for v, mv in results.items():
            f = mv["fidelity"]
            rows.append([v, fmt(f["within_1_5"]), fmt(f["within_2_5"]), fmt(f["rms_log_factor"], 3),
                         ", ".join(mv["diverged_runs"]) or "none"])
        best = max(results, key=lambda v: (-len(results[v]["diverged_runs"]), results[v]["fidelity"]["within_1_5"]))
        b += [("h2", "Variants: which reading of (51) reproduces more of the paper"),
              ("table", ["variant", "cells within 1.5", "within 2.5", "rms log-factor", "diverged runs"], rows),
              ("p", f"**{best}** reproduces more of the paper: fewer diverged runs, then more table cells within a "
                    f"factor 1.5 (computed from the table above). Cells of diverged runs count as misses (their "
                    f"ratio is computed over what was recorded).")]
    # ---- robustness
    if study:
        b += robustness_blocks(study, study_figure)
    # ---- honest differences
    b += [("h2", "What is not reproduced"), ("ul", not_reproduced(m, study))]
    # ---- figures
    if figures:
        b.append(("h2", "Figures (redrawn from our runs, in the layout of the paper's)"))
        for f in figures:
            b.append(("img", f, caption(f)))
    b.append(("h2", "Files"))
    b.append(("ul", ["`metrics.json`: every number of this variant (tasks -> learn / frozen / foam -> RMSE of the "
                     "measured signals and true RMSE, final position, t_goal, diverged, edge peak, ...; gamma_star, "
                     "gamma_true, gain_incremental; fidelity; claims: every pass/fail statement with the number it "
                     "states" + ("; robustness and freeze_study" if study else "") + ")",
                     "`runs/<task>/<run>/`: each run's recorded signals (`signals.npy`), resolved scenario, FMU logs "
                     "and summary", "`variants/<name>/`: the same for the other variants (metrics and runs)",
                     "`figures/`: the PNG files"]
              + (["`robustness/points/<id>.json`: one row per point of the robustness study"] if study else [])))
    return b
