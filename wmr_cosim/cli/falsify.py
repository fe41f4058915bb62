"""``wmr-cosim falsify``: the worst case of a requirement over a parameter space."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..exit_codes import OK as EXIT_OK, RUN_FAILED as EXIT_FAILED
from ..scenario_files import scenario_path
from . import options


def add_parser(sub: Any, name: str) -> None:
    """The command ``falsify`` (``name``) and its options."""
    fa = sub.add_parser(name, help="search a parameter space for the worst case of a requirement",
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
    options.dask_options(fa)
    fa.set_defaults(func=cmd_falsify, subparser=fa)


def cmd_falsify(args: argparse.Namespace) -> int:
    """A global search of a parameter space for the lowest robustness of a requirement."""
    from ..paper import robot_system
    from ..studies import cluster_options, falsify

    out = args.out if args.out is not None else Path("results") / args.spec.stem
    say = None if args.quiet else (lambda line: print(line, file=sys.stderr))
    r = falsify(args.spec, out, progress=not args.quiet, archive_limits=args.limits, say=say, seed=args.seed,
                budget=args.budget, system=robot_system(), **cluster_options(args))
    w, n = r["worst"], r["nominal"]
    print(f"nominal run: robustness {n['robustness']:.6g} ({n['verdict']})")
    print(f"worst case of {r['optimiser']['runs']} runs: robustness {w['robustness']:.6g} ({w['verdict']}) at "
          + ", ".join(f"{k} = {v:.6g}" for k, v in w["params"].items()))
    print(f"its re-run: robustness {r['rerun']['robustness']:.6g}"
          f"{'' if r['rerun']['same'] else ' (NOT the same as in the search)'}; run it again with:")
    print(f"  {w['command']}")
    print(f"results in {out} (falsify.json, falsify.csv, falsify.png, worst/)")
    return EXIT_OK if r["rerun"]["same"] else EXIT_FAILED

