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
import tomllib
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from . import scenario_files
from .analysis import (RUNS, disturbance_analysis, fidelity, load_signals, position_error, run_summary)
from .components import paper
from .report import fmt, to_html, to_markdown

DEFAULT_MANIFEST = "paper.toml"  # among the shipped scenario files (wmr_cosim.scenarios)
VARIANTS = ("freeze", "printed")


def _manifest(path: Path) -> dict[str, Path]:
    from .cosim.errors import ScenarioError

    if not path.is_file():
        raise ScenarioError(str(path), "", "file not found")
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(str(path), "", f"not valid TOML ({exc})") from None
    tasks = doc.get("tasks")
    if not isinstance(tasks, dict) or not tasks:
        raise ScenarioError(str(path), "tasks", "missing: a table task name -> protocol file")
    out = {}
    for name, f in tasks.items():
        if name not in paper.TASKS:
            raise ScenarioError(str(path), f"tasks.{name}", f"unknown task (one of {', '.join(paper.TASKS)})")
        out[name] = (path.parent / f).resolve()
    return out


def _task_job(task: str, file: str, folder: str, variant: str, fmi: int = 2) -> dict[str, Any]:
    """One task's protocol in a worker process: {run: {status, message, wall_s, setup_s}}; ``fmi`` 3 runs it
    through the FMI 3.0 FMUs (runner.resolver, runner.carry_fmi3)."""
    from .cosim.protocol import run_protocol
    from .runner import carry_fmi3, resolver

    t0 = time.perf_counter()
    results = run_protocol(file, folder, resolver(fmi), variant=variant, progress=False,
                           carry=carry_fmi3 if fmi == 3 else None)
    return {"task": task, "variant": variant, "wall_s": time.perf_counter() - t0,
            "runs": {n: {"status": r.status, "message": r.message, "wall_s": r.wall_s, "setup_s": r.setup_s,
                         "steps": r.steps} for n, r in results.items()}}


def analyse(folder: Path, statuses: dict[str, dict[str, dict[str, Any]]]) -> tuple[dict[str, Any], dict, dict]:
    """metrics.json content of one variant from its run folders; also the signals and the (52)/(53) curves."""
    t1 = paper.table1()
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
            d = disturbance_analysis(fr, fo, t1["Q"], t1["R"], t1["gamma"])
            dist[task] = d
            out["gamma_star"][task] = d["gamma_star"]
            out["gamma_true"][task] = d["gamma_true"]
            out["gain_incremental"][task] = d["gain_incremental"]
            tasks[task]["foam"]["foam_rise"] = d["foam_rise"]
            tasks[task]["foam"]["t_F"] = d["t_F"]
            tasks[task]["foam"]["gamma_star_max_after_tF"] = d["gamma_star_max"]
    out["fidelity"] = {k: v for k, v in fidelity(tasks).items()}
    out["diverged_runs"] = [f"{t}.{r}" for t in tasks for r in RUNS if tasks[t].get(r, {}).get("diverged")]
    return out, signals, dist


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
              progress: bool | None = None, figures: bool = True, fmi: int = 2) -> dict[str, Any]:
    """Run every task of the manifest for ``variant`` (and, with ``compare``, the other variants too),
    analyse, draw the figures and write report.md, report.html and metrics.json into ``out``."""
    from .runner import resolver

    resolve_model = resolver(fmi)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = _manifest(Path(manifest) if manifest else scenario_files.folder() / DEFAULT_MANIFEST)
    variants = [variant] + ([v for v in VARIANTS if v != variant] if compare else [])
    if progress is None:
        progress = sys.stderr.isatty()
    t0 = time.perf_counter()
    for model in ("WmrPlant", "WmrSensor", "WmrController"):  # build once, before the workers start
        resolve_model(model)
    folders = {v: out / "runs" if v == variant else out / "variants" / v / "runs" for v in variants}
    jobs = [(task, str(f), str(folders[v] / task), v, fmi) for v in variants for task, f in tasks.items()]
    statuses: dict[str, dict[str, dict[str, Any]]] = {v: {} for v in variants}
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    done = 0
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(_task_job, *job) for job in jobs]
        for fut in as_completed(futures):
            r = fut.result()
            statuses[r["variant"]][r["task"]] = r["runs"]
            done += 1
            if progress:
                runs = ", ".join(f"{n} {s['status']}" for n, s in r["runs"].items())
                print(f"[{done}/{len(jobs)}] {r['variant']} {r['task']}: {runs} ({r['wall_s']:.1f} s)",
                      file=sys.stderr, flush=True)
    results: dict[str, Any] = {}
    main_signals = main_dist = None
    for v in variants:
        m, sig, dist = analyse(folders[v], statuses[v])
        m = {"variant": v, **m}
        results[v] = m
        target = out if v == variant else out / "variants" / v
        (target / "metrics.json").write_text(json.dumps(_clean(m), indent=2) + "\n")
        if v == variant:
            main_signals, main_dist = sig, dist
    files = []
    if figures and main_signals is not None:
        from .figures import render_all
        files = render_all(main_signals, main_dist, out / "figures")
    wall = time.perf_counter() - t0
    blocks = report_blocks(results, variant, files, out, wall)
    (out / "report.md").write_text(to_markdown(blocks, out))
    (out / "report.html").write_text(to_html(blocks, "wmr-cosim: the paper's experiments"))
    return {"metrics": results[variant], "variants": results, "wall_s": wall, "out": out, "figures": files}


