"""The ``wmr-cosim`` command line.

Exit codes: 0 success; 1 the run failed or diverged; 2 bad input (a parameter, a file, an option);
130 interrupted (Ctrl-C).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from . import version
from .components import paper
from .components.controller import ControllerParams
from .components.direct_loop import run_direct
from .cosim import (CosimError, count, describe_coupling, describe_settings, did_you_mean, file_kind, FileKind,
                    MissingVariableError, named_kind, OtherFileError, parse_value, RunStatus)
from .components.metrics import run_metrics
from .components.plant import PlantParams
from .components.sensor import SensorParams
from .components.validation import ParameterError
from .exit_codes import OK as EXIT_OK, RUN_FAILED as EXIT_FAILED, for_error, for_runs
from .scenario_files import scenario_path


class UsageError(Exception):
    """Bad command-line input; the message is one line."""


#: The help of every command's --set.
SET_HELP = ("override a parameter or start value, one per --set (repeat it): INSTANCE.PARAM=VALUE, or PARAM=VALUE "
            "when there is one instance (a single FMU)")


def plain(text: str) -> str:
    """A docstring as --help shows it: reStructuredText's double backquotes (``name``) become plain text."""
    return text.replace("``", "")


def _overrides(items: list[str]) -> dict[str, dict[str, Any]]:
    """['plant.foam_da1=0.4', 'controller.gamma=5'] (one per --set) -> {'plant': {...}, 'sensor': {...},
    'controller': {...}}."""
    out: dict[str, dict[str, Any]] = {"plant": {}, "sensor": {}, "controller": {}}
    fields = {"plant": PlantParams.__dataclass_fields__, "sensor": SensorParams.__dataclass_fields__,
              "controller": ControllerParams.__dataclass_fields__}
    for item in items:
        key, sep, val = item.partition("=")
        comp, dot, name = key.partition(".")
        if not sep or not dot or comp not in out:
            raise UsageError(f"--set {item!r}: expected COMPONENT.PARAM=VALUE with COMPONENT plant, sensor or controller"
                             f"{did_you_mean(comp, out) if sep and dot else ''}")
        if name not in fields[comp]:
            raise UsageError(f"--set {item!r}: {comp} has no parameter {name!r}{did_you_mean(name, fields[comp])}")
        v = parse_value(val)
        out[comp][name] = tuple(v) if isinstance(v, list) else v
    return out


def cmd_direct(args: argparse.Namespace) -> int:
    """Run one task of the paper through the FMI-free direct loop and print its metrics."""
    ov = _overrides(args.set or [])
    cp = ControllerParams(**{**paper.task_controller(args.task), **ov["controller"]})
    pp = PlantParams(**ov["plant"])
    sp = SensorParams(**ov["sensor"])
    res = run_direct(pp, sp, cp, t_stop=args.t_stop, h=args.step)
    goal = paper.task_goal(args.task) if cp.task == "goal" else None
    m = run_metrics(res.signals, goal)
    m.update(task=args.task, status=res.status, steps=res.steps, wall_s=round(res.wall_s, 3))
    ref = paper.rmse_table(args.task)["learn"]
    if not args.json:
        print(f"{args.task}: direct loop, {count(res.steps, 'step')} of {args.step} s in {res.wall_s:.2f} s "
              f"({res.wall_s / max(res.steps, 1) * 1e6:.1f} us/step), status {res.status} {res.message}")
        print(f"{'RMSE':10s} {'ours':>8s} {'paper':>8s} {'ratio':>6s}")
        for i, (name, val) in enumerate([("e_1", m["rmse_e"][0]), ("e_2", m["rmse_e"][1]),
                                         ("e_dot_1", m["rmse_edot"][0]), ("e_dot_2", m["rmse_edot"][1])]):
            print(f"{name:10s} {val:8.4f} {ref[i]:8.4f} {val / ref[i]:6.2f}")
        x, y = m["final_position"]
        print(f"final position of A: ({x:.4f}, {y:.4f}) m", end="")
        fp = paper.results()["final_positions"].get(args.task)
        print(f"   paper: ({fp[0]:.4f}, {fp[1]:.4f}) m" if fp else "")
        if m["t_goal"] is not None:
            print(f"eps_G reached at t = {m['t_goal']:.3f} s; distance at the end {m['goal_distance']:.4f} m")
        print("final W:", " ".join(f"{w:.4f}" for w in m["final_W"]))
    print(json.dumps(m))
    return EXIT_OK if res.status == RunStatus.OK and not m["diverged"] else EXIT_FAILED


