"""``wmr-cosim info``: what an FMU is and holds."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..exit_codes import OK as EXIT_OK


def add_parser(sub: Any, name: str) -> None:
    """The command ``info`` (``name``) and its options."""
    i = sub.add_parser(name, help="describe an FMU", description="Describe any FMU whose model description "
                       "can be read (FMI 1.0, 2.0, 3.0; co-simulation, model exchange): model, FMI version, kinds "
                       "(CS, ME, SE), platforms, default experiment, one line on what would stop a run here, and "
                       "every variable with causality, variability (set events need tunable parameters), type, "
                       "unit, range and start. Exit code 0 when described, 2 when the archive or its model "
                       "description cannot be read.")
    i.add_argument("fmu", type=Path, help="an .fmu file")
    i.set_defaults(func=cmd_info, subparser=i)


def cmd_info(args: argparse.Namespace) -> int:
    """Describe an FMU (any it can read): model, kinds, platforms, default experiment, what would stop a
    run here, variables with variability, units and ranges."""
    from ..cosim import LimitOverrides
    from ..runs import describe

    print(describe(args.fmu, (args.limits or LimitOverrides()).over()))
    return EXIT_OK

