"""The Python API: a co-simulation from a script or a notebook, a thin layer over the master (``cosim``).

    from wmr_cosim import Simulation

    sim = Simulation.load("g1_learn.toml")          # a scenario file (or a shipped scenario's name)
    sim.parameter("controller.gamma", 8.0)          # as --set on the command line
    result = sim.run()                              # Result: signals (numpy), dataframe(), summary, scenario

    with sim.start() as run:                        # stepwise: initialised, at the start time
        run.step_to(10.0)
        run.set("controller.goal_x", 1.0)           # a tunable parameter, an input, an output feeding inputs
        run.on_step(lambda r: ...)                  # called after every step (read with get, change with set)
        result = run.finish()

A scenario is a document (the dict a TOML file gives), built in code with :meth:`Simulation.instance`,
:meth:`~Simulation.connect`, :meth:`~Simulation.record`, :meth:`~Simulation.event`, or loaded from a file.
Every check is the command line's (``cosim.scenario.parse`` and ``cosim.system.resolve``), raised as the
same exceptions: :class:`ScenarioError` (``file``, ``field``, ``reason``) for bad input, :class:`RunError`
for a run that failed.  See docs/scripting.md.
"""
from __future__ import annotations

import copy
import json
import math
import shutil
import tempfile
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .cosim import scenario, system
from .cosim.errors import CosimError, RunError, ScenarioError
from .cosim.kinds import FileKind, file_kind
from .cosim.status import RunStatus
from .cosim.execution import Execution, _Interrupt, _prepare, _results, _Stop, _Stopped
from .cosim.pacing import Pacer
from .cosim.recording import OutputLock, make_folder

__all__ = ["Simulation", "Run", "Result", "RunStatus", "ScenarioError", "RunError", "CosimError"]