def cmd_build(args: argparse.Namespace) -> int:
    """Build WmrPlant.fmu, WmrSensor.fmu and WmrController.fmu (only those whose sources changed)."""
    from .fmus.build import BuildError, build_all, default_out_dir, models_for, up_to_date

    out = args.out if args.out is not None else default_out_dir()
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {str(out)!r}: exists and is not a directory")
    current = {} if args.force else up_to_date(out)
    try:
        if args.fmi == 3:
            current = {} if args.force else up_to_date(out, models_for(3))
        paths = build_all(out, force=args.force, models=models_for(args.fmi))
    except BuildError as exc:
        print(f"wmr-cosim: build failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    for model, path in paths.items():
        print(f"{model}: {path} ({'up to date' if current.get(model) else 'built'})")
    if args.c_plant:
        from .fmus.cplant_build import CBuildError, build_c_plant

        try:
            print(f"WmrCPlant: {build_c_plant(out, force=args.force)} (C, built with cmake when its sources changed)")
        except CBuildError as exc:
            print(f"wmr-cosim: build failed: {' '.join(str(exc).split())}", file=sys.stderr)
            return EXIT_FAILED
    return EXIT_OK


def _real_time(text: str) -> float:
    """--real-time FACTOR: a number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: a factor of real time (a number > 0)") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r}: a factor of real time must be > 0 and finite")
    return v


#: The experiment options of run and check: option -> the field of [experiment] it sets.
EXPERIMENT_OPTIONS = {"start": "experiment.start", "stop": "experiment.stop", "step": "experiment.step",
                      "workers": "experiment.workers"}
#: What a scenario file, an SSP archive and one FMU end in (the positional argument of run and check).
SCENARIO_SUFFIXES = (".toml", ".ssp", ".fmu")
#: How to run each other kind of file that may be given as a scenario (cosim.messages.errors.OtherFileError).
OTHER_FILE_HINTS = {"a paper manifest": "run it with `wmr-cosim paper --manifest FILE`",
                    "a sweep file": "run it with `wmr-cosim sweep FILE`"}


def experiment_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The overrides of run and check: every --set (``experiment.stop=5`` and ``record.variables=[...]``
    among them), then --start, --stop, --step [s] and --record as the fields of [experiment] and [record]
    they set; the scenario's checks then judge them as they judge the file's own values."""
    from .runner import parse_set

    overrides = parse_set(args.set)
    for opt, key in EXPERIMENT_OPTIONS.items():
        if getattr(args, opt, None) is not None:
            overrides[key] = getattr(args, opt)
    if getattr(args, "record", None):
        overrides["record.variables"] = list(args.record)
    return overrides


def instance_fields(args: argparse.Namespace) -> dict[str, Any]:
    """The fields of a single FMU's instance that --solver and --max-step [s] set (checked as the
    instance's ``solver`` and ``max_step``); UsageError for a scenario file, an SSP archive or a protocol,
    whose instances say it themselves."""
    from .runner import is_fmu

    fields = {key: v for key in ("solver", "max_step") if (v := getattr(args, key, None)) is not None}
    if fields and not is_fmu(args.scenario):
        opt = "--solver" if "solver" in fields else "--max-step"
        raise UsageError(f"{opt} applies to a single FMU (.fmu); a scenario file says it in [instances.NAME] "
                         f"{opt[2:].replace('-', '_')}")
    return fields


#: The values of run --format: what the results folder gets beside signals.npy (always written).
RESULT_FORMATS = ("csv", "npy", "mat")


def format_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The fields of [record] that ``run --format`` sets (``record.csv``, ``record.mat``: exactly the formats
    named, repeated or comma-separated); {} without --format; UsageError naming an unknown format."""
    if not getattr(args, "format", None):
        return {}
    chosen = [f.strip().lower() for item in args.format for f in item.split(",")]
    for f in chosen:
        if f not in RESULT_FORMATS:
            raise UsageError(f"--format {f!r}: must be one of {', '.join(RESULT_FORMATS)}"
                             f"{did_you_mean(f, RESULT_FORMATS)}")
    return {"record.csv": "csv" in chosen, "record.mat": "mat" in chosen}


def cmd_run(args: argparse.Namespace) -> int:
    """Run a scenario through the co-simulation master."""
    from .runner import default_out, is_fmu, run_scenario

    out = args.out if args.out is not None else default_out(args.scenario)
    overrides = {**experiment_overrides(args), **format_overrides(args)}
    fields = instance_fields(args)
    parsed = scenario_file(args)
    if parsed is not None and parsed.scenario.runs:  # a protocol: every run, in order, into OUT/<run>
        return _run_protocol(args, parsed, out, overrides)
    if args.input is not None and not is_fmu(args.scenario):
        raise UsageError("--input applies to a single FMU (.fmu); a scenario file says it in [inputs]")
    res = run_scenario(args.scenario, out, overrides, progress=False if args.quiet else None, inputs=args.input,
                       force=args.force, isolate=args.isolate, real_time=args.real_time, limits=args.limits,
                       parsed=parsed, fields=fields,
                       on_plan=lambda plan: _print_notes([*plan.scenario.notes, *plan.run_notes]))
    _report_run(args, res, out)
    return for_runs([res.status], res.requirements)


def scenario_file(args: argparse.Namespace) -> Any:
    """The scenario file of ``run`` and ``check`` read once (a protocol's
    :class:`~wmr_cosim.cosim.runtime.protocol.Protocol`; None for an FMU or an SSP archive), with the options that
    apply to a protocol only judged alike for both commands: ``--variant`` must name a variant the file
    declares, of a file that declares runs; ``--real-time`` paces a single run, not a protocol's runs."""
    from .runner import is_scenario, read_scenario

    if not is_scenario(args.scenario):
        if args.variant is not None:
            raise UsageError(f"--variant {args.variant}: only a scenario file (.toml) declares variants")
        return None
    parsed = read_scenario(args.scenario, args.limits)
    parsed.variant_parameters(args.variant)
    if args.variant is not None and not parsed.scenario.runs:
        raise UsageError(f"--variant {args.variant}: {args.scenario} declares no runs")
    if args.real_time is not None and parsed.scenario.runs:
        raise UsageError("--real-time paces a single run, not a protocol's runs")
    return parsed


def _print_notes(notes: list[str]) -> None:
    """What ``run`` says of the scenario before it runs (a table its algorithm does not read), on stderr."""
    for note in notes:
        print(f"wmr-cosim: note: {note}", file=sys.stderr)


def _run_protocol(args: argparse.Namespace, parsed: Any, out: Path, overrides: dict[str, Any]) -> int:
    """``run`` of a protocol (a file read once: ``parsed``): every run, in order, into OUT/<run>, each
    judged by analysis.divergence; one line per run."""
    from .runner import run_protocol

    _print_notes(parsed.with_parameters(overrides).notes)
    results = run_protocol(parsed, out, variant=args.variant, overrides=overrides,
                           progress=False if args.quiet else None, force=args.force, isolate=args.isolate,
                           on_check=lambda plans: _print_notes(list(dict.fromkeys(
                               n for plan in plans.values() for n in plan.run_notes))))
    for name, r in results.items():
        if r.status == RunStatus.OK:
            print(f"{args.scenario} [{name}]: ok, {count(r.steps, 'step')} in {r.wall_s:.2f} s; "
                  f"results in {out / name}")
        else:
            print(f"wmr-cosim: run {name} {r.status}: {r.message}", file=sys.stderr)
        for line in requirement_lines(r.requirements):
            print(f"[{name}] {line}")
    return for_runs([r.status for r in results.values()], [v for r in results.values() for v in r.requirements])


def _report_run(args: argparse.Namespace, res: Any, out: Path) -> None:
    """What ``run`` prints of one finished run: real-time pacing, then ok (stdout) or the failure (stderr)."""
    per = f", {res.wall_s / res.steps * 1e6:.1f} us/step" if res.steps else ""
    if res.real_time is not None:
        rt = res.real_time
        print(f"real time x{rt['factor']:g}: {rt['overruns']} of {rt['steps']} steps finished late"
              + (f" (by up to {rt['late_max_s'] * 1e3:.3g} ms, {rt['late_mean_s'] * 1e3:.3g} ms on average)"
                 if rt["overruns"] else ""))
    if RunStatus(res.status).ended_well:
        how = "ok" if res.status == RunStatus.OK else res.message
        print(f"{args.scenario}: {how}, {count(res.steps, 'step')} to t = {res.t_end:g} s in {res.wall_s:.2f} s{per} "
              f"(set-up {res.setup_s:.2f} s); results in {out}")
    else:
        print(f"wmr-cosim: run {res.status}: {res.message}", file=sys.stderr)
        print(f"{args.scenario}: {res.status} after {count(res.steps, 'step')} (t = {res.t_end:g} s); "
              f"{_what_was_recorded(res, out)}", file=sys.stderr)
    for line in requirement_lines(res.requirements):
        print(line)


def requirement_lines(verdicts: list[dict[str, Any]]) -> list[str]:
    """One line per requirement verdict (summary.json's ``requirements``): holds, violated or undecided,
    with the robustness in its unit and the times."""
    out = []
    for v in verdicts:
        unit = f" {v['unit']}" if v.get("unit") else ""
        rob = f"robustness {v['robustness']:.6g}{unit} at t = {v['at']:.6g} s" if v["robustness"] is not None else ""
        if v["verdict"] == "violated":
            what = (f"VIOLATED at t = {v['first_violation']:.6g} s (known at t = {v['decided_at']:.6g} s); "
                    f"{rob}")
        elif v["verdict"] == "holds":
            what = f"holds; {rob}"
        else:
            window = v.get("window") or [0.0, None]
            why = "its planned stop" if window[1] is None else "the formula's horizon"
            what = f"undecided: the run ended before {why}" + (f"; {rob} so far" if rob else "")
        out.append(f"requirement {v['name']!r}: {what}")
    return out


def _what_was_recorded(res: Any, out: Path) -> str:
    """Where a run that failed left its rows: signals.npy with the rows recorded up to the failure, or
    none at all (a run that failed before its first row: only its logs and scenario.json are there)."""
    rows = int((res.summary or {}).get("rows") or 0)
    if rows and (out / "signals.npy").is_file():
        return f"what was recorded ({count(rows, 'row')}, to t = {res.t_end:g} s) is in {out}"
    return f"nothing was recorded (its logs are in {out / 'logs'})"


def cmd_check(args: argparse.Namespace) -> int:
    """Every check of a scenario against its FMUs, without stepping."""
    from .runner import fmu_plan, is_fmu, load_plan, ssp_plan

    overrides = experiment_overrides(args)
    fields = instance_fields(args)
    f, lim, iso = args.force, args.limits, args.isolate
    if args.input is not None and not is_fmu(args.scenario):
        raise UsageError("--input applies to a single FMU (.fmu); a scenario file says it in [inputs]")
    parsed = scenario_file(args)
    kind = file_kind(args.scenario)
    if kind is FileKind.SSP:
        with ssp_plan(args.scenario, overrides, f, iso, limits=lim) as plan:
            _report_check(args, plan)
    elif kind is FileKind.FMU:
        _report_check(args, fmu_plan(args.scenario, overrides, args.input, force=f, isolate=iso, limits=lim,
                                     fields=fields))
    else:
        try:
            plan = load_plan(args.scenario, overrides, f, iso, parsed=parsed)
        except MissingVariableError:
            if parsed.scenario.runs:   # every variable missing, run by run (the runs set parameters too)
                _check_runs(args, parsed, overrides)
            raise
        _report_check(args, plan, parsed.inherited)
        _check_runs(args, parsed, overrides)
    return EXIT_OK


def _report_check(args: argparse.Namespace, plan: Any, inherited: Any = ()) -> None:
    """What ``check`` prints of a checked plan: its verdict and sizes, what the file takes from its base
    (``inherited``: a line per base file), how each instance runs (its interface; for model exchange, the
    integrator), the inputs nothing drives, then its notes."""
    sc = plan.scenario
    print(f"{args.scenario}: ok: {count(len(plan.instances), 'instance')} ({', '.join(plan.order)}), "
          f"{count(len(plan.connections), 'connection')}, {count(len(plan.record), 'recorded variable')}, "
          f"{count(len(plan.events) + len(plan.conditions), 'event')}, "
          f"{count(plan.n_steps, 'step')} of {sc.step:g} s"
          f"{'' if plan.last_step is None else f' (the last {plan.last_step:.6g} s, to the stop time)'} "
          f"({sc.algorithm}); signals.npy about "
          f"{_size(plan.output_bytes)}{' (and signals.csv about ' + _size(3 * plan.output_bytes) + ')' if sc.csv else ''}")
    for i, report in enumerate(inherited):
        print(f"  {report.describe(top=i == 0)}")
    for name, ip in plan.instances.items():
        print(f"  {name}: {ip.describe()}")
    settings = describe_settings(sc.algorithm, sc.iteration, sc.adaptive, sc.step)
    if settings is not None:
        print(f"  {sc.algorithm}: {settings}")
    for line in describe_coupling(plan.coupling, sc.algorithm):
        print(f"  {line}")
    loose = plan.unconnected_inputs()
    if loose:
        print(f"  {count(len(loose), 'input')} not connected (nor in an input table), held at "
              f"{'its start value' if len(loose) == 1 else 'their start values'}: "
              + ", ".join(f"{ref} = {_value(v)}" + (f" (and {', '.join(f'events[{i}]' for i in ev)})" if ev else "")
                          for ref, v, ev in loose))
    if plan.not_recorded:
        print(f"note: String outputs are not recorded: {', '.join(plan.not_recorded)}")
    for r in plan.requirements:
        print(f"  requirement {r.name!r}: {r.formula}" + (" (stops the run when violated)" if r.on_violation == "stop"
                                                         else ""))
    for note in [*sc.notes, *plan.notes]:
        print(f"note: {note}")
    for name, n in plan.internal_steps.items():
        print(f"note: {name} takes fixed internal steps of {plan.instances[name].model.internal_step:g} s: "
              f"about {n:.3g} over the run")


def _check_runs(args: argparse.Namespace, parsed: Any, overrides: dict[str, Any]) -> None:
    """A protocol's runs (of the file read once: ``parsed``), each resolved as ``run`` would run it
    (parameters, carries, records)."""
    from .cosim import check_protocol

    parsed.variant_parameters(args.variant)
    sc = parsed.scenario
    if not sc.runs:
        return
    plans = check_protocol(parsed, variant=args.variant, overrides=overrides, force=args.force, isolate=args.isolate)
    carries = {r.name: len(r.carry) for r in sc.runs}
    for name, plan in plans.items():
        print(f"  run {name}: ok: {count(plan.n_steps, 'step')}, {count(len(plan.record), 'recorded variable')}"
              + (f", {count(carries[name], 'carried value')}" if carries[name] else ""))


def _value(v: Any) -> str:
    """A start value as check prints it: a number as %g, a string quoted, an array in brackets, none as "-"."""
    if v is None:
        return "-"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (int, float)):
        return f"{v:g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return repr(str(v))


