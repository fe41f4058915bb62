"""``wmr-cosim direct``: a task of the paper through the FMI-free direct loop."""
from __future__ import annotations

import argparse
import json
from typing import Any

from ..components import paper
from ..components.controller import ControllerParams
from ..components.direct_loop import run_direct
from ..components.metrics import run_metrics
from ..components.plant import PlantParams
from ..components.sensor import SensorParams
from ..cosim import count, did_you_mean, parse_value, RunStatus
from ..exit_codes import OK as EXIT_OK, RUN_FAILED as EXIT_FAILED
from .options import UsageError


def add_parser(sub: Any, name: str) -> None:
    """The command ``direct`` (``name``) and its options."""
    d = sub.add_parser(name, help="run a task of the paper through the FMI-free direct loop",
                       description="Run one task of the paper (learning run: adaptation 0-39 s, reference floor) "
                                   "through the FMI-free direct loop and print its metrics beside Table 2/3.")
    d.add_argument("task", nargs="?", default="G1", choices=paper.TASKS, help="task (default G1)")
    d.add_argument("--stop", dest="t_stop", type=float, default=50.0, help="stop time [s] (default 50)")
    d.add_argument("--t-stop", dest="t_stop", type=float, default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    d.add_argument("--step", type=float, default=0.002, help="communication step h [s] (default 0.002)")
    d.add_argument("--set", action="append", metavar="COMP.PARAM=VALUE",
                   help="override a parameter, e.g. --set controller.gamma=5 (one per --set; repeat it: "
                        "--set plant.foam_on_time=true --set plant.foam_t_on=8.38)")
    d.add_argument("--json", action="store_true", help="print only the JSON line")
    d.set_defaults(func=cmd_direct, subparser=d)


def _overrides(items: list[str]) -> dict[str, dict[str, Any]]:
    """['plant.foam_da1=0.4', 'controller.gamma=5'] (one per --set) -> {'plant': {...}, 'sensor': {...},
    'controller': {...}}."""
    out: dict[str, dict[str, Any]] = {"plant": {}, "sensor": {}, "controller": {}}
    fields = {"plant": PlantParams.__dataclass_fields__, "sensor": SensorParams.__dataclass_fields__,
              "controller": ControllerParams.__dataclass_fields__}
    for item in items:
        key, sep, val = item.partition("=")
        comp, dot, name = key.partition(".")
        if not sep or not dot or comp not in out:
            raise UsageError(f"--set {item!r}: expected COMPONENT.PARAM=VALUE with COMPONENT plant, sensor or controller"
                             f"{did_you_mean(comp, out) if sep and dot else ''}")
        if name not in fields[comp]:
            raise UsageError(f"--set {item!r}: {comp} has no parameter {name!r}{did_you_mean(name, fields[comp])}")
        v = parse_value(val)
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
        print(f"{args.task}: direct loop, {count(res.steps, 'step')} of {args.step} s in {res.wall_s:.2f} s "
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
    return EXIT_OK if res.status == RunStatus.OK and not m["diverged"] else EXIT_FAILED

