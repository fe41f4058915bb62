"""``wmr-cosim gamma-search``: the smallest gamma for which the H-infinity condition holds."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..exit_codes import OK as EXIT_OK
from ..scenario_files import scenario_path
from . import options


def add_parser(sub: Any, name: str) -> None:
    """The command ``gamma-search`` (``name``) and its options."""
    gs = sub.add_parser(name, help="the smallest gamma for which the H-infinity condition holds",
                        description="gamma* of (53) against gamma on a grid (the whole learning + frozen + foam "
                                    "protocol at each gamma), then bisection where the grid shows a single crossing; "
                                    "reports the smallest gamma for which every run stays stable and gamma* <= gamma, "
                                    "and the whole curve.")
    gs.add_argument("scenario", type=scenario_path, help="a protocol with runs learn, frozen, foam (e.g. scenarios/paper/g1.toml)")
    gs.add_argument("--out", type=Path, default=None, metavar="DIR",
                    help="results folder (default results/gamma-search-<scenario>)")
    gs.add_argument("--grid", type=float, nargs="+", default=None, metavar="GAMMA", help="the gamma grid")
    gs.add_argument("--variant", default="freeze", help="a variant the protocol declares (default freeze)")
    options.dask_options(gs)
    gs.set_defaults(func=cmd_gamma_search, subparser=gs)


def cmd_gamma_search(args: argparse.Namespace) -> int:
    """gamma* against gamma on a grid, then bisection: the smallest gamma for which the condition holds."""
    from ..paper import gamma_search
    from ..studies import cluster_options

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