def _size(n: float) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"


def cmd_export_ssp(args: argparse.Namespace) -> int:
    """Write a scenario as an SSP 1.0 archive (FMUs, system structure, parameter set, default experiment)."""
    from .runner import export_ssp, parse_set

    if file_kind(args.out) is not FileKind.SSP:
        raise UsageError(f"--out {str(args.out)!r}: an SSP archive's name ends in .ssp")
    out = export_ssp(args.scenario, args.out, parse_set(args.set), limits=args.limits)
    print(f"{args.scenario}: written {out}")
    return EXIT_OK


def cmd_info(args: argparse.Namespace) -> int:
    """Describe an FMU (any it can read): model, kinds, platforms, default experiment, what would stop a
    run here, variables with variability, units and ranges."""
    from .runner import describe_fmu

    print(describe_fmu(args.fmu, args.limits))
    return EXIT_OK


def cmd_plot(args: argparse.Namespace) -> int:
    """Draw recorded signals of a results folder against time [s], the events as vertical lines."""
    from .plot import PlotError, plot_results

    try:
        done = plot_results(args.results, args.variables or None, out=args.out, show=args.show,
                            requirements=args.requirement)
    except PlotError as exc:
        raise UsageError(str(exc)) from None
    print(f"{args.results}: {', '.join(done.variables)} drawn in {done.path}")
    if done.note:
        print(f"wmr-cosim: note: {done.note}", file=sys.stderr)
    return EXIT_OK


