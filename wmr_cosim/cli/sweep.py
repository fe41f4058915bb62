"""``wmr-cosim sweep``: a sweep file's points on Dask."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..cosim import count
from ..exit_codes import OK as EXIT_OK
from ..scenario_files import scenario_path
from . import options


def add_parser(sub: Any, name: str) -> None:
    """The command ``sweep`` (``name``) and its options."""
    sw = sub.add_parser(name, help="run a parameter sweep or Monte Carlo study on Dask",
                        description="Run a sweep file (scenarios/sweep-*.toml): a base scenario or protocol, grids "
                                    "and random distributions over any parameter, a seed. Each point is one full "
                                    "co-simulation (all the base's runs) in a Dask worker process; a local cluster by "
                                    "default, or an existing dask.distributed scheduler. Results: results.parquet, "
                                    "results.csv, figures/, points/ (a restarted sweep skips the points done).")
    sw.add_argument("sweep", type=scenario_path, help="sweep file (.toml)")
    sw.add_argument("--out", type=Path, default=None, metavar="DIR", help="results folder (default results/<sweep>)")
    options.dask_options(sw)
    sw.set_defaults(func=cmd_sweep, subparser=sw)


def cmd_sweep(args: argparse.Namespace) -> int:
    """A sweep file on Dask: one full co-simulation per point, in worker processes."""
    from ..paper import robot_system
    from ..studies import cluster_options, run_sweep

    out = args.out if args.out is not None else Path("results") / args.sweep.stem
    df = run_sweep(args.sweep, out, progress=not args.quiet, archive_limits=args.limits,
                   system=robot_system(), **cluster_options(args))
    counts = df["status"].value_counts().to_dict()
    print(f"{args.sweep}: {count(len(df), 'point')} ({', '.join(f'{v} {k}' for k, v in sorted(counts.items()))}); "
          f"results in {out} (results.parquet, results.csv, figures/)")
    return EXIT_OK

