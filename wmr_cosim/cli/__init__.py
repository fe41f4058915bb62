"""The ``wmr-cosim`` command line.

Exit codes: 0 success; 1 the run failed or diverged; 2 bad input (a parameter, a file, an option);
130 interrupted (Ctrl-C).
"""
from __future__ import annotations

import argparse
import sys
from typing import Any, Callable, NoReturn

from .. import version
from ..components.validation import ParameterError
from ..cosim import CosimError, OtherFileError
from ..exit_codes import for_error
# the face: main, entry, build_parser, error_message, each command's function (cmd_<name>) and the helpers
# scripts and tests import from wmr_cosim.cli
from .build import cmd_build
from .check import cmd_check
from .commands import COMMANDS
from .direct import cmd_direct
from .export_fmu import cmd_export_fmu
from .export_ssp import cmd_export_ssp
from .falsify import cmd_falsify
from .gamma_search import cmd_gamma_search
from .info import cmd_info
from .linearize import cmd_linearize
from .options import (archive_limits, experiment_overrides, field_option_hint, instance_fields, plain,
                      scenario_after_record, scenario_file, SET_HELP, UsageError)
from .paper import cmd_paper
from .plot import cmd_plot
from .run import cmd_run, format_overrides, requirement_lines
from .sweep import cmd_sweep


#: How to run each other kind of file that may be given as a scenario (cosim.messages.errors.OtherFileError).
OTHER_FILE_HINTS = {"a paper manifest": "run it with `wmr-cosim paper --manifest FILE`",
                    "a sweep file": "run it with `wmr-cosim sweep FILE`"}


#: What a scenario file, an SSP archive and one FMU end in (the positional argument of run and check).
SCENARIO_SUFFIXES = (".toml", ".ssp", ".fmu")


def error_message(exc: BaseException) -> str:
    """The one line ``wmr-cosim: error: ...`` says for an error: its own message, and for a file of another
    kind given as a scenario, how to run it."""
    hint = OTHER_FILE_HINTS.get(exc.kind) if isinstance(exc, OtherFileError) else None
    return f"{exc}: {hint}" if hint else str(exc)


class OneLineParser(argparse.ArgumentParser):
    """argparse's parser whose refusal of a command line (an unknown option, a value of the wrong type, a
    missing argument) is one line on stderr and exit code 2, as every other refusal of bad input; its usage is
    what ``-h`` prints.  The parsers of the commands are of this class too (argparse makes them so)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} ({self.prog} -h lists the options)\n")


def build_parser() -> argparse.ArgumentParser:
    ap = OneLineParser(prog="wmr-cosim", description=plain(__doc__),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--max-archive-size", metavar="SIZE", default=None,
                    help="refuse FMU/SSP archives that unpack to more than SIZE (default 2 GiB; e.g. 8GiB)")
    ap.add_argument("--max-archive-ratio", metavar="RATIO", default=None,
                    help="refuse archives that unpack to more than RATIO times their size (default 200)")
    ap.add_argument("--version", action="version", version=f"wmr-cosim {version()}")
    sub = ap.add_subparsers(dest="command", required=True)
    for name, module in COMMANDS.items():
        module.add_parser(sub, name)
    return ap


def command_function(args: argparse.Namespace) -> Callable[[argparse.Namespace], Any]:
    """The function that runs the parsed command: the one this package exports under its name
    (``wmr_cosim.cli.cmd_run``), so that what replaces it there (a test's stand-in) is what runs; a
    command's own module's (``args.func``) when the package does not export it."""
    return getattr(sys.modules[__name__], args.func.__name__, args.func)


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
    scenario_after_record(ap, args)
    try:
        args.limits = archive_limits(args)
        return int(command_function(args)(args))
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