def cmd_paper(args: argparse.Namespace) -> int:
    """Every experiment of section 5 through the FMU co-simulation, with analysis, figures and a report."""
    from .paper_job import exit_code, run_paper, unfinished_runs

    r = run_paper(args.out, variant=args.variant, compare=not args.no_compare, workers=args.workers,
                  manifest=args.manifest, progress=False if args.quiet else None, robustness=args.robustness,
                  fmi=args.fmi, archive_limits=args.limits)
    m = r["metrics"]
    f = m["fidelity"]
    print(f"report: {args.out / 'report.md'} (and report.html, metrics.json, figures/) in {r['wall_s']:.1f} s")
    print(f"variant {m['variant']}: {f['within_1_5']} of {f['n_cells']} RMSE cells within 1.5x of the paper, "
          f"{f['within_2_5']} within 2.5x, rms log-factor {f['rms_log_factor'] if f['rms_log_factor'] is None else round(f['rms_log_factor'], 3)}; "
          f"diverged runs: {', '.join(m['diverged_runs']) or 'none'}")
    failing = [c for c in m.get("claims", []) if not c["holds"]]
    print(f"claims of the paper: {len(failing)} of {len(m.get('claims', []))} fail"
          + (f" ({', '.join(sorted({c['id'].split('.', 1)[-1] for c in failing}))}); report.md lists each with its figure"
             if failing else ""))
    for v, mv in r["variants"].items():
        if v != m["variant"]:
            print(f"variant {v}: {mv['fidelity']['within_1_5']} cells within 1.5x; diverged runs: "
                  f"{', '.join(mv['diverged_runs']) or 'none'}")
    for v, mv in r["variants"].items():
        if unfinished_runs(mv):
            print(f"wmr-cosim paper: variant {v}: runs that did not finish: {', '.join(unfinished_runs(mv))}",
                  file=sys.stderr)
    return exit_code(r["variants"], m["variant"])


def cmd_sweep(args: argparse.Namespace) -> int:
    """A sweep file on Dask: one full co-simulation per point, in worker processes."""
    from .cluster import cluster_options
    from .sweep import run_sweep

    out = args.out if args.out is not None else Path("results") / args.sweep.stem
    df = run_sweep(args.sweep, out, progress=not args.quiet, archive_limits=args.limits,
                   **cluster_options(args))
    counts = df["status"].value_counts().to_dict()
    print(f"{args.sweep}: {count(len(df), 'point')} ({', '.join(f'{v} {k}' for k, v in sorted(counts.items()))}); "
          f"results in {out} (results.parquet, results.csv, figures/)")
    return EXIT_OK


def cmd_gamma_search(args: argparse.Namespace) -> int:
    """gamma* against gamma on a grid, then bisection: the smallest gamma for which the condition holds."""
    from .cluster import cluster_options
    from .gamma_search import gamma_search

    out = args.out if args.out is not None else Path("results") / f"gamma-search-{args.scenario.stem}"
    r = gamma_search(args.scenario, out, grid=args.grid, variant=args.variant,
                     progress=not args.quiet, archive_limits=args.limits, **cluster_options(args))
    for p in r["curve"]:
        gs = "-" if p["gamma_star"] is None else f"{p['gamma_star']:.3f}"
        print(f"  gamma {p['gamma']:8.3f}  gamma* {gs:>10s}  {'holds' if p['holds'] else 'fails'}"
              f"{'' if p['stable'] else '  (' + p['status'] + ')'}")
    sg = r["smallest_gamma"]
    print(f"smallest gamma for which the learning + foam protocol stays stable with gamma* <= gamma: "
          f"{'none on this grid' if sg is None else f'{sg:.4g}'}"
          f"{'' if r['monotone'] else ' (the condition is not monotone in gamma: see the whole curve)'}")
    print(r["note"])
    print(f"results in {out} (gamma_search.json, gamma_search.csv, gamma_search.png)")
    return EXIT_OK


def cmd_falsify(args: argparse.Namespace) -> int:
    """A global search of a parameter space for the lowest robustness of a requirement."""
    from .cluster import cluster_options
    from .falsify import falsify

    out = args.out if args.out is not None else Path("results") / args.spec.stem
    say = None if args.quiet else (lambda line: print(line, file=sys.stderr))
    r = falsify(args.spec, out, progress=not args.quiet, archive_limits=args.limits, say=say, seed=args.seed,
                budget=args.budget, **cluster_options(args))
    w, n = r["worst"], r["nominal"]
    print(f"nominal run: robustness {n['robustness']:.6g} ({n['verdict']})")
    print(f"worst case of {r['optimiser']['runs']} runs: robustness {w['robustness']:.6g} ({w['verdict']}) at "
          + ", ".join(f"{k} = {v:.6g}" for k, v in w["params"].items()))
    print(f"its re-run: robustness {r['rerun']['robustness']:.6g}"
          f"{'' if r['rerun']['same'] else ' (NOT the same as in the search)'}; run it again with:")
    print(f"  {w['command']}")
    print(f"results in {out} (falsify.json, falsify.csv, falsify.png, worst/)")
    return EXIT_OK if r["rerun"]["same"] else EXIT_FAILED


def cmd_linearize(args: argparse.Namespace) -> int:
    """A linear model around a point of a run; with a break, the loop's margins."""
    from .linearize import (check_out, linearize, parse_break, parse_count, parse_names, parse_number, parse_states,
                            report, write)
    from .runner import parse_set

    out = check_out(args.out if args.out is not None else Path("results") / f"linear-{Path(args.target).stem}")
    lin = linearize(args.target, at=parse_number("--at", args.at), inputs=parse_names("--inputs", args.inputs),
                    outputs=parse_names("--outputs", args.outputs),
                    breaks=parse_break(args.breaks) if args.breaks is not None else None, discrete=args.discrete,
                    method=args.method, steps=parse_count("--steps", args.steps),
                    order=parse_count("--order", args.order), pulse=parse_number("--pulse", args.pulse),
                    states=parse_states(args.state), overrides=parse_set(args.set), limits=args.limits,
                    phase_budget=parse_number("--phase-budget", args.phase_budget))
    for line in report(lin):
        print(line)
    files = write(lin, out)
    print(f"results in {out} ({', '.join(f.name for f in files)})")
    return EXIT_OK