# ---------------------------------------------------------------------- the report
def _cells_table(m: dict[str, Any], tasks: tuple[str, ...]) -> tuple[list[str], list[list[str]]]:
    header = ["run", "wheel", "quantity"] + [f"{t} {w}" for t in tasks for w in ("ours", "paper", "ratio")]
    rows = []
    cells = {(c["task"], c["run"], c["cell"]): c for c in m["fidelity"]["cells"]}
    names = {"learn": "without disturbances (learning)", "foam": "changing operating conditions (foam)"}
    for run in ("learn", "foam"):
        for q, qn in (("e", "RMSE e [rad]"), ("e_dot", "RMSE de/dt [rad/s]")):
            for i in (1, 2):
                row = [names[run], f"i = {i}", qn]
                for t in tasks:
                    c = cells.get((t, run, f"{q}_{i}"))
                    if c is None:
                        row += ["-", "-", "-"]
                    else:
                        row += [fmt(c["ours"]), fmt(c["paper"]), fmt(c["ratio"], 2)]
                rows.append(row)
    return header, rows


def report_blocks(results: dict[str, Any], variant: str, figures: list[Path], out: Path, wall: float) -> list:
    m = results[variant]
    tasks = m["tasks"]
    fid = m["fidelity"]
    t1 = paper.table1()
    rep = paper.results()["reported_figures"]
    b: list = [("h1", "The paper's experiments, reproduced by co-simulation")]
    b.append(("p", f"Variant **{variant}** (reading of (51): "
                   f"{'W and P stop once the smallest eigenvalue of P falls to P0' if variant == 'freeze' else 'the Frobenius norm of P against P0, only P stops'}"
                   f"; see docs/decisions.md). Every run: 50 s at h = 2 ms through the three FMUs (WmrPlant, "
                   f"WmrSensor, WmrController) under the project's master, Gauss-Seidel plant -> sensor -> "
                   f"controller, from (0, 0) at t = 0. All runs of all variants took {wall:.1f} s."))
    # ---- verdict
    learn_ok = [t for t in tasks if t != "LINE" and tasks[t]["learn"].get("goal_distance") is not None
                and tasks[t]["learn"]["goal_distance"] <= t1["eps_G"]]
    verdict = [
        f"RMSE cells of Tables 2 and 3 within a factor 1.5 of the paper: **{fid['within_1_5']} of {fid['n_cells']}**; "
        f"within 2.5: {fid['within_2_5']} of {fid['n_cells']}; rms log-factor "
        f"exp(sqrt(mean(log(ours/paper)^2))) = **{fmt(fid['rms_log_factor'], 3)}** (1 would be exact).",
        f"Diverged runs: {', '.join(m['diverged_runs']) if m['diverged_runs'] else '**none**'} "
        f"(diverged: a non-finite value or |e_i| > 1 rad at the end).",
        f"Learning runs ending within eps_G = {t1['eps_G']} m of their goal (true pose): "
        f"{', '.join(learn_ok) if learn_ok else 'none'} of G1, G2, G3.",
    ]
    b += [("h2", "Summary"), ("ul", verdict)]
    # ---- tables 2 and 3
    b.append(("h2", "Table 2: go-to-goal, RMSE (54) over all 25,001 samples"))
    h, rows = _cells_table(m, ("G1", "G2", "G3"))
    b.append(("table", h, rows))
    b.append(("h2", "Table 3: straight line, RMSE (54)"))
    h, rows = _cells_table(m, ("LINE",))
    b.append(("table", h, rows))
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
    b.append(("p", f"The paper's robot reached the proximity of G1 at about {rep['G1_time_near_goal_s']:.0f} s."))
    # ---- control levels
    b.append(("h2", "Control levels"))
    rows = []
    for t in tasks:
        fr, fo = tasks[t]["frozen"], tasks[t]["foam"]
        rise = fo.get("foam_rise")
        rows.append([t, fmt(fr["cruise_u"][0], 2) + " / " + fmt(fr["cruise_u"][1], 2) if fr.get("cruise_u") else "-",
                     fmt(fr["peak_u"][0], 2) + " / " + fmt(fr["peak_u"][1], 2) if fr.get("peak_u") else "-",
                     fmt(rise[0], 3) + " / " + fmt(rise[1], 3) if rise else "-",
                     fmt(rep["foam_control_rise_line_Nm"] if t == "LINE" else rep["foam_control_rise_goal_Nm"], 1),
                     fmt(fo["final_u"][0], 2) + " / " + fmt(fo["final_u"][1], 2) if fo.get("final_u") else "-"])
    b.append(("table", ["task", "cruising u, wheel 1 / 2 [N.m]", "peak of abs(u) [N.m]", "rise on foam (2 s after the edge) [N.m]",
                        "paper's rise [N.m]", "u at 50 s, foam [N.m]"], rows))
    b.append(("p", f"The paper: cruising control about {rep['line_cruise_control_Nm']:.0f} N.m (line), a peak of "
                   f"about {rep['foam_control_peak_Nm']} N.m at the foam's edge and a static control of "
                   f"{rep['G1_static_control_Nm'][0]} / {rep['G1_static_control_Nm'][1]} N.m after G1 (neither "
                   f"reproducible with the smooth friction (36): see below)."))
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
        rows.append([t, fmt(m["gamma_star"].get(t), 2), fmt(fo.get("gamma_star_max_after_tF"), 2),
                     fmt(rep["gamma_star_bound"].get(t), 0), fmt(m["gamma_true"].get(t), 2),
                     fmt(m["gain_incremental"].get(t), 3), fmt(fo.get("t_F"), 3)])
    b.append(("table", ["task", "gamma* at 50 s (53)", "max gamma* after t_F + 1 s", "paper: gamma* below",
                        "(53) with the injected dF", "incremental gain", "t_F [s]"], rows))
    b.append(("p", f"gamma* of (53) divides the whole cost of the foam run by the energy of the disturbance "
                   f"estimate (52) (the difference of the controls with and without the foam), so it scales as 1 / "
                   f"the size of the friction change: it says gamma* <= gamma = {t1['gamma']:g} for the assumed "
                   f"change (a5, a6 + 0.4 N.m; + 0.5 N.m on the line), not for any. A simulation knows the injected "
                   f"disturbance: '(53) with the injected dF' replaces the estimate by the truth, and the "
                   f"incremental gain sqrt(int |z_foam - z_frozen|^2 / int |dF|^2), |z|^2 = s'Qs + u'Ru, is the "
                   f"L2 gain from the friction change to the change of the controlled output."))
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
                    f"factor 1.5. Under the printed reading W drifts towards rank one during the whole window "
                    f"(V close to w (s1 + s2)^2); frozen, such weights cannot steer the heading, and the go-to-goal "
                    f"runs with frozen weights diverge, although the paper's did not. Cells of diverged runs count "
                    f"as misses (their ratio is computed over what was recorded).")]
    # ---- honest differences
    b += [("h2", "What is not reproduced, and why"), ("ul", [
        "The static error after braking (0.07-0.10 rad held with 0.7-0.8 N.m of control on G1): the friction "
        "model (36) is smooth (a tanh), so there is no stiction to hold the wheels; our errors decay to near zero.",
        "The 8.4 N.m spike at the foam's edge: the friction change is a ramp of a5, a6, with no bump at the edge.",
        "The G3 e_dot cells (0.23-0.25 rad/s in the paper): they carry the real robot's measurement noise and "
        "unmodelled actuator dynamics, which a smooth model lacks; we do not add noise to match them.",
        "The foam rows of G2 and G3 (the paper's are smaller than its own learning rows, ours are not): on the "
        "real robot the two experiments were different drives; ours differ only by the foam.",
        "r = 0.0825 m and l1 = 0.16 m are not printed in the paper (Pioneer 2-DX values); the RMSE moves by "
        "1-12 % within their plausible ranges.",
    ])]
    # ---- figures
    if figures:
        b.append(("h2", "Figures (redrawn from our runs, in the layout of the paper's)"))
        for f in figures:
            b.append(("img", f, f.stem.replace("_", " ")))
    b.append(("h2", "Files"))
    b.append(("ul", ["`metrics.json`: every number of this variant (tasks -> learn / frozen / foam -> RMSE, final "
                     "position, t_goal, diverged, ...; gamma_star, gamma_true, gain_incremental; fidelity)",
                     "`runs/<task>/<run>/`: each run's recorded signals (`signals.npy`), resolved scenario, FMU logs "
                     "and summary", "`variants/<name>/`: the same for the other variants (metrics and runs)",
                     "`figures/`: the PNG files"]))
    return b
