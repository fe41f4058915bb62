"""A finished run served in the live view's page (``wmr-cosim view RESULTS``): its results folder read once,
the state of its end, its recorded signals streamed at once (decimated to at most :data:`MAX_ROWS` rows),
its event table and its requirements' verdicts; every command refused (409: the run has ended)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..cosim import CosimError, ResultsError, read_json
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


class FinishedRun:
    """The results folder ``folder`` as a source of the live view's server (the interface of
    :class:`.session.LiveSession`); NotResults where it is not one."""

    def __init__(self, folder: str | Path) -> None:
        from ..runs.plot import PlotError, read_results

        self.folder = Path(folder)
        try:
            res = read_results(self.folder)
            summary = read_json(self.folder / "summary.json", {"columns": dict, "events": list})
            scenario = read_json(self.folder / "scenario.json", {"experiment": dict, "instances": dict})
        except (PlotError, ResultsError) as exc:
            raise NotResults(str(exc)) from None
        names = [c for c in res.columns if res.signals.dtype[c].shape == ()]
        if not names or names[0] != "time":
            raise NotResults(f"{self.folder}: signals.npy has no time column (not a results folder of `wmr-cosim run`)")
        self.columns = names
        self.units = [res.units.get(c) if c != "time" else "s" for c in names]
        table = np.column_stack([np.asarray(res.signals[c], dtype=float) for c in names]) if len(res.signals) \
            else np.empty((0, len(names)))
        every = max(1, math.ceil(len(table) / MAX_ROWS))
        keep = list(range(0, len(table), every))
        if table.shape[0] and keep[-1] != len(table) - 1:
            keep.append(len(table) - 1)
        self.rows = [[_finite(float(x)) for x in table[k]] for k in keep]
        self.events = list(res.events)
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
            "requirements": list(res.requirements.values()), "variables": [{"name": c, "unit": u} for c, u in
                                                                          zip(names, self.units)],
            "settable": [], "xy": finished_scene(scenario, self.events, units), "note": res.note}

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