def _dask_options(p: argparse.ArgumentParser) -> None:
    """--workers, --scheduler, --dashboard, --tls-*, --quiet: where the points of a sweep or gamma search run."""
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes, at least 1 (default: one per core)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing dask.distributed scheduler, e.g. tls://10.0.0.5:8786 (its workers need this "
                        "project's version installed, no shared files: the FMUs and scenario files are sent to "
                        "them; a scheduler runs any code it is sent: plain tcp:// only on a trusted network, see "
                        "docs/security.md and docs/cluster.md)")
    p.add_argument("--dashboard", action="store_true",
                   help="start the local cluster's Dask dashboard (on 127.0.0.1 only) and print its address "
                        "(with --scheduler: print that scheduler's)")
    for opt, what in (("--tls-ca-file", "the CA certificate that signed the scheduler's"), ("--tls-cert", "this "
                      "client's certificate"), ("--tls-key", "this client's private key")):
        p.add_argument(opt, default=None, metavar="PEM", help=f"for a tls:// scheduler: {what} (PEM file)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress (a bar with the time left on a terminal, a line every 5%% of the points otherwise)")


def _solver_options(p: argparse.ArgumentParser) -> None:
    """--solver and --max-step of run and check: a single FMU run as model exchange by the master's integrator."""
    from .cosim import SOLVERS

    p.add_argument("--solver", default=None, metavar="NAME",
                   help=f"one FMU only: run it as model exchange with this integrator ({', '.join(SOLVERS)}; an "
                        "FMU with no co-simulation interface runs as model exchange with cvode anyway): sets the "
                        "instance's solver")
    p.add_argument("--max-step", dest="max_step", type=float, default=None, metavar="H",
                   help="one FMU only: the integrator's largest step [s] (model exchange): sets the instance's "
                        "max_step")


def _run_options(p: argparse.ArgumentParser, check: bool = False) -> None:
    """--isolate and --real-time of run, which check takes too, to judge what run with them would run."""
    how = "check as `run --isolate` would run: " if check else ""
    p.add_argument("--isolate", action="store_true",
                   help=f"{how}host every FMU in a child process of its own: a crash or hang is reported, not fatal "
                        "(instances can also say isolate = true)")
    p.add_argument("--real-time", nargs="?", const=1.0, default=None, type=_real_time, metavar="FACTOR",
                   help=("check as `run --real-time` would run (a single run, not a protocol's runs): " if check
                         else "") + "pace the steps to the wall clock at FACTOR x real time (default 1); steps that "
                                    "finish late are counted and reported, never skipped")


def _experiment_options(p: argparse.ArgumentParser) -> None:
    """--start, --stop, --step, --workers and --record of run and check (with FMPy's names as aliases)."""
    what = "of the scenario, the SSP archive or the FMU's default experiment"
    p.add_argument("--start", "--start-time", dest="start", type=float, default=None, metavar="T",
                   help=f"start time [s]: sets experiment.start (default: that {what})")
    p.add_argument("--stop", "--stop-time", dest="stop", type=float, default=None, metavar="T",
                   help=f"stop time [s]: sets experiment.stop (default: that {what})")
    p.add_argument("--step", "--output-interval", dest="step", type=float, default=None, metavar="H",
                   help=f"communication step [s]: sets experiment.step (default: that {what})")
    p.add_argument("--workers", "--parallel", dest="workers", type=int, default=None, metavar="N",
                   help="up to N isolated instances, and C FMUs in this process in N threads, step at once "
                        "(Jacobi: all; Gauss-Seidel: each level's): sets experiment.workers (default 1)")
    p.add_argument("--record", "--output-variables", dest="record", nargs="+", action="extend", default=None,
                   metavar="VAR", help="the variables to record, as [record] variables: names or patterns "
                                       "(plant.x_A, \"controller.W*\", \"*.*\"); replaces the file's list")


def _scenario_after_record(ap: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """``run --record a.x b.y scenario.toml``: --record takes every word up to the next option, the scenario
    too; the last of them is the scenario when it ends in .toml, .ssp or .fmu and none was given."""
    if getattr(args, "scenario", "given") is not None:
        return
    sub = args.subparser
    if args.record and named_kind(args.record[-1]) is not None:
        args.scenario = scenario_path(args.record.pop())
        if args.record:
            return
        sub.error("argument --record: expected at least one variable before the scenario")
    sub.error("the following arguments are required: scenario")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="wmr-cosim", description=plain(__doc__),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--max-archive-size", metavar="SIZE", default=None,
                    help="refuse FMU/SSP archives that unpack to more than SIZE (default 2 GiB; e.g. 8GiB)")
    ap.add_argument("--max-archive-ratio", metavar="RATIO", default=None,
                    help="refuse archives that unpack to more than RATIO times their size (default 200)")
    ap.add_argument("--version", action="version", version=f"wmr-cosim {version()}")
    sub = ap.add_subparsers(dest="command", required=True)
    _add_direct(sub)
    _add_build(sub)
    _add_run(sub)
    _add_check(sub)
    _add_plot(sub)
    _add_export_ssp(sub)
    _add_info(sub)
    _add_paper(sub)
    _add_sweep(sub)
    _add_gamma_search(sub)
    _add_falsify(sub)
    _add_linearize(sub)
    return ap


