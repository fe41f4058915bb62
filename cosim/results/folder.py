"""A run's results: its folder (made, locked, emptied of an earlier run's files, or temporary), the
resolved scenario written before the first step, and at the end signals.csv, signals.mat (when asked),
summary.json and the :class:`RunResult` the drivers get."""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..plan.records import Plan
from ..stepping import table as algorithms
from .formats import RECORDING, RESULT_FORMATS
from .recording import OutputLock, make_folder, write_json
from .status import RunStatus


@dataclass
class RunResult:
    """How a run ended and what it gave."""

    status: RunStatus
    message: str
    steps: int
    t_end: float                # [s]
    wall_s: float               # the stepping loop, first step to last, recording included
    setup_s: float              # extraction, instantiation, initialisation
    out_dir: Path | None        # None: the folder was temporary and is gone
    columns: list[str]
    final: dict[str, float] = field(default_factory=dict)
    fmi_s: float | None = None  # time inside FMI calls (only with timing=True)
    events: list[dict[str, Any]] = field(default_factory=list)   # the event table (.event_log): time, source, kind, what
    real_time: dict[str, Any] | None = None   # pacing: factor, steps, overruns, late_max_s, late_mean_s
    summary: dict[str, Any] = field(default_factory=dict)      # summary.json
    scenario: dict[str, Any] = field(default_factory=dict)     # scenario.json (the scenario as resolved)
    signals: np.ndarray | None = None   # the recording in memory (when the execution was asked to keep it)
    stepping: dict[str, Any] | None = None   # the algorithm's own counts (iterations, accepted/rejected steps)
    events_left_out: int = 0   # entries of the event table beyond its limit (.event_log.MAX_ENTRIES)
    handoff: dict[str, Any] | None = None   # how the master and the child processes waited (instances.handoff)
    requirements: list[dict[str, Any]] = field(default_factory=list)   # each requirement's verdict


class ResultsFolder:
    """The folder a run writes (``out``), locked for the run and emptied of an earlier run's result files."""

    def __init__(self, out: str | Path) -> None:
        self.path = make_folder(Path(out))
        self.lock = OutputLock(self.path)
        self.lock.acquire()

    def prepare(self, plan: Plan) -> None:
        """logs/ made, stale signals, summary and logs removed, scenario.json written."""
        out = self.path
        (out / "logs").mkdir(exist_ok=True)
        for stale in (*(f.file for f in RESULT_FORMATS.values()), "summary.json", "requirements.npy"):
            (out / stale).unlink(missing_ok=True)
        for old in (out / "logs").glob("*.log"):
            old.unlink()
        write_json(out / "scenario.json", resolved(plan))

    @property
    def logs(self) -> Path:
        return self.path / "logs"

    @property
    def signals(self) -> Path:
        return self.path / RESULT_FORMATS[RECORDING].file

    def release(self) -> None:
        self.lock.release()


def summary(plan: Plan, res: RunResult, rows: int, logs: dict[str, tuple[int, int]]) -> dict[str, Any]:
    """summary.json: ``logs`` gives each instance's (lines kept, messages received)."""
    sc = plan.scenario
    return {
        "status": res.status, "message": res.message, "steps": res.steps, "n_steps": plan.n_steps,
        "t_end": res.t_end, "step": sc.step, **({"last_step": plan.last_step} if plan.last_step is not None else {}),
        "algorithm": sc.algorithm, "wall_s": round(res.wall_s, 6),
        "setup_s": round(res.setup_s, 6),
        "us_per_step": round(res.wall_s / res.steps * 1e6, 3) if res.steps else None,
        "rows": rows,
        "instances": {n: {"fmu": str(ip.model.path), "model": ip.model.model_name, "interface": ip.interface,
                          "log_lines": logs.get(n, (0, 0))[0], "log_received": logs.get(n, (0, 0))[1]}
                      for n, ip in plan.instances.items()},
        "final": res.final,
        "columns": plan.columns(),
        "not_recorded": plan.not_recorded,
        "events": res.events,
        **({"events_left_out": res.events_left_out} if res.events_left_out else {}),
        **({"real_time": res.real_time} if res.real_time is not None else {}),
        **({"stepping": res.stepping} if res.stepping is not None else {}),
        **({"handoff": res.handoff} if res.handoff is not None else {}),
        **({"requirements": res.requirements} if res.requirements else {}),
    }


def write_robustness(path: Path, signals: dict[str, np.ndarray], times: list[float]) -> None:
    """requirements.npy: a structured array, ``time`` [s] and each requirement's robustness by name, one
    row per communication point monitored (NaN where a window the run cut leaves it unknown).  A name
    beyond Latin-1 takes the .npy format 3.0 (its header in UTF-8; NumPy 1.17 on reads it)."""
    rows = len(times)
    data = np.zeros(rows, dtype=[("time", "<f8")] + [(name, "<f8") for name in signals])
    data["time"] = times
    for name, values in signals.items():
        data[name] = values[:rows]
    latin1 = all(ord(c) < 256 for name in signals for c in name)
    with open(path, "wb") as f:
        np.lib.format.write_array(f, data, version=None if latin1 else (3, 0), allow_pickle=False)


def write_results(folder: ResultsFolder, plan: Plan, res: RunResult) -> None:
    """The result formats beside the recording (signals.csv, signals.mat: each when the scenario's flag
    asks for it and something was recorded) and summary.json (``res.summary``)."""
    for f in RESULT_FORMATS.values():
        if res.final and f.writer is not None and f.flag is not None and getattr(plan.scenario, f.flag):
            f.writer(folder.signals, folder.path / f.file, plan)
    write_json(folder.path / "summary.json", res.summary)


def scenario_record(plan: Plan) -> dict[str, Any]:
    """scenario.json's content as it reads back (JSON's types: lists, strings for what JSON has no type
    for), for the result of a run with a folder or without."""
    return json.loads(json.dumps(resolved(plan), default=str))


def resolved(plan: Plan) -> dict[str, Any]:
    """scenario.json: the scenario as resolved (times, instances with their parameters, connections with
    their folded factors, what is recorded, the events) and the document it came from."""
    sc = plan.scenario
    return {"file": sc.file, "experiment": {"start": sc.start, "stop": sc.stop, "step": sc.step,
                                            "algorithm": sc.algorithm, "order": sc.order, "workers": sc.workers,
                                            "tolerance": sc.tolerance,
                                            **{t.name: sc.settings[t.name].as_dict() for t in algorithms.TABLES
                                               if t.name in sc.settings}},
            "instances": {n: {"fmu": str(ip.model.path), "model": ip.model.model_name,
                              "parameters": {v.name: val for v, val in ip.parameters},
                              "names": ip.spec.names, "units": ip.spec.units, "logging": ip.spec.logging,
                              "tolerance": ip.tolerance, "interface": ip.interface,
                              **({"solver": dataclasses.asdict(ip.solver)} if ip.solver is not None else {})}
                          for n, ip in plan.instances.items()},
            "connections": [{"from": c.spec.src, "to": c.spec.dst, "factor": c.factor, "offset": c.offset}
                            for c in plan.connections],
            "record": [r.column for r in plan.record], "columns": plan.columns(), "decimation": sc.decimation,
            "events": [{"time": e.time, "variable": e.ref, "action": e.action, "value": e.value,
                        **({"when": e.when, "trigger": e.trigger, "delay": e.delay} if e.when else {})}
                       for e in sorted(plan.events + plan.conditions, key=lambda e: e.index)],
            "document": sc.data}
