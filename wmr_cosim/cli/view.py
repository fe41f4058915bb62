"""``wmr-cosim view``: a finished run's results folder in the live view's page."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..exit_codes import OK as EXIT_OK
from .run import host_arg, port_arg


def add_parser(sub: Any, name: str) -> None:
    """The command ``view`` (``name``) and its options."""
    p = sub.add_parser(name, help="show a finished run's results folder in the live view's page",
                       description="Serve the page of `run --live` on a finished run (what `run` writes: "
                                   "signals.npy, summary.json, scenario.json): its recorded signals against time "
                                   "grouped by unit, its event table, its requirements' verdicts and robustness, "
                                   "the path of the scenario's [live] xy; prints its address on stderr (`live "
                                   "view: URL`) and serves until Ctrl-C (docs/live.md). Needs the live extra. Exit "
                                   "code 0, or 2 for a folder that is not a results folder or a port in use.")
    p.add_argument("results", type=Path, metavar="RESULTS", help="a results folder of `wmr-cosim run`")
    p.add_argument("--port", type=port_arg, default=0, metavar="N", help="the port to serve on (default: a free one)")
    p.add_argument("--host", type=host_arg, default="127.0.0.1", metavar="ADDRESS",
                   help="the address to serve on (default 127.0.0.1; another interface requires the random token "
                        "printed in the address)")
    p.set_defaults(func=cmd_view, subparser=p)


def cmd_view(args: argparse.Namespace) -> int:
    """Serve the results folder until Ctrl-C (exit 0)."""
    from ..live import LiveOptions, serve_results

    serve_results(args.results, LiveOptions(host=args.host, port=args.port))
    return EXIT_OK