def _add_direct(sub: Any) -> None:
    """The ``direct`` command."""
    d = sub.add_parser("direct", help="run a task of the paper through the FMI-free direct loop",
                       description="Run one task of the paper (learning run: adaptation 0-39 s, reference floor) "
                                   "through the FMI-free direct loop and print its metrics beside Table 2/3.")
    d.add_argument("task", nargs="?", default="G1", choices=paper.TASKS, help="task (default G1)")
    d.add_argument("--stop", dest="t_stop", type=float, default=50.0, help="stop time [s] (default 50)")
    d.add_argument("--t-stop", dest="t_stop", type=float, default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    d.add_argument("--step", type=float, default=0.002, help="communication step h [s] (default 0.002)")
    d.add_argument("--set", action="append", metavar="COMP.PARAM=VALUE",
                   help="override a parameter, e.g. --set controller.gamma=5 (one per --set; repeat it: "
                        "--set plant.foam_on_time=true --set plant.foam_t_on=8.38)")
    d.add_argument("--json", action="store_true", help="print only the JSON line")
    d.set_defaults(func=cmd_direct, subparser=d)


def _add_build(sub: Any) -> None:
    """The ``build`` command."""
    b = sub.add_parser("build", help="build the three FMUs (WmrPlant, WmrSensor, WmrController)",
                       description="Build WmrPlant.fmu, WmrSensor.fmu and WmrController.fmu into DIR, rebuilding "
                                   "only those whose sources changed.")
    b.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="output folder (default: build/fmus of the source tree, git-ignored; when installed from a "
                        "wheel, the per-user cache ~/.cache/wmr-cosim/fmus)")
    b.add_argument("--force", action="store_true", help="rebuild even if up to date")
    b.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                   help="FMI version: 2 (default) builds WmrPlant/WmrSensor/WmrController with pythonfmu, 3 builds "
                        "WmrPlant3/WmrSensor3/WmrController3 with pythonfmu3 (docs/fmu-interfaces-fmi3.md)")
    b.add_argument("--c-plant", action="store_true",
                   help="also build WmrCPlant.fmu, the plant in C (needs cmake and a C compiler)")
    b.set_defaults(func=cmd_build, subparser=b)


def _add_run(sub: Any) -> None:
    """The ``run`` command."""
    r = sub.add_parser("run", help="run a scenario (.toml), SSP archive (.ssp) or FMU (.fmu)",
                       description="Run a scenario file: FMUs, parameters, connections, experiment, recording, events. "
                                   "A name that is not a file is looked up among the shipped scenarios (example.toml, "
                                   "g1_learn.toml, paper/g1.toml, ...). Results go to a folder: signals.npy (written "
                                   "as the run goes), signals.csv, scenario.json, logs/, summary.json. Exit codes: "
                                   "0 ok, 1 the run failed (an FMU error, a non-finite value, or a run of a protocol that "
                                   "diverged), 2 bad input, 130 interrupted.")
    r.add_argument("scenario", type=scenario_path, nargs="?",
                   help="scenario file (.toml), SSP 1.0 archive (.ssp) or one FMU (.fmu)")
    r.add_argument("--out", type=Path, default=None, metavar="DIR", help="results folder (default results/<scenario>)")
    r.add_argument("--set", action="append", metavar="INSTANCE.PARAM=VALUE", help=SET_HELP)
    r.add_argument("--variant", default=None, help="a variant the scenario declares ([variants.NAME])")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--input", type=Path, default=None, metavar="FILE.csv",
                   help="one FMU only: input signals (a time column, one column per input; see docs/scenarios.md)")
    _experiment_options(r)
    _solver_options(r)
    r.add_argument("--force", action="store_true",
                   help="run even beyond the limits of steps (experiment.max_steps) and recording size (record.max_bytes)")
    _run_options(r)
    r.add_argument("--format", action="append", default=None, metavar="FORMAT",
                   help="what the results folder gets beside signals.npy (always written): csv (signals.csv), mat "
                        "(signals.mat, Dymola's result layout, MAT v4) or npy (nothing more); repeat it or separate "
                        "by commas for several (--format csv,mat); default: as the scenario's [record] csv and mat "
                        "say (signals.csv)")
    r.set_defaults(func=cmd_run, subparser=r)


def _add_check(sub: Any) -> None:
    """The ``check`` command."""
    c = sub.add_parser("check", help="check a scenario, SSP archive or FMU without running it",
                       description="Run every check of a scenario (files, variables, causality, types, units, "
                                   "steps, ranges, keys) without stepping. Exit code 0 if it would run, 2 if not.")
    c.add_argument("scenario", type=scenario_path, nargs="?",
                   help="scenario file (.toml), SSP 1.0 archive (.ssp) or one FMU (.fmu)")
    c.add_argument("--set", action="append", metavar="INSTANCE.PARAM=VALUE", help=SET_HELP)
    c.add_argument("--force", action="store_true", help="check as `run --force` would run")
    c.add_argument("--input", type=Path, default=None, metavar="FILE.csv",
                   help="one FMU only: input signals, checked as `run --input` reads them")
    _experiment_options(c)
    _solver_options(c)
    _run_options(c, check=True)
    c.add_argument("--variant", default=None, help="a protocol's variant ([variants.NAME]): check its runs with it")
    c.set_defaults(func=cmd_check, subparser=c)


def _add_plot(sub: Any) -> None:
    """The ``plot`` command."""
    p = sub.add_parser("plot", help="draw recorded signals of a results folder against time",
                       description="Draw recorded signals of a results folder (what `run` writes: signals.npy, "
                                   "summary.json, scenario.json) against time, one subplot per unit, the events of "
                                   "the run as vertical lines; write the figure (default RESULTS/plot.png). Exit "
                                   "code 0, or 2 for a folder without signals.npy or a variable not recorded.")
    p.add_argument("results", type=Path, metavar="RESULTS", help="a results folder of `wmr-cosim run`")
    p.add_argument("variables", nargs="*", metavar="VARIABLE",
                   help="recorded variables to draw: names, or patterns such as 'controller.W*' (default: the "
                        "first 4 recorded, in the order of summary.json's columns)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.png",
                   help="the figure to write (default RESULTS/plot.png; .pdf, .svg, ... by the suffix)")
    p.add_argument("--requirement", action="append", default=None, metavar="NAME",
                   help="also draw this requirement's robustness over time below the signals (by default the "
                        "signals its formula names); repeat it for several")
    p.add_argument("--show", action="store_true",
                   help="also open a window (where there is a display; without one, only the file is written)")
    p.set_defaults(func=cmd_plot, subparser=p)


def _add_export_ssp(sub: Any) -> None:
    """The ``export-ssp`` command."""
    e = sub.add_parser("export-ssp", help="write a scenario as an SSP 1.0 archive",
                       description="Write a scenario as an SSP 1.0 archive that other tools (libcosim, ecos, FMPy, "
                                   "OMSimulator) run: the FMUs as resources, SystemStructure.ssd (components, "
                                   "connectors, connections with linear transforms, units, default experiment with "
                                   "the step, OMSimulator's fixed-step master at that step), the parameter values as "
                                   "an SSV parameter set named 'parameters'. These tools run the system as Jacobi: "
                                   "their results equal this master's run with algorithm = \"jacobi\" (a note says "
                                   "so for a Gauss-Seidel scenario). A String parameter at the FMU's default is left "
                                   "out of the parameter set (OMSimulator cannot import one; this master reads it "
                                   "back); at another value it stays there and OMSimulator runs with the default (a "
                                   "warning names each). Timed events cannot be expressed in SSP 1.0 and are refused.")
    e.add_argument("scenario", type=scenario_path, help="scenario file (.toml)")
    e.add_argument("--out", type=Path, required=True, metavar="FILE.ssp", help="the archive to write")
    e.add_argument("--set", action="append", metavar="INSTANCE.PARAM=VALUE", help=SET_HELP)
    e.set_defaults(func=cmd_export_ssp, subparser=e)


