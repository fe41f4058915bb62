"""The options several commands share, and how they are read: the experiment options of run and check
(--start, --stop, --step, --workers, --record), --solver and --max-step, --isolate and --real-time, the Dask
options of sweep, gamma-search and falsify, the archive limits every command takes, the one error of a bad
option (:class:`UsageError`) and the hint for an option that names a field of the scenario."""
from __future__ import annotations

import argparse
import json
from typing import Any

from ..cosim import named_kind
from ..scenario_files import scenario_path


class UsageError(Exception):
    """Bad command-line input; the message is one line."""


#: The help of every command's --set.
SET_HELP = ("override a parameter or start value, one per --set (repeat it): INSTANCE.PARAM=VALUE, or PARAM=VALUE "
            "when there is one instance (a single FMU)")


def set_option(p: argparse.ArgumentParser) -> None:
    """--set INSTANCE.PARAM=VALUE of run, check, export-ssp and linearize (repeated: a list, read by
    :func:`wmr_cosim.runner.parse_set`)."""
    p.add_argument("--set", action="append", metavar="INSTANCE.PARAM=VALUE", help=SET_HELP)


def plain(text: str) -> str:
    """A docstring as --help shows it: reStructuredText's double backquotes (``name``) become plain text."""
    return text.replace("``", "")


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


def experiment_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The overrides of run and check: every --set (``experiment.stop=5`` and ``record.variables=[...]``
    among them), then --start, --stop, --step [s] and --record as the fields of [experiment] and [record]
    they set; the scenario's checks then judge them as they judge the file's own values."""
    from ..runner import parse_set

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
    from ..runner import is_fmu

    fields = {key: v for key in ("solver", "max_step") if (v := getattr(args, key, None)) is not None}
    if fields and not is_fmu(args.scenario):
        opt = "--solver" if "solver" in fields else "--max-step"
        raise UsageError(f"{opt} applies to a single FMU (.fmu); a scenario file says it in [instances.NAME] "
                         f"{opt[2:].replace('-', '_')}")
    return fields


def scenario_file(args: argparse.Namespace) -> Any:
    """The scenario file of ``run`` and ``check`` read once (a protocol's
    :class:`~wmr_cosim.cosim.runtime.protocol.Protocol`; None for an FMU or an SSP archive), with the options that
    apply to a protocol only judged alike for both commands: ``--variant`` must name a variant the file
    declares, of a file that declares runs; ``--real-time`` paces a single run, not a protocol's runs."""
    from ..runner import is_scenario, read_scenario

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


def refuse_input_of_a_scenario(args: argparse.Namespace) -> None:
    """UsageError for run's and check's --input given with anything but a single FMU (a scenario file says
    its input signals in [inputs])."""
    from ..runner import is_fmu

    if args.input is not None and not is_fmu(args.scenario):
        raise UsageError("--input applies to a single FMU (.fmu); a scenario file says it in [inputs]")


def archive_limits(args: argparse.Namespace) -> Any:
    """The archive limits of --max-archive-size and --max-archive-ratio (None when neither is given), which
    every command passes down as an argument (paper, sweep and gamma-search send them to their worker
    processes with each job); CosimError naming the option for a bad value."""
    if args.max_archive_size is None and args.max_archive_ratio is None:
        return None
    from ..cosim import limit_overrides

    return limit_overrides(args.max_archive_size, args.max_archive_ratio,
                           names=("--max-archive-size", "--max-archive-ratio"))


def dask_options(p: argparse.ArgumentParser) -> None:
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


def solver_options(p: argparse.ArgumentParser) -> None:
    """--solver and --max-step of run and check: a single FMU run as model exchange by the master's integrator."""
    from ..cosim import SOLVERS

    p.add_argument("--solver", default=None, metavar="NAME",
                   help=f"one FMU only: run it as model exchange with this integrator ({', '.join(SOLVERS)}; an "
                        "FMU with no co-simulation interface runs as model exchange with cvode anyway): sets the "
                        "instance's solver")
    p.add_argument("--max-step", dest="max_step", type=float, default=None, metavar="H",
                   help="one FMU only: the integrator's largest step [s] (model exchange): sets the instance's "
                        "max_step")


def run_options(p: argparse.ArgumentParser, check: bool = False) -> None:
    """--isolate and --real-time of run, which check takes too, to judge what run with them would run."""
    how = "check as `run --isolate` would run: " if check else ""
    p.add_argument("--isolate", action="store_true",
                   help=f"{how}host every FMU in a child process of its own: a crash or hang is reported, not fatal "
                        "(instances can also say isolate = true)")
    p.add_argument("--real-time", nargs="?", const=1.0, default=None, type=_real_time, metavar="FACTOR",
                   help=("check as `run --real-time` would run (a single run, not a protocol's runs): " if check
                         else "") + "pace the steps to the wall clock at FACTOR x real time (default 1); steps that "
                                    "finish late are counted and reported, never skipped")


def experiment_options(p: argparse.ArgumentParser) -> None:
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


def scenario_after_record(ap: argparse.ArgumentParser, args: argparse.Namespace) -> None:
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
    from ..cosim import settable_table

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