@dataclass
class Result:
    """A finished run.  ``signals`` is the recording (a numpy structured array: one field per recorded
    variable plus ``time`` [s]); ``summary`` is summary.json (status, steps, wall time, final values, the
    event log, the real-time figures); ``scenario`` is scenario.json (the scenario as resolved)."""

    status: RunStatus                # how the run ended (cosim.status.RunStatus: a str, "ok", "failed", ...)
    message: str
    steps: int
    t_end: float                     # [s]
    signals: np.ndarray
    summary: dict[str, Any]
    scenario: dict[str, Any]
    out_dir: Path | None             # None: the results folder was temporary and is gone
    events: list[dict[str, Any]] = field(default_factory=list)   # the event log: time, event, action, ...

    @property
    def ok(self) -> bool:
        """The run reached its stop time, or ended cleanly earlier (an FMU or a stop event ended it)."""
        return RunStatus(self.status).ended_well

    def __getitem__(self, name: str) -> np.ndarray:
        """One recorded signal, e.g. ``result["plant.x_A"]``."""
        return self.signals[name]

    @property
    def final(self) -> dict[str, Any]:
        """The last recorded value of each column."""
        return dict(self.summary.get("final", {}))

    def dataframe(self):
        """The signals as a pandas DataFrame, one column per variable, indexed by time [s] (needs pandas)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Result.dataframe() needs pandas: pip install pandas "
                              "(result.signals is the same data as a numpy array)") from None
        return pd.DataFrame(self.signals).set_index("time")


class Simulation:
    """A scenario to check and run: loaded from a file or built in code.  Methods that change it return
    the simulation, so calls chain: ``Simulation().instance(...).connect(...).record(...)``."""

    def __init__(self, document: dict[str, Any] | None = None, *, file: str = "<simulation>") -> None:
        """``document``: a scenario as the dict a TOML file gives (FMU paths absolute, or model names);
        ``file`` names it in error messages."""
        self.document: dict[str, Any] = copy.deepcopy(document) if document is not None else {}
        self.file = str(file)
        self._overrides: dict[str, Any] = {}

    # ------------------------------------------------------------------ where it comes from
    @classmethod
    def load(cls, path: str | Path, parameters: dict[str, Any] | None = None) -> "Simulation":
        """A scenario file (``.toml``, following its ``base`` chain; a name that is not a file is looked up
        among the shipped scenarios, as on the command line) or one FMU run alone (``.fmu``).
        ``parameters`` ({"instance.param": value}) are applied as ``--set`` applies them."""
        from .runner import fmu_document, is_fmu
        from .scenario_files import scenario_path

        p = scenario_path(str(path))
        if is_fmu(p):
            try:
                doc = fmu_document(p)
            except CosimError as exc:
                raise ScenarioError(str(p), "", str(exc).replace(f"{Path(p).resolve()}: ", "", 1)) from None
        elif file_kind(p) is FileKind.SSP:
            raise ScenarioError(str(p), "", "an SSP archive: the API loads scenario files (.toml) and FMUs (.fmu); "
                                            "run an archive with `wmr-cosim run`")
        else:
            doc = scenario._read(Path(p))
        sim = cls(doc, file=str(p))
        for ref, value in (parameters or {}).items():
            sim.parameter(ref, value)
        return sim

    # ------------------------------------------------------------------ building in code
    def experiment(self, **fields: Any) -> "Simulation":
        """Set ``[experiment]`` keys: start, stop, step [s], algorithm, order, tolerance, max_steps."""
        self.document.setdefault("experiment", {}).update(fields)
        return self

    def instance(self, name: str, fmu: str | Path, **parameters: Any) -> "Simulation":
        """Add an instance: ``fmu`` a model name (WmrPlant, WmrSensor, WmrController, WmrCPlant) or a path
        to an .fmu; keyword arguments are its parameters and start values."""
        fmu = str(Path(fmu).resolve()) if scenario._is_path(str(fmu)) else str(fmu)
        inst: dict[str, Any] = {"fmu": fmu}
        if parameters:
            inst["parameters"] = dict(parameters)
        self.document.setdefault("instances", {})[name] = inst
        order = self.document.get("experiment", {}).get("order")
        if isinstance(order, list) and name not in order:
            order.append(name)
        return self

    def connect(self, src: str, dst: str, *, factor: float | None = None, offset: float | None = None,
                **more: Any) -> "Simulation":
        """Connect an output ``"instance.output"`` to an input ``"instance.input"`` (``dst = factor * src +
        offset`` after unit conversion; ``convert``, ``threshold`` as in a scenario file)."""
        c: dict[str, Any] = {"from": src, "to": dst, **more}
        if factor is not None:
            c["factor"] = factor
        if offset is not None:
            c["offset"] = offset
        self.document.setdefault("connections", []).append(c)
        return self

    def record(self, *variables: str, decimation: int | None = None, csv: bool | None = None) -> "Simulation":
        """Record these variables (names or patterns such as ``"controller.W*"``; added to the list)."""
        rec = self.document.setdefault("record", {})
        rec["variables"] = list(rec.get("variables", [])) + list(variables)
        if decimation is not None:
            rec["decimation"] = decimation
        if csv is not None:
            rec["csv"] = csv
        return self

    def event(self, **fields: Any) -> "Simulation":
        """Add an event, with the keys of ``[[events]]``: ``time`` or ``when`` (a condition such as
        ``"plant.y_A > 1.5 and t > 5"``), ``trigger`` (once, each), ``delay`` [s], ``variable``, ``action``
        (override, bias, reset, set, stop), ``value``."""
        self.document.setdefault("events", []).append(dict(fields))
        return self

    def parameter(self, ref: str, value: Any) -> "Simulation":
        """Override a parameter or start value, ``"instance.param"``, as ``--set`` does."""
        self._overrides[ref] = value
        return self

    # ------------------------------------------------------------------ checking and running
    def scenario(self) -> scenario.Scenario:
        """The parsed scenario (every structural check; ScenarioError naming the file, field and reason)."""
        from .runner import resolve_model

        doc = scenario.apply_overrides(copy.deepcopy(self.document), self._overrides, self.file)
        sc = scenario.parse(doc, self.file, resolve_model)
        if sc.runs:
            raise ScenarioError(self.file, "runs", "a protocol (several runs): run it with `wmr-cosim run`, or "
                                                   "make one Simulation per run")
        return sc

    def check(self, force: bool = False) -> system.Plan:
        """Every check ``wmr-cosim check`` makes, against the FMUs (built on demand); returns the plan, or
        raises the ScenarioError the command line prints."""
        return system.resolve(self.scenario(), force)

    def start(self, out: str | Path | None = None, *, real_time: float | None = None,
              progress: bool | None = False, force: bool = False) -> "Run":
        """Check, load and initialise: a :class:`Run` at the start time, to step, read and change.
        ``out``: the results folder (None: a temporary one, removed when the run ends)."""
        return Run(self.check(force), out, real_time=real_time, progress=progress)

    def run(self, out: str | Path | None = None, *, real_time: float | None = None,
            on_step: Callable[["Run"], Any] | list[Callable[["Run"], Any]] | None = None,
            progress: bool | None = False, force: bool = False, raise_on_failure: bool = True) -> Result:
        """Run to the stop time; ``on_step`` (a function or a list) is called with the :class:`Run` after
        every step.  A failed run raises RunError (the message the command line prints), unless
        ``raise_on_failure=False``, which returns it with status "failed"."""
        with self.start(out, real_time=real_time, progress=progress, force=force) as r:
            for fn in ([on_step] if callable(on_step) else list(on_step or [])):
                r.on_step(fn)
            return r.finish(raise_on_failure=raise_on_failure)


class Run:
    """A run in progress: the FMUs loaded and initialised, stepped on demand.  Use it as a context
    manager (or call :meth:`finish` or :meth:`close`) so every FMU is freed."""

    def __init__(self, plan: system.Plan, out: str | Path | None = None, *, real_time: float | None = None,
                 progress: bool | None = False) -> None:
        self.plan = plan
        self.result: Result | None = None
        self._keep = out is not None
        pacer = Pacer(real_time) if real_time is not None else None
        self._out = make_folder(Path(out)) if self._keep else Path(tempfile.mkdtemp(prefix="wmr-cosim-out-"))
        self._lock = OutputLock(self._out)
        self._lock.acquire()
        self._ex: Execution | None = None
        self._vars: dict[str, tuple[str, Any]] = {}
        self._readers: dict[str, Callable[[], Any]] = {}   # ref -> a function returning its current value
        try:
            _prepare(self._out, plan)
            ex = self._ex = Execution(plan, self._out)
            ex.pacer = pacer
            t0 = _time.perf_counter()
            ex.load()
            ex.initialise(True)
            ex.setup_s = _time.perf_counter() - t0
            ex.begin(progress, True, None)
        except BaseException as exc:
            if self._ex is not None:
                self._ex.status, self._ex.message = RunStatus.FAILED, str(exc)
            self._end(raise_on_failure=False)
            raise

    # ------------------------------------------------------------------ time
    @property
    def time(self) -> float:
        """The current communication point t_k = start + k h [s]."""
        ex = self._ex
        return ex.t0 + ex.k_done * ex.h

    @property
    def steps(self) -> int:
        """Steps done."""
        return self._ex.k_done

    @property
    def finished(self) -> bool:
        return self.result is not None

    def step(self, n: int = 1) -> "Run":
        """Do ``n`` communication steps (fewer at the stop time or when the run ends)."""
        return self._advance(self._ex.k_done + int(n))

    def step_to(self, t: float) -> "Run":
        """Step until the communication point at or after ``t`` [s] (at most the stop time)."""
        ex = self._ex
        return self._advance(int(math.ceil((float(t) - ex.t0) / ex.h - 1e-9)))

    def finish(self, raise_on_failure: bool = True) -> Result:
        """Step to the stop time (unless the run has ended) and return the result."""
        if self.result is None:
            try:
                self._advance(self._ex.n_steps)
            except RunError:
                if raise_on_failure:
                    raise
        if self.result is None:
            self._end(raise_on_failure)
        return self.result

    def close(self) -> Result:
        """End the run now (status "stopped" if it had not ended), free the FMUs; returns the result."""
        if self.result is None:
            ex = self._ex
            if ex.k_done < ex.n_steps and ex.status == RunStatus.OK:
                ex.status, ex.message = RunStatus.STOPPED, f"closed at t = {self.time:.6g} s"
            self._end(raise_on_failure=False)
        return self.result

    def stop(self, reason: str = "") -> None:
        """End the run cleanly at the current time (from a callback or between steps): status "stopped"."""
        if self.result is None:
            ex = self._ex
            ex.status, ex.message = RunStatus.STOPPED, f"stopped by the script at t = {self.time:.6g} s" + \
                (f": {reason}" if reason else "")
            ex.stop_request = True
            if not ex.in_step:
                self._end(raise_on_failure=False)

    def __enter__(self) -> "Run":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ values between steps
    def _lookup(self, ref: str) -> tuple[str, Any]:
        got = self._vars.get(ref)
        if got is None:
            inst, name = scenario.split_ref(self.plan.scenario.file, ref, ref)
            if inst not in self.plan.instances:
                raise ScenarioError(self.plan.scenario.file, ref, f"unknown instance {inst!r}")
            got = self._vars[ref] = (inst, system._var(self.plan.scenario.file, ref, self.plan.instances[inst], name))
        return got

    def get(self, ref: str) -> Any:
        """The current value of ``"instance.variable"`` (any variable: an output, an input, a parameter).
        A Float64 output the loop reads at every step gives its value at the last communication point (as
        recorded, and as conditions see it); any other variable is asked of the FMU, so an output with
        direct feedthrough already reflects an input :meth:`set` since that point."""
        read = self._readers.get(ref)
        if read is None or self.result is not None:
            self._alive()
            inst, var = self._lookup(ref)
            read = self._readers[ref] = self._ex._reader(inst, var)
        return read()

    def set(self, ref: str, value: Any) -> None:
        """Change ``"instance.variable"`` from the next step on: a tunable parameter; a Real input (its
        connection is overridden until :meth:`release`); an output feeding connections (what they carry);
        an input no connection drives.  The value is checked against the variable's type and range."""
        self._alive()
        inst, var = self._lookup(ref)
        self._ex.set(inst, var, system._value(self.plan.scenario.file, ref, var, value))

    def release(self, ref: str) -> None:
        """End an override :meth:`set` put on a connected input or an output."""
        self._alive()
        inst, var = self._lookup(ref)
        self._ex.release(inst, var)

    def on_step(self, fn: Callable[["Run"], Any]) -> Callable[["Run"], Any]:
        """Call ``fn(run)`` after every step from now on (an observer reads with :meth:`get`, a
        manipulator changes inputs with :meth:`set`; :meth:`stop` ends the run).  Returns ``fn``."""
        self._alive()
        self._ex.callbacks.append(lambda: fn(self))
        return fn

    @property
    def events(self) -> list[dict[str, Any]]:
        """The event log so far: time, event, action, ..."""
        return list(self._ex.event_log)

    # ------------------------------------------------------------------ internals
    def _alive(self) -> None:
        if self.result is not None:
            raise CosimError(f"the run has ended ({self.result.status}: {self.result.message or 'at the stop time'})")

    def _advance(self, k: int) -> "Run":
        self._alive()
        ex = self._ex
        stop = _Interrupt()
        ex._stop = stop
        try:
            ex.advance(k)
        except (_Stop, _Stopped) as s:
            ex.ended(s)
        except KeyboardInterrupt:
            ex.status, ex.message = RunStatus.INTERRUPTED, f"interrupted by the user at t = {self.time:.6g} s"
            stop.restore()
            self._end(raise_on_failure=False)
            raise
        except CosimError as exc:
            ex.status, ex.message = RunStatus.FAILED, str(exc)
        except Exception as exc:   # a callback's own error: the run ends failed, the error goes to the script
            ex.status = RunStatus.FAILED
            ex.message = f"a callback raised {type(exc).__name__}: {exc} at t = {self.time:.6g} s"
            stop.restore()
            self._end(raise_on_failure=False)
            raise
        finally:
            stop.restore()
            ex._stop = None
        if ex.status != RunStatus.OK or ex.k_done >= ex.n_steps or ex.stop_request:
            self._end(raise_on_failure=True)
        return self

    def _end(self, raise_on_failure: bool) -> None:
        """Free the FMUs, write summary.json, load the results, release the folder."""
        ex = self._ex
        try:
            if ex is not None:
                ex.end()
                ex.close()
                _results(ex, self._keep)
                data = np.load(self._out / "signals.npy") if (self._out / "signals.npy").is_file() else \
                    np.zeros(0, dtype=[("time", "f8")])
                summary = json.loads((self._out / "summary.json").read_text())
                resolved = json.loads((self._out / "scenario.json").read_text())
                self.result = Result(ex.status, ex.message, ex.k_done, summary["t_end"], data, summary, resolved,
                                     self._out if self._keep else None, list(ex.event_log))
        finally:
            self._lock.release()
            if not self._keep:
                shutil.rmtree(self._out, ignore_errors=True)
        if raise_on_failure and self.result is not None and self.result.status == RunStatus.FAILED:
            raise RunError(self.result.message)