def _add_info(sub: Any) -> None:
    """The ``info`` command."""
    i = sub.add_parser("info", help="describe an FMU", description="Describe any FMU whose model description "
                       "can be read (FMI 1.0, 2.0, 3.0; co-simulation, model exchange): model, FMI version, kinds "
                       "(CS, ME, SE), platforms, default experiment, one line on what would stop a run here, and "
                       "every variable with causality, variability (set events need tunable parameters), type, "
                       "unit, range and start. Exit code 0 when described, 2 when the archive or its model "
                       "description cannot be read.")
    i.add_argument("fmu", type=Path, help="an .fmu file")
    i.set_defaults(func=cmd_info, subparser=i)


def _add_paper(sub: Any) -> None:
    """The ``paper`` command."""
    pp = sub.add_parser("paper", help="run the paper's experiments and write the report",
                        description="Run every experiment of section 5 of the paper (G1, G2, G3, LINE; each a "
                                    "learning run, a frozen-weights run on the reference floor and one on foam) "
                                    "through the FMU co-simulation, in parallel processes; analyse them and write "
                                    "report.md, report.html, metrics.json and figures/ into DIR. Exit code 1 if a "
                                    "run of the chosen variant diverged or did not finish, or a run of the compared "
                                    "variant did not finish (its diverged runs are reported, not an error); else 0.")
    pp.add_argument("--out", type=Path, default=Path("results/paper"), metavar="DIR",
                    help="output folder (default results/paper)")
    pp.add_argument("--variant", default="freeze", choices=("freeze", "printed"),
                    help="the reading of (51) the report and metrics.json describe (default freeze)")
    pp.add_argument("--no-compare", action="store_true",
                    help="do not also run the other variant (the report then cannot compare them)")
    pp.add_argument("--workers", type=int, default=None, help="worker processes (default: one per core)")
    pp.add_argument("--manifest", type=Path, default=None,
                    help="the tasks file (default: the shipped scenarios/paper.toml)")
    pp.add_argument("--quiet", action="store_true", help="no progress lines")
    pp.add_argument("--robustness", action="store_true",
                    help="also the robustness study (mismatch, initial heading, encoder noise) and the study of when "
                         "W stops adapting, on Dask (about 300 more runs; resumes in DIR/robustness)")
    pp.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                    help="run the FMI 2.0 FMUs (default) or their FMI 3.0 versions (WmrPlant3, ...): same numbers")
    pp.set_defaults(func=cmd_paper, subparser=pp)


def _add_sweep(sub: Any) -> None:
    """The ``sweep`` command."""
    sw = sub.add_parser("sweep", help="run a parameter sweep or Monte Carlo study on Dask",
                        description="Run a sweep file (scenarios/sweep-*.toml): a base scenario or protocol, grids "
                                    "and random distributions over any parameter, a seed. Each point is one full "
                                    "co-simulation (all the base's runs) in a Dask worker process; a local cluster by "
                                    "default, or an existing dask.distributed scheduler. Results: results.parquet, "
                                    "results.csv, figures/, points/ (a restarted sweep skips the points done).")
    sw.add_argument("sweep", type=scenario_path, help="sweep file (.toml)")
    sw.add_argument("--out", type=Path, default=None, metavar="DIR", help="results folder (default results/<sweep>)")
    _dask_options(sw)
    sw.set_defaults(func=cmd_sweep, subparser=sw)


def _add_gamma_search(sub: Any) -> None:
    """The ``gamma-search`` command."""
    gs = sub.add_parser("gamma-search", help="the smallest gamma for which the H-infinity condition holds",
                        description="gamma* of (53) against gamma on a grid (the whole learning + frozen + foam "
                                    "protocol at each gamma), then bisection where the grid shows a single crossing; "
                                    "reports the smallest gamma for which every run stays stable and gamma* <= gamma, "
                                    "and the whole curve.")
    gs.add_argument("scenario", type=scenario_path, help="a protocol with runs learn, frozen, foam (e.g. scenarios/paper/g1.toml)")
    gs.add_argument("--out", type=Path, default=None, metavar="DIR",
                    help="results folder (default results/gamma-search-<scenario>)")
    gs.add_argument("--grid", type=float, nargs="+", default=None, metavar="GAMMA", help="the gamma grid")
    gs.add_argument("--variant", default="freeze", help="a variant the protocol declares (default freeze)")
    _dask_options(gs)
    gs.set_defaults(func=cmd_gamma_search, subparser=gs)


def _add_falsify(sub: Any) -> None:
    """The ``falsify`` command."""
    fa = sub.add_parser("falsify", help="search a parameter space for the worst case of a requirement",
                        description="Differential evolution over the file's parameter space (every point a full "
                                    "co-simulation on Dask, within the file's budget of runs or --budget) for the lowest "
                                    "robustness of one of the base scenario's requirements; reports the worst case "
                                    "found, its robustness against the nominal run's, and re-runs it "
                                    "(docs/requirements.md).")
    fa.add_argument("spec", type=scenario_path, help="falsification file (.toml), e.g. scenarios/falsify-foam.toml")
    fa.add_argument("--out", type=Path, default=None, metavar="DIR", help="results folder (default results/<file>)")
    fa.add_argument("--budget", type=int, default=None, metavar="N",
                    help="co-simulations of the search, over the file's budget (at least 10)")
    fa.add_argument("--seed", type=int, default=None, metavar="N",
                    help="the optimiser's seed, over the file's (0 to 2**32 - 1)")
    _dask_options(fa)
    fa.set_defaults(func=cmd_falsify, subparser=fa)


