"""The ``wmr-cosim`` command line.

Exit codes: 0 success; 1 the run failed or diverged; 2 bad input (a parameter, a file, an option).
"""
from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from .components import paper
from .components.controller import ControllerParams
from .components.direct_loop import run_direct
from .components.metrics import run_metrics
from .components.plant import PlantParams
from .components.sensor import SensorParams
from .components.validation import ParameterError

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class UsageError(Exception):
    """Bad command-line input; the message is one line."""


def _parse_value(text: str) -> Any:
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _overrides(items: list[str]) -> dict[str, dict[str, Any]]:
    """--set plant.foam_da1=0.4 controller.gamma=5 ... -> {'plant': {...}, 'sensor': {...}, 'controller': {...}}."""
    out: dict[str, dict[str, Any]] = {"plant": {}, "sensor": {}, "controller": {}}
    fields = {"plant": PlantParams.__dataclass_fields__, "sensor": SensorParams.__dataclass_fields__,
              "controller": ControllerParams.__dataclass_fields__}
    for item in items:
        key, sep, val = item.partition("=")
        comp, dot, name = key.partition(".")
        if not sep or not dot or comp not in out:
            raise UsageError(f"--set {item!r}: expected COMPONENT.PARAM=VALUE with COMPONENT plant, sensor or controller")
        if name not in fields[comp]:
            raise UsageError(f"--set {item!r}: {comp} has no parameter {name!r}")
        v = _parse_value(val)
        out[comp][name] = tuple(v) if isinstance(v, list) else v
    return out


def cmd_direct(args: argparse.Namespace) -> int:
    """Run one task of the paper through the FMI-free direct loop and print its metrics."""
    ov = _overrides(args.set or [])
    cp = ControllerParams(**{**paper.task_controller(args.task), **ov["controller"]})
    pp = PlantParams(**ov["plant"])
    sp = SensorParams(**ov["sensor"])
    res = run_direct(pp, sp, cp, t_stop=args.t_stop, h=args.step)
    goal = paper.task_goal(args.task) if cp.task == "goal" else None
    m = run_metrics(res.signals, goal)
    m.update(task=args.task, status=res.status, steps=res.steps, wall_s=round(res.wall_s, 3))
    ref = paper.rmse_table(args.task)["learn"]
    if not args.json:
        print(f"{args.task}: direct loop, {res.steps} steps of {args.step} s in {res.wall_s:.2f} s "
              f"({res.wall_s / max(res.steps, 1) * 1e6:.1f} us/step), status {res.status} {res.message}")
        print(f"{'RMSE':10s} {'ours':>8s} {'paper':>8s} {'ratio':>6s}")
        for i, (name, val) in enumerate([("e_1", m["rmse_e"][0]), ("e_2", m["rmse_e"][1]),
                                         ("e_dot_1", m["rmse_edot"][0]), ("e_dot_2", m["rmse_edot"][1])]):
            print(f"{name:10s} {val:8.4f} {ref[i]:8.4f} {val / ref[i]:6.2f}")
        x, y = m["final_position"]
        print(f"final position of A: ({x:.4f}, {y:.4f}) m", end="")
        fp = paper.results()["final_positions"].get(args.task)
        print(f"   paper: ({fp[0]:.4f}, {fp[1]:.4f}) m" if fp else "")
        if m["t_goal"] is not None:
            print(f"eps_G reached at t = {m['t_goal']:.3f} s; distance at the end {m['goal_distance']:.4f} m")
        print("final W:", " ".join(f"{w:.4f}" for w in m["final_W"]))
    print(json.dumps(m))
    return EXIT_OK if res.status == "ok" and not m["diverged"] else EXIT_FAILED


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="wmr-cosim", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    d = sub.add_parser("direct", help="run a task of the paper through the FMI-free direct loop",
                       description="Run one task of the paper (learning run: adaptation 0-39 s, reference floor) "
                                   "through the FMI-free direct loop and print its metrics beside Table 2/3.")
    d.add_argument("task", nargs="?", default="G1", choices=paper.TASKS, help="task (default G1)")
    d.add_argument("--t-stop", type=float, default=50.0, help="stop time [s] (default 50)")
    d.add_argument("--step", type=float, default=0.002, help="communication step h [s] (default 0.002)")
    d.add_argument("--set", nargs="*", metavar="COMP.PARAM=VALUE",
                   help="override parameters, e.g. plant.foam_on_time=true plant.foam_t_on=8.38 controller.gamma=5")
    d.add_argument("--json", action="store_true", help="print only the JSON line")
    d.set_defaults(func=cmd_direct)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return int(args.func(args))
    except (ParameterError, UsageError) as exc:
        print(f"wmr-cosim: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("wmr-cosim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
