"""``wmr-cosim paper``: the paper's experiments, their analysis and the report."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def add_parser(sub: Any, name: str) -> None:
    """The command ``paper`` (``name``) and its options."""
    pp = sub.add_parser(name, help="run the paper's experiments and write the report",
                        description="Run every experiment of section 5 of the paper (G1, G2, G3, LINE; each a "
                                    "learning run, a frozen-weights run on the reference floor and one on foam) "
                                    "through the FMU co-simulation, in parallel processes; analyse them and write "
                                    "report.md, report.html, metrics.json and figures/ into DIR. Exit code 1 if a "
                                    "run of the chosen variant diverged or did not finish, or a run of the compared "
                                    "variant did not finish (its diverged runs are reported, not an error); else 0.")
    pp.add_argument("--out", type=Path, default=Path("results/paper"), metavar="DIR",
                    help="output folder (default results/paper)")
    pp.add_argument("--variant", default="freeze", choices=("freeze", "printed"),
                    help="the reading of (51) the report and metrics.json describe (default freeze)")
    pp.add_argument("--no-compare", action="store_true",
                    help="do not also run the other variant (the report then cannot compare them)")
    pp.add_argument("--workers", type=int, default=None, help="worker processes (default: one per core)")
    pp.add_argument("--manifest", type=Path, default=None,
                    help="the tasks file (default: the shipped scenarios/paper.toml)")
    pp.add_argument("--quiet", action="store_true", help="no progress lines")
    pp.add_argument("--robustness", action="store_true",
                    help="also the robustness study (mismatch, initial heading, encoder noise) and the study of when "
                         "W stops adapting, on Dask (about 300 more runs; resumes in DIR/robustness)")
    pp.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                    help="run the FMI 2.0 FMUs (default) or their FMI 3.0 versions (WmrPlant3, ...): same numbers")
    pp.set_defaults(func=cmd_paper, subparser=pp)


def cmd_paper(args: argparse.Namespace) -> int:
    """Every experiment of section 5 through the FMU co-simulation, with analysis, figures and a report."""
    from ..paper import exit_code, run_paper, unfinished_runs

    r = run_paper(args.out, variant=args.variant, compare=not args.no_compare, workers=args.workers,
                  manifest=args.manifest, progress=False if args.quiet else None, robustness=args.robustness,
                  fmi=args.fmi, archive_limits=args.limits)
    m = r["metrics"]
    f = m["fidelity"]
    print(f"report: {args.out / 'report.md'} (and report.html, metrics.json, figures/) in {r['wall_s']:.1f} s")
    print(f"variant {m['variant']}: {f['within_1_5']} of {f['n_cells']} RMSE cells within 1.5x of the paper, "
          f"{f['within_2_5']} within 2.5x, rms log-factor {f['rms_log_factor'] if f['rms_log_factor'] is None else round(f['rms_log_factor'], 3)}; "
          f"diverged runs: {', '.join(m['diverged_runs']) or 'none'}")
    failing = [c for c in m.get("claims", []) if not c["holds"]]
    print(f"claims of the paper: {len(failing)} of {len(m.get('claims', []))} fail"
          + (f" ({', '.join(sorted({c['id'].split('.', 1)[-1] for c in failing}))}); report.md lists each with its figure"
             if failing else ""))
    for v, mv in r["variants"].items():
        if v != m["variant"]:
            print(f"variant {v}: {mv['fidelity']['within_1_5']} cells within 1.5x; diverged runs: "
                  f"{', '.join(mv['diverged_runs']) or 'none'}")
    for v, mv in r["variants"].items():
        if unfinished_runs(mv):
            print(f"wmr-cosim paper: variant {v}: runs that did not finish: {', '.join(unfinished_runs(mv))}",
                  file=sys.stderr)
    return exit_code(r["variants"], m["variant"])

