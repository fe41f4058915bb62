"""``wmr-cosim export-fmu``: a scenario's system as one FMI 2.0 co-simulation FMU (a container)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..cosim import file_kind, FileKind
from ..exit_codes import OK as EXIT_OK
from ..scenario_files import scenario_path
from . import options
from .options import UsageError


def add_parser(sub: Any, name: str) -> None:
    """The command ``export-fmu`` (``name``) and its options."""
    e = sub.add_parser(name, help="write a scenario's system as one co-simulation FMU (FMI 2.0 or 3.0)",
                       description="Write a scenario's system as one FMI 2.0 (--fmi 3: FMI 3.0) co-simulation FMU "
                                   "(linux64, and win64 where it can be built for the FMI 2.0 face) that any FMI host "
                                   "runs: the scenario's FMUs under its resources, their connections with the unit "
                                   "conversions, factors and offsets, the parameters and start values, and the "
                                   "master's own compiled loop (Gauss-Seidel or Jacobi, instances at their own rates, "
                                   "timed events, input tables; the iterated coupling, its loops rolled back through "
                                   "the inner FMUs' state) "
                                   "as its runtime, so that its outputs equal `wmr-cosim run` of the scenario bit for "
                                   "bit. Its variables: the recorded outputs, the open inputs and the inner FMUs' "
                                   "parameters (Real, Integer, Boolean), named instance.variable. The FMUs inside may be FMI "
                                   "2.0 or 3.0, connected by Real, Integer, Boolean, Enumeration and the FMI 3.0 "
                                   "number types' connections; Model Exchange FMUs (FMI 2.0) inside are integrated "
                                   "by the master's integrators (euler, rk4, cvode) as the run integrates them. What "
                                   "it cannot hold yet (the step-size control, events on conditions, requirements, "
                                   "String connections, String outputs, FMI 3.0 outputs other than Float64, Int32 "
                                   "and Boolean, rows at events) is refused, nothing written (docs/export-fmu.md).")
    e.add_argument("scenario", type=scenario_path, help="scenario file (.toml) or SSP archive (.ssp)")
    e.add_argument("--out", type=Path, required=True, metavar="FILE.fmu", help="the FMU to write")
    e.add_argument("--name", default=None, metavar="NAME",
                   help="its model name and identifier, a C name (default: the scenario's or archive's file name)")
    e.add_argument("--platforms", default=None, metavar="LIST",
                   help="the container's binaries, comma-separated: linux64 (always) and win64 (MinGW-w64; every "
                        "inner FMU needs a win64 binary). Default: linux64, and win64 where it can be built (a "
                        "note says why not)")
    e.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                   help="the FMI version of the container's interface: 2 (default) or 3 (an FMI 3.0 co-simulation "
                        "FMU; whatever the FMI versions of the FMUs inside)")
    options.set_option(e)
    e.set_defaults(func=cmd_export_fmu, subparser=e)


def cmd_export_fmu(args: argparse.Namespace) -> int:
    """Write a scenario's system as one co-simulation FMU (FMI 2.0, or 3.0 with --fmi 3)."""
    from ..cosim import export_fmu
    from ..runner import load_plan, parse_set, ssp_plan

    if file_kind(args.out) is not FileKind.FMU:
        raise UsageError(f"--out {str(args.out)!r}: an FMU's name ends in .fmu")
    kind = file_kind(args.scenario)
    asked = None if args.platforms is None else [p.strip() for p in args.platforms.split(",") if p.strip()]
    notes: list[str] = []
    if kind is FileKind.SSP:   # (its FMUs extracted for the time of the export)
        with ssp_plan(args.scenario, parse_set(args.set), limits=args.limits) as plan:
            out = export_fmu(plan, args.out, args.name, args.fmi, platforms_asked=asked, notes=notes)
    elif kind is FileKind.SCENARIO:
        out = export_fmu(load_plan(args.scenario, parse_set(args.set), limits=args.limits), args.out, args.name,
                         args.fmi, platforms_asked=asked, notes=notes)
    else:
        raise UsageError(f"{args.scenario}: export-fmu takes a scenario file (.toml) or an SSP archive (.ssp)")
    for note in notes:
        print(f"wmr-cosim: note: {note}", file=sys.stderr)
    print(f"{args.scenario}: written {out}")
    return EXIT_OK
