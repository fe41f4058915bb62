"""``wmr-cosim run``: a scenario, an SSP archive or one FMU through the master, or a protocol's runs."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..cosim import RECORDING, RESULT_FORMATS, count, did_you_mean, format_flags, format_help, RunStatus
from ..exit_codes import for_runs
from ..scenario_files import scenario_path
from . import options
from .options import experiment_overrides, instance_fields, scenario_file, UsageError


def add_parser(sub: Any, name: str) -> None:
    """The command ``run`` (``name``) and its options."""
    r = sub.add_parser(name, help="run a scenario (.toml), SSP archive (.ssp) or FMU (.fmu)",
                       description="Run a scenario file: FMUs, parameters, connections, experiment, recording, events. "
                                   "A name that is not a file is looked up among the shipped scenarios (example.toml, "
                                   "g1_learn.toml, paper/g1.toml, ...). Results go to a folder: signals.npy (written "
                                   "as the run goes), signals.csv, scenario.json, logs/, summary.json. Exit codes: "
                                   "0 ok, 1 the run failed (an FMU error, a non-finite value, or a run of a protocol that "
                                   "diverged), 2 bad input, 130 interrupted.")
    r.add_argument("scenario", type=scenario_path, nargs="?",
                   help="scenario file (.toml), SSP 1.0 archive (.ssp) or one FMU (.fmu)")
    r.add_argument("--out", type=Path, default=None, metavar="DIR", help="results folder (default results/<scenario>)")
    options.set_option(r)
    r.add_argument("--variant", default=None, help="a variant the scenario declares ([variants.NAME])")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--input", type=Path, default=None, metavar="FILE.csv",
                   help="one FMU only: input signals (a time column, one column per input; see docs/scenarios.md)")
    options.experiment_options(r)
    options.solver_options(r)
    r.add_argument("--force", action="store_true",
                   help="run even beyond the limits of steps (experiment.max_steps) and recording size (record.max_bytes)")
    options.run_options(r)
    live_options(r)
    asked = {name: f.flag for name, f in RESULT_FORMATS.items() if f.flag is not None}   # name -> [record] flag
    r.add_argument("--format", action="append", default=None, metavar="FORMAT",
                   help=f"what the results folder gets beside {RESULT_FORMATS[RECORDING].file} (always written): "
                        f"{format_help()}; repeat it or separate by commas for several (--format {','.join(asked)}); "
                        f"default: as the scenario's [record] {' and '.join(asked.values())} say (signals.csv)")
    r.set_defaults(func=cmd_run, subparser=r)


def live_options(r: argparse.ArgumentParser) -> None:
    """--live and what goes with it (--port, --host, --paused, --open)."""
    r.add_argument("--live", action="store_true",
                   help="serve the run while it goes: an HTTP and WebSocket API (and a page) to watch it, pause, "
                        "step, pace it and set values that replay exactly (docs/live.md); prints its address "
                        "on stderr; needs the live extra")
    r.add_argument("--port", type=port_arg, default=None, metavar="N",
                   help="with --live: the port to serve on (default: a free one)")
    r.add_argument("--host", type=host_arg, default=None, metavar="ADDRESS",
                   help="with --live: the address to serve on (default 127.0.0.1; another interface requires the "
                        "random token printed in the address)")
    r.add_argument("--paused", action="store_true", help="with --live: start paused (at the start time)")
    r.add_argument("--open", action="store_true", help="with --live: open the page in the default web browser")


def port_arg(text: str) -> int:
    """--port N: a port number 0 (any free port) to 65535."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: a port number (0 to 65535)") from None
    if not 0 <= n <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r}: a port number is 0 (any free port) to 65535")
    return n


def host_arg(text: str) -> str:
    """--host ADDRESS: an IPv4 or IPv6 address of this machine's interfaces (or localhost)."""
    import ipaddress

    if text == "localhost":
        return text
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: an IP address to serve on (127.0.0.1, 0.0.0.0, ::1, ...)") \
            from None


def live_request(args: argparse.Namespace, parsed: Any) -> Any:
    """The :class:`wmr_cosim.live.LiveOptions` of ``run --live`` (None without it); UsageError for
    --port, --host, --paused or --open without --live, --live of a protocol, or where the live extra is
    missing."""
    if not getattr(args, "live", False):
        given = [f for f, v in (("--port", args.port), ("--host", args.host)) if v is not None] + \
            (["--paused"] if args.paused else []) + (["--open"] if args.open else [])
        if given:
            raise UsageError(f"{given[0]} goes with --live (it serves the run)")
        return None
    if parsed is not None and parsed.scenario.runs:
        raise UsageError(f"--live serves a single run: {args.scenario} is a protocol of "
                         f"{count(len(parsed.scenario.runs), 'run')}")
    from ..live import LiveOptions, missing_libraries

    missing = missing_libraries()
    if missing:
        raise UsageError(f"--live needs {', '.join(missing)} (the live extra): pip install 'wmr-cosim[live]'")
    return LiveOptions(host=args.host or "127.0.0.1", port=args.port or 0, paused=args.paused, open=args.open)


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
    return format_flags(chosen)


def cmd_run(args: argparse.Namespace) -> int:
    """Run a scenario through the co-simulation master."""
    from ..paper import judge_run
    from ..runner import default_out, run_scenario

    out = args.out if args.out is not None else default_out(args.scenario)
    overrides = {**experiment_overrides(args), **format_overrides(args)}
    fields = instance_fields(args)
    parsed = scenario_file(args)
    live = live_request(args, parsed)
    if parsed is not None and parsed.scenario.runs:  # a protocol: every run, in order, into OUT/<run>
        return _run_protocol(args, parsed, out, overrides)
    options.refuse_input_of_a_scenario(args)
    res = run_scenario(args.scenario, out, overrides, progress=False if args.quiet else None, inputs=args.input,
                       force=args.force, isolate=args.isolate, real_time=args.real_time, limits=args.limits,
                       parsed=parsed, fields=fields, judge=judge_run, live=live,
                       on_plan=lambda plan: _print_notes([*plan.scenario.notes, *plan.run_notes]))
    _report_run(args, res, out)
    return for_runs([res.status], res.requirements)


def _print_notes(notes: list[str]) -> None:
    """What ``run`` says of the scenario before it runs (a table its algorithm does not read), on stderr."""
    for note in notes:
        print(f"wmr-cosim: note: {note}", file=sys.stderr)


def _run_protocol(args: argparse.Namespace, parsed: Any, out: Path, overrides: dict[str, Any]) -> int:
    """``run`` of a protocol (a file read once: ``parsed``): every run, in order, into OUT/<run>, each
    judged by analysis.divergence; one line per run."""
    from ..paper import judge_run
    from ..runner import run_protocol

    _print_notes(parsed.with_parameters(overrides).notes)
    results = run_protocol(parsed, out, variant=args.variant, overrides=overrides,
                           progress=False if args.quiet else None, force=args.force, isolate=args.isolate, judge=judge_run,
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

