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
Every check is the command line's (``cosim.parse`` and ``cosim.resolve``), raised as the
same exceptions: :class:`ScenarioError` (``file``, ``field``, ``reason``) for bad input, :class:`RunError`
for a run that failed.  See docs/scripting.md.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .cosim import (apply_overrides, CosimError, Execution, file_kind, FileKind, is_path, layout, MatLayout, parse
                    as parse_scenario, Plan, read_document, resolve, RunError, RunStatus, Scenario, ScenarioError,
                    write_mat)

__all__ = ["Simulation", "Run", "Result", "RunStatus", "ScenarioError", "RunError", "CosimError"]


@dataclass
class Result:
    """A finished run.  ``signals`` is the recording (a numpy structured array: one field per recorded
    variable plus ``time`` [s]); ``summary`` is summary.json (status, steps, wall time, final values, the
    event log, the real-time figures); ``scenario`` is scenario.json (the scenario as resolved)."""

    status: RunStatus                # how the run ended (cosim.results.status.RunStatus: a str, "ok", "failed", ...)
    message: str
    steps: int
    t_end: float                     # [s]
    signals: np.ndarray
    summary: dict[str, Any]
    scenario: dict[str, Any]
    out_dir: Path | None             # None: the results folder was temporary and is gone
    events: list[dict[str, Any]] = field(default_factory=list)   # the event log: time, event, action, ...
    mat_layout: MatLayout | None = field(default=None, repr=False)   # descriptions, units, constants (MAT)

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

    @property
    def requirements(self) -> dict[str, dict[str, Any]]:
        """Each requirement's verdict by name: ``verdict`` ("holds", "violated", "undecided"),
        ``robustness`` (in ``unit``) and ``at`` [s], ``first_violation`` [s] (None), ``decided_at`` [s]."""
        return {r["name"]: dict(r) for r in self.summary.get("requirements", [])}

    def dataframe(self):
        """The signals as a pandas DataFrame, one column per variable, indexed by time [s] (needs pandas)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Result.dataframe() needs pandas: pip install pandas "
                              "(result.signals is the same data as a numpy array)") from None
        return pd.DataFrame(self.signals).set_index("time")

    def write_mat(self, path: str | Path) -> Path:
        """Write the signals to ``path`` in Dymola's result layout (MAT v4: ``Aclass``, ``name``,
        ``description`` with each unit as ``text [unit]``, ``dataInfo``, ``data_1`` the parameters the
        scenario sets, ``data_2`` time [s] and every recorded column as float64), as ``[record] mat = true``
        writes signals.mat; DyMat, OMEdit and ``scipy.io.loadmat`` read it.  Returns the path; ValueError
        when nothing was recorded."""
        spec = self.mat_layout or MatLayout.from_columns(self.summary.get("columns", {}))
        return write_mat(path, self.signals, spec)


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
        from .scenario_files import shipped_folder
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
            doc = read_document(Path(p), shipped=shipped_folder())
        sim = cls(doc, file=str(p))
        for ref, value in (parameters or {}).items():
            sim.parameter(ref, value)
        return sim

    # ------------------------------------------------------------------ building in code
    def experiment(self, **fields: Any) -> "Simulation":
        """Set ``[experiment]`` keys: start, stop, step [s], algorithm, order, tolerance, max_steps, and the
        tables of the algorithms beyond one pass per step, checked as a scenario file's:
        ``.experiment(algorithm="iterated", iteration={"method": "newton", "tolerance": 1e-10})``,
        ``.experiment(algorithm="adaptive", adaptive={"rtol": 1e-5, "atol": 1e-7, "max_step": 0.01})``."""
        self.document.setdefault("experiment", {}).update(fields)
        return self

    def instance(self, name: str, fmu: str | Path, *, fields: dict[str, Any] | None = None,
                 **parameters: Any) -> "Simulation":
        """Add an instance: ``fmu`` a model name (WmrPlant, WmrSensor, WmrController, WmrCPlant) or a path
        to an .fmu; keyword arguments are its parameters and start values; ``fields``: the other keys of
        ``[instances.NAME]`` (``logging``, ``isolate``, ``tolerance``, ``step`` [s] (its own rate, a whole
        multiple of the experiment's step), ``interface``, ``solver``, ``max_step`` [s],
        ``event_tolerance`` [s], ...), checked as a scenario file's:
        ``.instance("plant", "Plant.fmu", fields={"solver": "rk4", "max_step": 1e-3})`` runs it as model
        exchange with RK4."""
        fmu = str(Path(fmu).resolve()) if is_path(str(fmu)) else str(fmu)
        inst: dict[str, Any] = {**(fields or {}), "fmu": fmu}
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

    def record(self, *variables: str, decimation: int | None = None, csv: bool | None = None,
               mat: bool | None = None, event_rows: bool | None = None) -> "Simulation":
        """Record these variables (names or patterns such as ``"controller.W*"``; added to the list);
        ``csv``, ``mat``: whether the results folder gets signals.csv, signals.mat (``[record]`` csv, mat);
        ``event_rows``: rows before and after each event of a lone model-exchange instance
        (``[record] event_rows``)."""
        rec = self.document.setdefault("record", {})
        rec["variables"] = list(rec.get("variables", [])) + list(variables)
        if decimation is not None:
            rec["decimation"] = decimation
        if csv is not None:
            rec["csv"] = csv
        if mat is not None:
            rec["mat"] = mat
        if event_rows is not None:
            rec["event_rows"] = event_rows
        return self

    def event(self, **fields: Any) -> "Simulation":
        """Add an event, with the keys of ``[[events]]``: ``time`` or ``when`` (a condition such as
        ``"plant.y_A > 1.5 and t > 5"``), ``trigger`` (once, each), ``delay`` [s], ``variable``, ``action``
        (override, bias, reset, set, stop), ``value``."""
        self.document.setdefault("events", []).append(dict(fields))
        return self

    def require(self, name: str, formula: str, *, on_violation: str = "record", description: str = "") -> "Simulation":
        """Add a requirement, as ``[[requirements]]``: its ``name``, its ``formula`` in signal temporal logic
        (e.g. ``"always[10,30] abs(controller.e1) < 0.05 rad"``; docs/requirements.md), and whether a
        violation is recorded (``"record"``) or stops the run (``"stop"``: status "violated")."""
        self.document.setdefault("requirements", []).append(
            {"name": name, "formula": formula, "on_violation": on_violation, "description": description})
        return self

    def parameter(self, ref: str, value: Any) -> "Simulation":
        """Override a parameter or start value, ``"instance.param"``, as ``--set`` does."""
        self._overrides[ref] = value
        return self

    # ------------------------------------------------------------------ checking and running
    def scenario(self) -> Scenario:
        """The parsed scenario (every structural check; ScenarioError naming the file, field and reason)."""
        from .runner import resolve_model

        doc = apply_overrides(copy.deepcopy(self.document), self._overrides, self.file)
        sc = parse_scenario(doc, self.file, resolve_model)
        if sc.runs:
            raise ScenarioError(self.file, "runs", "a protocol (several runs): run it with `wmr-cosim run`, or "
                                                   "make one Simulation per run")
        return sc

    def check(self, force: bool = False) -> Plan:
        """Every check ``wmr-cosim check`` makes, against the FMUs (built on demand); returns the plan, or
        raises the ScenarioError the command line prints."""
        return resolve(self.scenario(), force)

    def linearize(self, at: float | None = None, **request: Any) -> Any:
        """A linear model around t = ``at`` [s] of this scenario's run (docs/linearisation.md): the keyword
        arguments of :class:`wmr_cosim.cosim.Request` (``inputs``, ``outputs``, ``breaks=("FROM", "TO")``,
        ``discrete``, ``method``, ``steps``, ``order``, ``pulse``, ``states``, ``phase_budget``); returns the
        :class:`~wmr_cosim.cosim.Linearisation` (``.model.statespace()``, ``.loop.gain_margin``, ...)."""
        from .cosim import Linearizer, Request

        return Linearizer(self.check(), Request(at=at, **request)).run()

    def export_fmu(self, out: str | Path, name: str | None = None, fmi: int = 2) -> Path:
        """Write this scenario's system as one co-simulation FMU ``out`` (.fmu), whose outputs in any FMI host
        equal :meth:`run`'s bit for bit (docs/export-fmu.md); checked as ``wmr-cosim export-fmu`` checks it:
        ScenarioError for what it cannot hold, nothing written.  ``name``: its model name and identifier, a C
        name (default: the scenario file's name; ``system`` for one built in code); ``fmi``: the FMI version
        of its interface, 2 or 3 (whatever the FMI versions of the FMUs inside).  Returns the FMU's path."""
        from .cosim import export_fmu

        if file_kind(out) is not FileKind.FMU:
            raise ScenarioError(self.file, "out", f"{str(out)!r}: an FMU's name ends in .fmu")
        if fmi not in (2, 3) or isinstance(fmi, bool):
            raise ScenarioError(self.file, "fmi", f"{fmi!r}: the container's FMI version is 2 or 3")
        if name is None and not Path(self.file).suffix:
            name = "system"
        return export_fmu(self.check(), out, name, fmi)

    def start(self, out: str | Path | None = None, *, real_time: float | None = None,
              progress: bool | None = False, force: bool = False) -> "Run":
        """Check, load and initialise: a :class:`Run` at the start time, to step, read and change.
        ``out``: the results folder (None: none, the run kept in memory)."""
        return Run(self.check(force), out, real_time=real_time, progress=progress)

    def run(self, out: str | Path | None = None, *, real_time: float | None = None,
            on_step: Callable[["Run"], Any] | list[Callable[["Run"], Any]] | None = None,
            progress: bool | None = False, force: bool = False, raise_on_failure: bool = True,
            live: bool = False, port: int = 0, host: str = "127.0.0.1", paused: bool = False) -> Result:
        """Run to the stop time; ``on_step`` (a function or a list) is called with the :class:`Run` after
        every step.  A failed run raises RunError (the message the command line prints), unless
        ``raise_on_failure=False``, which returns it with status "failed".

        ``live=True`` serves the run while it goes, as ``wmr-cosim run --live`` (docs/live.md): on ``host``
        (127.0.0.1; another interface requires the token printed in the address) and ``port`` (0: a free
        one), its address printed on stderr, ``paused`` to start paused; ``out`` then gets replay.toml too.
        It needs the live extra (CosimError naming what is missing) and takes no ``on_step``."""
        if live:
            return self._run_live(out, real_time, force, raise_on_failure, port, host, paused, on_step)
        with self.start(out, real_time=real_time, progress=progress, force=force) as r:
            for fn in ([on_step] if callable(on_step) else list(on_step or [])):
                r.on_step(fn)
            return r.finish(raise_on_failure=raise_on_failure)

    def _run_live(self, out: str | Path | None, real_time: float | None, force: bool,
                  raise_on_failure: bool, port: int, host: str, paused: bool, on_step: Any) -> Result:
        """:meth:`run` with ``live=True``."""
        import ipaddress

        from .live import LiveOptions, run_live

        if on_step:
            raise ScenarioError(self.file, "on_step", "a live run is steered through its API: it takes no on_step")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ScenarioError(self.file, "port", f"{port!r}: a port number is 0 (any free port) to 65535")
        try:
            host = host if host == "localhost" else str(ipaddress.ip_address(host))
        except ValueError:
            raise ScenarioError(self.file, "host", f"{host!r}: an IP address to serve on") from None
        plan = self.check(force)
        result = _result_of(run_live(plan, out, LiveOptions(host, port, paused), real_time=real_time,
                                     keep_signals=True), plan)
        if raise_on_failure and result.status == RunStatus.FAILED:
            raise RunError(result.message)
        return result


def _result_of(r: Any, plan: Plan) -> Result:
    """The :class:`Result` of the master's RunResult ``r`` of a run of ``plan``."""
    signals = r.signals if r.signals is not None else np.zeros(0, dtype=[("time", "f8")])
    return Result(r.status, r.message, r.steps, r.t_end, signals, r.summary, r.scenario, r.out_dir, list(r.events),
                  layout(plan))


class Run:
    """A run in progress: the FMUs loaded and initialised, stepped on demand (a driver of the master's
    :class:`~wmr_cosim.cosim.runtime.execution.Execution`).  Use it as a context manager (or call :meth:`finish`
    or :meth:`close`) so every FMU is freed."""

    def __init__(self, plan: Plan, out: str | Path | None = None, *, real_time: float | None = None,
                 progress: bool | None = False) -> None:
        self.plan = plan
        self.result: Result | None = None
        self._ex = Execution(plan, out, progress=progress, real_time=real_time, keep_signals=True)
        try:
            self._ex.initialize()
        except BaseException:
            self._take_result(raise_on_failure=False)
            raise

    # ------------------------------------------------------------------ time
    @property
    def time(self) -> float:
        """The current communication point t_k = start + k h [s]."""
        return self._ex.time

    @property
    def steps(self) -> int:
        """Steps done."""
        return self._ex.k_done

    @property
    def finished(self) -> bool:
        return self.result is not None

    @property
    def execution(self) -> Execution:
        """The master's execution this run drives (to add observers and manipulators)."""
        return self._ex

    def step(self, n: int = 1) -> "Run":
        """Do ``n`` communication steps (fewer at the stop time or when the run ends)."""
        return self._advance(lambda ex: ex.step(n))

    def step_to(self, t: float) -> "Run":
        """Step until the communication point at or after ``t`` [s] (at most the stop time)."""
        return self._advance(lambda ex: ex.step_to(t))

    def finish(self, raise_on_failure: bool = True) -> Result:
        """Step to the stop time (unless the run has ended) and return the result."""
        if self.result is None:
            try:
                self._advance(lambda ex: ex.simulate_until())
            except RunError:
                if raise_on_failure:
                    raise
        if self.result is None:
            self._ex.close()
            self._take_result(raise_on_failure)
        assert self.result is not None
        return self.result

    def close(self) -> Result:
        """End the run now (status "stopped" if it had not ended), free the FMUs; returns the result."""
        if self.result is None:
            self._ex.close()
            self._take_result(raise_on_failure=False)
        assert self.result is not None
        return self.result

    def stop(self, reason: str = "") -> None:
        """End the run cleanly at the current time (from a callback or between steps): status "stopped"."""
        if self.result is None:
            self._ex.stop(f"stopped by the script at t = {self.time:.6g} s" + (f": {reason}" if reason else ""))
            if self._ex.ended:   # (from a callback, the run ends after its step)
                self._take_result(raise_on_failure=False)

    def __enter__(self) -> "Run":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ values between steps
    def get(self, ref: str) -> Any:
        """The current value of ``"instance.variable"`` (any variable: an output, an input, a parameter).
        A Float64 output the loop reads at every step gives its value at the last communication point (as
        recorded, and as conditions see it); any other variable is asked of the FMU, so an output with
        direct feedthrough already reflects an input :meth:`set` since that point."""
        return self._ex.get(ref)

    def set(self, ref: str, value: Any) -> None:
        """Change ``"instance.variable"`` from the next step on: a tunable parameter; a Real input (its
        connection is overridden until :meth:`release`); an output feeding connections (what they carry);
        an input no connection drives.  The value is checked against the variable's type and range."""
        self._ex.set(ref, value)

    def release(self, ref: str) -> None:
        """End an override :meth:`set` put on a connected input or an output."""
        self._ex.release(ref)

    def on_step(self, fn: Callable[["Run"], Any]) -> Callable[["Run"], Any]:
        """Call ``fn(run)`` after every step from now on (an observer reads with :meth:`get`, a
        manipulator changes inputs with :meth:`set`; :meth:`stop` ends the run).  Returns ``fn``."""
        self._ex.on_step(lambda: fn(self))
        return fn

    @property
    def events(self) -> list[dict[str, Any]]:
        """The event log so far: time, event, action, ..."""
        return self._ex.events

    # ------------------------------------------------------------------ internals
    def _advance(self, how: Callable[[Execution], Any]) -> "Run":
        """Step the execution; when the run ends (at the stop time, cleanly earlier, or on a failure, which
        is raised as the execution raises it) its result is taken."""
        if self._ex.ended:
            how(self._ex)   # refused: the run has ended
        try:
            how(self._ex)
        finally:
            self._take_result(raise_on_failure=False)
        if self.result is not None and self.result.status == RunStatus.FAILED:
            raise RunError(self.result.message)
        return self

    def _take_result(self, raise_on_failure: bool) -> None:
        """The execution's result as a :class:`Result`; a failed run raises RunError when asked."""
        r = self._ex.result
        if r is None:
            return
        if self.result is None:
            self.result = _result_of(r, self.plan)
        if raise_on_failure and self.result.status == RunStatus.FAILED:
            raise RunError(self.result.message)
