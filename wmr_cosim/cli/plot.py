"""``wmr-cosim plot``: recorded signals of a results folder against time."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..exit_codes import OK as EXIT_OK
from .options import UsageError


def add_parser(sub: Any, name: str) -> None:
    """The command ``plot`` (``name``) and its options."""
    p = sub.add_parser(name, help="draw recorded signals of a results folder against time",
                       description="Draw recorded signals of a results folder (what `run` writes: signals.npy, "
                                   "summary.json, scenario.json) against time, one subplot per unit, the events of "
                                   "the run as vertical lines; write the figure (default RESULTS/plot.png). Exit "
                                   "code 0, or 2 for a folder without signals.npy or a variable not recorded.")
    p.add_argument("results", type=Path, metavar="RESULTS", help="a results folder of `wmr-cosim run`")
    p.add_argument("variables", nargs="*", metavar="VARIABLE",
                   help="recorded variables to draw: names, or patterns such as 'controller.W*' (default: the "
                        "first 4 recorded, in the order of summary.json's columns)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.png",
                   help="the figure to write (default RESULTS/plot.png; .pdf, .svg, ... by the suffix)")
    p.add_argument("--requirement", action="append", default=None, metavar="NAME",
                   help="also draw this requirement's robustness over time below the signals (by default the "
                        "signals its formula names); repeat it for several")
    p.add_argument("--show", action="store_true",
                   help="also open a window (where there is a display; without one, only the file is written)")
    p.set_defaults(func=cmd_plot, subparser=p)


def cmd_plot(args: argparse.Namespace) -> int:
    """Draw recorded signals of a results folder against time [s], the events as vertical lines."""
    from ..runs import PlotError, plot_results

    try:
        done = plot_results(args.results, args.variables or None, out=args.out, show=args.show,
                            requirements=args.requirement)
    except PlotError as exc:
        raise UsageError(str(exc)) from None
    print(f"{args.results}: {', '.join(done.variables)} drawn in {done.path}")
    if done.note:
        print(f"wmr-cosim: note: {done.note}", file=sys.stderr)
    return EXIT_OK

