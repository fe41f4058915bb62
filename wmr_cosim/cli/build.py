"""``wmr-cosim build``: the robot's FMUs (and the plant in C), built where their sources changed."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..exit_codes import OK as EXIT_OK, RUN_FAILED as EXIT_FAILED
from .options import UsageError


def add_parser(sub: Any, name: str) -> None:
    """The command ``build`` (``name``) and its options."""
    b = sub.add_parser(name, help="build the three FMUs (WmrPlant, WmrSensor, WmrController)",
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


def cmd_build(args: argparse.Namespace) -> int:
    """Build WmrPlant.fmu, WmrSensor.fmu and WmrController.fmu (only those whose sources changed)."""
    from ..fmus.build import BuildError, build_all, default_out_dir, models_for, up_to_date

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
        from ..fmus.cplant_build import CBuildError, build_c_plant

        try:
            print(f"WmrCPlant: {build_c_plant(out, force=args.force)} (C, built with cmake when its sources changed)")
        except CBuildError as exc:
            print(f"wmr-cosim: build failed: {' '.join(str(exc).split())}", file=sys.stderr)
            return EXIT_FAILED
    return EXIT_OK

