"""``wmr-cosim check``: every check of a scenario, an SSP archive or an FMU, without stepping."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..cosim import count, describe_coupling, describe_settings, file_kind, FileKind, MissingVariableError
from ..exit_codes import OK as EXIT_OK
from ..scenario_files import scenario_path
from . import options
from .options import experiment_overrides, instance_fields, scenario_file


def add_parser(sub: Any, name: str) -> None:
    """The command ``check`` (``name``) and its options."""
    c = sub.add_parser(name, help="check a scenario, SSP archive or FMU without running it",
                       description="Run every check of a scenario (files, variables, causality, types, units, "
                                   "steps, ranges, keys) without stepping. Exit code 0 if it would run, 2 if not.")
    c.add_argument("scenario", type=scenario_path, nargs="?",
                   help="scenario file (.toml), SSP 1.0 archive (.ssp) or one FMU (.fmu)")
    options.set_option(c)
    c.add_argument("--force", action="store_true", help="check as `run --force` would run")
    c.add_argument("--input", type=Path, default=None, metavar="FILE.csv",
                   help="one FMU only: input signals, checked as `run --input` reads them")
    options.experiment_options(c)
    options.solver_options(c)
    options.run_options(c, check=True)
    c.add_argument("--variant", default=None, help="a protocol's variant ([variants.NAME]): check its runs with it")
    c.set_defaults(func=cmd_check, subparser=c)


def cmd_check(args: argparse.Namespace) -> int:
    """Every check of a scenario against its FMUs, without stepping."""
    from ..runner import fmu_plan, load_plan, ssp_plan

    overrides = experiment_overrides(args)
    fields = instance_fields(args)
    f, lim, iso = args.force, args.limits, args.isolate
    options.refuse_input_of_a_scenario(args)
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
          f"{count(len(plan.connections) + len(plan.clock_links), 'connection')}"
          f"{f' ({len(plan.clock_links)} between clocks)' if plan.clock_links else ''}, "
          f"{count(len(plan.record), 'recorded variable')}, "
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
    from ..cosim import check_protocol

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