def _add_linearize(sub: Any) -> None:
    """The ``linearize`` command."""
    li = sub.add_parser("linearize", help="a linear model of an FMU or a system around a point of its run",
                        description="Run a scenario (one run) or an FMU to t = --at, then linearise there: "
                                    "Model Exchange FMUs and memoryless ones as a continuous-time model "
                                    "(directional derivatives, else central differences; the blocks closed through "
                                    "the connections), anything else as a discrete-time model at the communication "
                                    "step realised from pulse responses taken with rollback. With --break, the loop "
                                    "opened at that connection: its margins, Bode and Nyquist plots. Writes "
                                    "linear.npz, linear.mat, linear.json (docs/linearisation.md). Exit codes: 0 ok, "
                                    "1 the run failed, 2 bad input.")
    li.add_argument("target", type=scenario_path, help="scenario file (.toml) of one run, or one FMU (.fmu)")
    li.add_argument("--at", default=None, metavar="T", help="the operating point's time [s] (default: the start)")
    li.add_argument("--inputs", action="append", metavar="INST.VAR,...",
                    help="inputs of the model (an FMU alone: default every Real input); an input a connection "
                         "drives gets the signal added to what it carries")
    li.add_argument("--outputs", action="append", metavar="INST.VAR,...",
                    help="outputs of the model (an FMU alone: default every Real output)")
    li.add_argument("--break", dest="breaks", default=None, metavar="FROM->TO",
                    help="open this connection: inject at TO, read the return at FROM; the loop's margins")
    li.add_argument("--discrete", action="store_true",
                    help="a discrete-time model from pulse responses even where a continuous one can be taken")
    li.add_argument("--method", choices=("auto", "directional", "differences"), default="auto",
                    help="the Jacobian of Model Exchange FMUs (default: directional derivatives where provided)")
    li.add_argument("--steps", default=None, metavar="N", help="length of the pulse responses [steps] (default 200)")
    li.add_argument("--order", default=None, metavar="N",
                    help="order of the realisation, a positive whole number (default: from the Hankel singular values; "
                         "a lower one truncates the realisation, which the output says)")
    li.add_argument("--pulse", default=None, metavar="SIZE",
                    help="the pulse, relative to max(|u|, nominal) (default 1e-4)")
    li.add_argument("--state", action="append", metavar="INST.STATE=VALUE",
                    help="set a continuous state at the point (Model Exchange)")
    li.add_argument("--phase-budget", default=None, metavar="DEG",
                    help="with --break on a continuous loop: the phase margin [deg] the co-simulation's coupling may "
                         "cost; the largest step within it is reported (default 5)")
    li.add_argument("--set", action="append", metavar="INSTANCE.PARAM=VALUE", help=SET_HELP)
    li.add_argument("--out", default=None, metavar="DIR", help="results folder (default results/linear-<target>)")
    li.set_defaults(func=cmd_linearize, subparser=li)


def archive_limits(args: argparse.Namespace) -> Any:
    """The archive limits of --max-archive-size and --max-archive-ratio (None when neither is given), which
    every command passes down as an argument (paper, sweep and gamma-search send them to their worker
    processes with each job); CosimError naming the option for a bad value."""
    if args.max_archive_size is None and args.max_archive_ratio is None:
        return None
    from .cosim import limit_overrides

    return limit_overrides(args.max_archive_size, args.max_archive_ratio,
                           names=("--max-archive-size", "--max-archive-ratio"))


def error_message(exc: BaseException) -> str:
    """The one line ``wmr-cosim: error: ...`` says for an error: its own message, and for a file of another
    kind given as a scenario, how to run it."""
    hint = OTHER_FILE_HINTS.get(exc.kind) if isinstance(exc, OtherFileError) else None
    return f"{exc}: {hint}" if hint else str(exc)


#: The commands whose --set sets a field of [experiment] or [record] (``--set experiment.algorithm=jacobi``).
SET_FIELD_COMMANDS = ("run", "check")


#: The fields of [experiment] and [record] whose value is an array (--set gives it in JSON).
LIST_FIELDS = ("order", "variables")


def _option_value(option: str, argv: list[str], array: bool) -> str:
    """The value an unknown option was given: the word after it on the command line (argparse may have
    taken it for the scenario), for an array every word up to the next option or the scenario, in JSON and
    quoted for the shell; "VALUE" where none follows."""
    at = argv.index(option) + 1 if option in argv else len(argv)
    words = []
    while at < len(argv) and not argv[at].startswith("-") and named_kind(argv[at]) is None:
        words.append(argv[at])
        at += 1
        if not array:
            break
    if not words:
        return "VALUE"
    return "'" + json.dumps(words) + "'" if array else words[0]


def field_option_hint(command: str, unknown: list[str], argv: list[str]) -> str | None:
    """For an unknown option of run or check that names a field of [experiment] or [record] (or of a table
    inside [experiment]): the one line that says to set it with --set (``--algorithm jacobi``: "--set
    experiment.algorithm=jacobi"); None for any other."""
    from .cosim import settable_table

    if command not in SET_FIELD_COMMANDS:
        return None
    for i, token in enumerate(unknown):
        if not token.startswith("--"):
            continue
        option, eq, value = token.partition("=")
        key = option[2:].replace("-", "_")
        where = settable_table(key)
        if where is None:
            continue
        setting = f"{where}.{key}={value if eq else _option_value(token, argv, key in LIST_FIELDS)}"
        hint = " (or --record VAR ...)" if key == "variables" else ""
        return (f"{command} {option}: not an option; {where}.{key} is set with --set {setting}{hint} "
                f"(docs/scenarios.md)")
    return None


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args, unknown = ap.parse_known_args(argv)
    if unknown:
        hint = field_option_hint(args.command, unknown, argv)
        if hint is not None:
            print(f"wmr-cosim: error: {hint}", file=sys.stderr)
            return for_error(UsageError(hint))
        ap.error(f"unrecognized arguments: {' '.join(unknown)}")
    _scenario_after_record(ap, args)
    try:
        args.limits = archive_limits(args)
        return int(args.func(args))
    except (ParameterError, UsageError, CosimError) as exc:
        print(f"wmr-cosim: error: {error_message(exc)}", file=sys.stderr)
        return for_error(exc)
    except ImportError as exc:
        missing = exc.name.split(".")[0] if exc.name else ""
        if missing == "control" or (missing == "scipy" and args.command == "linearize"):
            print(f"wmr-cosim: error: {args.command} needs {'python-control' if missing == 'control' else missing} "
                  "(the linear extra): pip install 'wmr-cosim[linear]'", file=sys.stderr)
            return for_error(exc)
        if exc.name and exc.name.split(".")[0] in ("dask", "distributed", "pandas", "pyarrow"):
            print(f"wmr-cosim: error: {args.command} needs {exc.name}: pip install 'wmr-cosim[sweep]'", file=sys.stderr)
            return for_error(exc)
        raise
    except KeyboardInterrupt as exc:
        print("wmr-cosim: interrupted", file=sys.stderr)
        return for_error(exc)


def entry() -> None:
    """The ``wmr-cosim`` command: :func:`main`, its return value the exit status; the interpreter then
    finishes normally.  Output into a pipe the reader closed (``wmr-cosim info X.fmu | head``) ends the
    command quietly, with the shell's status for it (128 + SIGPIPE)."""
    try:
        code = main()
        sys.stdout.flush()
    except BrokenPipeError:
        import os
        import signal
        # Python's own advice: point stdout at devnull so that the flush at exit cannot raise again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = 128 + signal.SIGPIPE
    sys.exit(code)


if __name__ == "__main__":
    entry()
