"""A finished run served in the live view's page (``wmr-cosim view RESULTS``): its results folder read once,
the state of its end, its recorded signals streamed at once (decimated to at most :data:`MAX_ROWS` rows),
its event table and its requirements' verdicts; every command refused (409: the run has ended)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..cosim import CosimError, ResultsError, read_json, read_signals
from .scene import finished_scene
from .session import Refused

#: The rows of a finished run the page gets at most (every n-th row, the last one always): a 50 s run at
#: 2 ms has 25,001; a plot has about as many pixels across as this.
MAX_ROWS = 5000
#: The rows of one message of the stream.
ROWS_PER_MESSAGE = 1000


class NotResults(CosimError):
    """A folder that is not a results folder of ``wmr-cosim run``: one line naming it."""


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _read(folder: Path) -> tuple[Any, dict[str, Any], dict[str, Any]]:
    """The recording, summary.json and scenario.json of a results folder; NotResults (one line naming the
    folder or the file) where it is not one or a file of it cannot be read."""
    if not folder.is_dir():
        raise NotResults(f"{folder}: {'not a folder' if folder.exists() else 'no such folder'}")
    if not (folder / "signals.npy").is_file():
        raise NotResults(f"{folder}: no signals.npy (not a results folder of `wmr-cosim run`)")
    shapes: dict[str, type | tuple[type, ...]] = {"columns": dict, "events": list, "requirements": list,
                                                  "experiment": dict, "instances": dict}
    try:
        return (read_signals(folder / "signals.npy"), read_json(folder / "summary.json", shapes),
                read_json(folder / "scenario.json", shapes))
    except ResultsError as exc:
        raise NotResults(str(exc)) from None


class FinishedRun:
    """The results folder ``folder`` as a source of the live view's server (the interface of
    :class:`.session.LiveSession`); NotResults where it is not one."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        recording, summary, scenario = _read(self.folder)
        signals = recording.signals
        declared = summary.get("columns") or scenario.get("columns") or {}
        unit_of = {n: (c.get("unit") if isinstance(c, dict) else None) for n, c in declared.items()}
        fields = list(signals.dtype.names or ())
        names = list(dict.fromkeys(["time"] + [n for n in [*unit_of, *fields] if n in fields and n != "time"
                                               and signals.dtype[n].shape == () and signals.dtype[n].kind in "fiub"]))
        self.columns = names
        self.units = [unit_of.get(c) if c != "time" else "s" for c in names]
        table = np.column_stack([np.asarray(signals[c], dtype=float) for c in names]) if len(signals) \
            else np.empty((0, len(names)))
        every = max(1, math.ceil(len(table) / MAX_ROWS))
        keep = list(range(0, len(table), every))
        if table.shape[0] and keep[-1] != len(table) - 1:
            keep.append(len(table) - 1)
        self.rows = [[_finite(float(x)) for x in table[k]] for k in keep]
        self.events = [e for e in summary.get("events") or [] if isinstance(e, dict)
                       and isinstance(e.get("time"), (int, float)) and not isinstance(e.get("time"), bool)]
        exp = scenario.get("experiment") or {}
        t_end = float(table[-1, 0]) if len(table) else 0.0
        stop = exp.get("stop") if isinstance(exp.get("stop"), (int, float)) else t_end
        step = summary.get("step") if isinstance(summary.get("step"), (int, float)) else None
        units = dict(zip(names, self.units))
        self._state = {
            "mode": "finished", "folder": str(self.folder), "time": t_end, "stop_time": stop, "step": step,
            "steps": summary.get("steps"), "n_steps": summary.get("n_steps"), "paused": True, "rate": 0.0,
            "real_time_factor": None, "status": str(summary.get("status", "unknown")),
            "message": str(summary.get("message", "")), "events": [e for e in self.events if e.get("source") == "live"],
            "requirements": [r for r in summary.get("requirements") or [] if isinstance(r, dict) and "name" in r],
            "variables": [{"name": c, "unit": u} for c, u in zip(names, self.units)],
            "settable": [], "xy": finished_scene(scenario, self.events, units), "note": recording.note}

    def state(self) -> dict[str, Any]:
        return dict(self._state)

    def submit(self, kind: str, **args: Any) -> Any:
        """Every command is refused: the run has ended."""
        import concurrent.futures

        reply: concurrent.futures.Future[dict[str, Any]] = concurrent.futures.Future()
        reply.set_exception(Refused(f"{self.folder} is a finished run (wmr-cosim view): nothing to {kind}", 409))
        return reply

    def header(self) -> dict[str, Any]:
        return {"type": "columns", "columns": self.columns, "units": self.units, "events": self.events}

    def subscribe(self, sink: Callable[[dict[str, Any] | None], None]) -> Callable[[], None]:
        """The rows (in messages of ROWS_PER_MESSAGE), then the end, at once."""
        for i in range(0, len(self.rows), ROWS_PER_MESSAGE):
            sink({"type": "rows", "rows": self.rows[i:i + ROWS_PER_MESSAGE]})
        sink(None)
        return lambda: None
