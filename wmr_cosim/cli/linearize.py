"""``wmr-cosim linearize``: a linear model around a point of a run, and a loop's margins."""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import Any, Sequence

from ..cosim import CosimError, OutputError

from ..exit_codes import OK as EXIT_OK
from ..scenario_files import scenario_path
from . import options


def add_parser(sub: Any, name: str) -> None:
    """The command ``linearize`` (``name``) and its options."""
    li = sub.add_parser(name, help="a linear model of an FMU or a system around a point of its run",
                        description="Run a scenario (one run) or an FMU to t = --at, then linearise there: "
                                    "Model Exchange FMUs and memoryless ones as a continuous-time model "
                                    "(directional derivatives, else central differences; the blocks closed through "
                                    "the connections), anything else as a discrete-time model at the communication "
                                    "step realised from pulse responses taken with rollback. With --break, the loop "
                                    "opened at that connection: its margins, Bode and Nyquist plots. Writes "
                                    "linear.npz, linear.mat, linear.json (docs/linearisation.md). Exit codes: 0 ok, "
                                    "1 the run failed, 2 bad input.")
    li.add_argument("target", type=scenario_path, help="scenario file (.toml) of one run, or one FMU (.fmu)")
    li.add_argument("--at", default=None, metavar="T", help="the operating point's time [s] (default: the start)")
    li.add_argument("--inputs", action="append", metavar="INST.VAR,...",
                    help="inputs of the model (an FMU alone: default every Real input); an input a connection "
                         "drives gets the signal added to what it carries")
    li.add_argument("--outputs", action="append", metavar="INST.VAR,...",
                    help="outputs of the model (an FMU alone: default every Real output)")
    li.add_argument("--break", dest="breaks", default=None, metavar="FROM->TO",
                    help="open this connection: inject at TO, read the return at FROM; the loop's margins")
    li.add_argument("--discrete", action="store_true",
                    help="a discrete-time model from pulse responses even where a continuous one can be taken")
    li.add_argument("--method", choices=("auto", "directional", "differences"), default="auto",
                    help="the Jacobian of Model Exchange FMUs (default: directional derivatives where provided)")
    li.add_argument("--steps", default=None, metavar="N", help="length of the pulse responses [steps] (default 200)")
    li.add_argument("--order", default=None, metavar="N",
                    help="order of the realisation, a positive whole number (default: from the Hankel singular values; "
                         "a lower one truncates the realisation, which the output says)")
    li.add_argument("--pulse", default=None, metavar="SIZE",
                    help="the pulse, relative to max(|u|, nominal) (default 1e-4)")
    li.add_argument("--state", action="append", metavar="INST.STATE=VALUE",
                    help="set a continuous state at the point (Model Exchange)")
    li.add_argument("--phase-budget", default=None, metavar="DEG",
                    help="with --break on a continuous loop: the phase margin [deg] the co-simulation's coupling may "
                         "cost; the largest step within it is reported (default 5)")
    options.set_option(li)
    li.add_argument("--out", default=None, metavar="DIR", help="results folder (default results/linear-<target>)")
    li.set_defaults(func=cmd_linearize, subparser=li)


def cmd_linearize(args: argparse.Namespace) -> int:
    """A linear model around a point of a run; with a break, the loop's margins."""
    from ..runs import linearize, report, write
    from ..runner import parse_set

    out = check_out(args.out if args.out is not None else Path("results") / f"linear-{Path(args.target).stem}")
    lin = linearize(args.target, at=parse_number("--at", args.at), inputs=parse_names("--inputs", args.inputs),
                    outputs=parse_names("--outputs", args.outputs),
                    breaks=parse_break(args.breaks) if args.breaks is not None else None, discrete=args.discrete,
                    method=args.method, steps=parse_count("--steps", args.steps),
                    order=parse_count("--order", args.order), pulse=parse_number("--pulse", args.pulse),
                    states=parse_states(args.state), overrides=parse_set(args.set), limits=args.limits,
                    phase_budget=parse_number("--phase-budget", args.phase_budget))
    for line in report(lin):
        print(line)
    files = write(lin, out)
    print(f"results in {out} ({', '.join(f.name for f in files)})")
    return EXIT_OK


# ---------------------------------------------------------------------- its options
def parse_break(text: str) -> tuple[str, str]:
    """``"FROM->TO"`` -> (FROM, TO); CosimError for another form."""
    parts = [p.strip() for p in text.split("->")]
    if len(parts) != 2 or not all(parts):
        raise CosimError(f"--break {text!r}: give one connection as FROM->TO, e.g. controller.u1->plant.u1")
    return parts[0], parts[1]


def parse_states(items: Sequence[str] | None) -> dict[str, float]:
    """``--state NAME=VALUE`` items -> {name: value}; CosimError naming a bad one, or one given twice."""
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            x = float(value)
        except ValueError:
            x = math.nan
        if not sep or not name.strip() or not math.isfinite(x):
            raise CosimError(f"--state {item!r}: give INSTANCE.STATE=VALUE with a finite number")
        if name.strip() in out:
            raise CosimError(f"--state {item!r}: {name.strip()} is given twice")
        out[name.strip()] = x
    return out


def parse_names(option: str, items: Sequence[str] | None) -> list[str]:
    """Repeated or comma-separated ``INST.VAR`` names -> one list; CosimError for an empty name or one
    given twice."""
    out: list[str] = []
    for item in items or []:
        for name in (n.strip() for n in item.split(",")):
            if not name:
                raise CosimError(f"{option} {item!r}: an empty name; give INSTANCE.VARIABLE names, comma-separated")
            if name in out:
                raise CosimError(f"{option} {item!r}: {name} is given twice")
            out.append(name)
    return out


def parse_number(option: str, text: str | None) -> float | None:
    """An option's number (None where not given); CosimError where it is not a finite one."""
    if text is None:
        return None
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise CosimError(f"{option} {text!r}: give a finite number")
    return x


def parse_count(option: str, text: str | None) -> int | None:
    """An option's whole number (None where not given; ``1e3`` is 1000); CosimError for another value."""
    x = parse_number(option, text)
    if x is None:
        return None
    if x != int(x):
        raise CosimError(f"{option} {text!r}: give a whole number")
    return int(x)


def check_out(out: str | Path) -> Path:
    """The results folder ``out`` as :func:`write` will make it, checked before anything runs: OutputError
    (one line) where it, or the nearest of its parents that exists, is not a folder or cannot be written.
    Nothing is made here."""
    if not str(out).strip():
        raise OutputError(f"--out {str(out)!r}: give a folder")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: exists and is not a folder")
    parent = next((p for p in out.absolute().parents if p.exists()), None)
    if parent is None or not parent.is_dir():
        raise OutputError(f"--out {out}: {parent} is not a folder")
    where = out if out.exists() else parent
    if not os.access(where, os.W_OK | os.X_OK):
        raise OutputError(f"--out {out}: cannot write in {where}")
    return out
