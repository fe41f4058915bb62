"""``wmr-cosim export-ssp``: a scenario written as an SSP 1.0 archive."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..cosim import file_kind, FileKind
from ..exit_codes import OK as EXIT_OK
from ..scenario_files import scenario_path
from . import options
from .options import UsageError


def add_parser(sub: Any, name: str) -> None:
    """The command ``export-ssp`` (``name``) and its options."""
    e = sub.add_parser(name, help="write a scenario as an SSP 1.0 archive",
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
    options.set_option(e)
    e.set_defaults(func=cmd_export_ssp, subparser=e)


def cmd_export_ssp(args: argparse.Namespace) -> int:
    """Write a scenario as an SSP 1.0 archive (FMUs, system structure, parameter set, default experiment)."""
    from ..runner import export_ssp, parse_set

    if file_kind(args.out) is not FileKind.SSP:
        raise UsageError(f"--out {str(args.out)!r}: an SSP archive's name ends in .ssp")
    out = export_ssp(args.scenario, args.out, parse_set(args.set), limits=args.limits)
    print(f"{args.scenario}: written {out}")
    return EXIT_OK

