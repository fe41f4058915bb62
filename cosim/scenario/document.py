"""System and scenario files (TOML): which FMUs, their parameters, the connections, the experiment,
what to record and the timed events.  See scenarios/example.toml for a commented example.

Every problem is reported as ScenarioError(file, field, reason) before any FMU is loaded.
"""
from __future__ import annotations

import copy
import json
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..instances.integrators import SOLVERS
from ..messages.errors import OtherFileError, ScenarioError
from ..messages.suggest import did_you_mean, unknown_key
from ..messages.words import count, plural
from ..model.archive import DEFAULT_LIMITS, ArchiveLimits, LimitOverrides, parse_limits
from ..model.description import CO_SIMULATION, MODEL_EXCHANGE, SCHEDULED_EXECUTION
from ..model.kinds import FileKind, file_kind
from ..stepping import table as algorithms
from ..stepping.settings import AdaptiveSpec, IterationSpec, SpecError

ACTIONS = ("override", "bias", "reset", "set", "stop")
TRIGGERS = ("once", "each")
LOGGING = ("error", "warning", "info", "all")
#: The FMI interfaces an instance may use (``[instances.NAME] interface``).
INTERFACES = (CO_SIMULATION, MODEL_EXCHANGE, SCHEDULED_EXECUTION)
#: The instance fields that set a Model Exchange instance's integrator (any of them asks for model exchange).
SOLVER_KEYS = ("solver", "max_step", "event_tolerance")

_TOP_KEYS = {"base", "replace", "description", "experiment", "instances", "connections", "record", "events", "runs",
             "variants", "inputs", "limits", "requirements", "live"}
_INPUTS_KEYS = {"file", "interpolation"}
_EXPERIMENT_KEYS = {"start", "stop", "step", "algorithm", "order", "tolerance", "max_steps", "max_internal_steps",
                    *(t.name for t in algorithms.TABLES), "workers"}
_INSTANCE_KEYS = {"fmu", "parameters", "names", "units", "override_declared_units", "description", "logging", "isolate",
                  "step_timeout", "tolerance", "interface", "step", "clock_ticks", *SOLVER_KEYS}
_CONNECTION_KEYS = {"from", "to", "factor", "offset", "convert", "threshold"}
_RECORD_KEYS = {"variables", "decimation", "csv", "mat", "max_bytes", "event_rows"}
_RUN_KEYS = {"name", "description", "parameters", "carry"}
_VARIANT_KEYS = {"description", "parameters"}
_EVENT_KEYS = {"time", "when", "trigger", "delay", "variable", "action", "value"}
_REQUIREMENT_KEYS = {"name", "formula", "on_violation", "description", "runs"}
_LIVE_KEYS = {"xy"}
#: What a requirement's violation does: recorded in the results, or the run stopped at once.
ON_VIOLATION = ("record", "stop")


@dataclass
class InstanceSpec:
    """One FMU instance.  ``names`` maps the FMU's own variable names to the names the scenario uses
    (their -> ours); ``units`` declares units for variables whose FMU does not (scenario name -> unit; a unit
    that contradicts a declared one is refused unless ``override_declared_units``);
    ``logging`` is the level of the FMU's messages kept in its log ("error", "warning", "info", "all");
    ``interface`` the FMU's interface to use ("co-simulation" or "model-exchange"; None: model exchange when
    a solver setting is given or the FMU has no co-simulation, else co-simulation: see
    :func:`cosim.plan.resolution.resolve`), and ``solver``, ``max_step`` [s], ``event_tolerance`` [s] the integrator
    of a Model Exchange instance (:class:`cosim.instances.integrators.SolverSpec`; None: its default)."""

    name: str
    fmu: str
    fmu_path: Path | None
    parameters: dict[str, Any] = field(default_factory=dict)
    names: dict[str, str] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    logging: str = "warning"
    isolate: bool = False               # host the FMU in a child process (a crash or hang cannot take the run down)
    step_timeout: float | None = None   # seconds a call may take before the instance is ended (isolated: 60)
    override_declared_units: bool = False   # ``units`` may replace a unit the model description declares
    tolerance: float | None = None      # this FMU's own solver tolerance (else [experiment], else its default)
    interface: str | None = None        # "co-simulation" | "model-exchange" | "scheduled-execution"; None: chosen
                                        # by the FMU and the solver keys
    solver: str | None = None           # a Model Exchange instance's integrator (cosim.instances.integrators.SOLVERS)
    max_step: float | None = None       # [s] its largest internal step
    event_tolerance: float | None = None   # [s] the width to which Euler and RK4 locate a state event
    step: float | None = None           # [s] its own communication step, a whole multiple of the experiment's
    clock_ticks: dict[str, list[float]] = field(default_factory=dict)   # scheduled execution: the times [s] the
                                        # master ticks each triggered input clock (``clock_ticks = {c = [0.0, 1.0]}``)


@dataclass
class ConnectionSpec:
    """output -> input; ``convert`` allows Boolean -> Real (0 or 1, then factor and offset) and Real ->
    Boolean (true when the value exceeds ``threshold``)."""

    src: str
    dst: str
    factor: float = 1.0
    offset: float = 0.0
    index: int = 0
    convert: bool = False
    threshold: float = 0.5


@dataclass
class EventSpec:
    """An event: at ``time`` [s], or each time / the first time the condition ``when`` becomes true (then
    ``delay`` [s] later); ``action`` override, bias, reset or set ``variable`` (``value``), or stop the run."""

    time: float | None
    variable: str | None
    action: str
    value: Any = None
    index: int = 0
    when: str | None = None
    condition: Any = None          # the parsed condition (cosim.scenario.condition syntax tree)
    trigger: str = "once"
    delay: float = 0.0


@dataclass
class RequirementSpec:
    """A requirement: its ``name``, its ``formula`` in signal temporal logic (:mod:`cosim.requirements.formula`),
    what a violation does (``on_violation``: "record" it, or "stop" the run), a description, and the runs
    of a protocol it is monitored in."""

    name: str
    formula: str
    on_violation: str = "record"
    description: str = ""
    index: int = 0
    runs: list[str] | None = None   # the protocol's runs it is monitored in (None: every run)
    node: Any = None                # the parsed formula (cosim.requirements.formula syntax tree)


@dataclass
class RunSpec:
    """One run of a protocol: parameter values ("instance.param" -> value) and values carried from an
    earlier run's final outputs ("instance.param" -> "run.instance.variable")."""

    name: str
    parameters: dict[str, Any] = field(default_factory=dict)
    carry: dict[str, str] = field(default_factory=dict)
    description: str = ""


@dataclass
class Scenario:
    """A parsed and syntactically checked scenario; :func:`cosim.plan.resolution.resolve` checks it against the FMUs."""

    file: str
    start: float | None = None      # None: from the FMUs' default experiments (else 0)
    stop: float | None = None       # None: from the FMUs' default experiments
    step: float | None = None       # None: from the FMUs' default experiments
    tolerance: float | None = None  # passed to every FMU's set-up, unless its instance gives its own
    max_steps: int = 50_000_000     # a run of more steps is refused (unless forced)
    max_internal_steps: int = 1_000_000_000   # ... and one in which an FMU takes more fixed internal steps
    max_bytes: int = 4 * 2 ** 30    # a recording expected larger than this is refused (unless forced)
    force: bool = False             # lift max_steps and max_bytes (the command line's --force)
    algorithm: str = algorithms.DEFAULT
    settings: dict[str, Any] = field(default_factory=dict)   # table name -> the settings the algorithm reads
    workers: int = 1                         # instances stepped at once: isolated ones, C FMUs in threads
    order: list[str] = field(default_factory=list)
    instances: dict[str, InstanceSpec] = field(default_factory=dict)
    connections: list[ConnectionSpec] = field(default_factory=list)
    record: list[str] = field(default_factory=list)
    requirements: list[RequirementSpec] = field(default_factory=list)
    decimation: int = 1
    events: list[EventSpec] = field(default_factory=list)
    # the flags of the result formats (the table cosim.results.formats names them, a layer above)
    csv: bool = True
    mat: bool = False               # also signals.mat, Dymola's result layout (cosim.results.matfile)
    event_rows: bool = False        # rows before and after each event of a lone model-exchange instance
    runs: list[RunSpec] = field(default_factory=list)
    variants: dict[str, dict[str, Any]] = field(default_factory=dict)
    inputs_file: Path | None = None                      # a CSV table of input signals
    interpolation: dict[str, str] = field(default_factory=dict)  # column -> "linear" | "hold"
    data: dict[str, Any] = field(default_factory=dict)  # the merged document, as run
    archive_limits: ArchiveLimits = DEFAULT_LIMITS      # how far its FMU and SSP archives may unpack ([limits])
    notes: list[str] = field(default_factory=list)      # what check and run print of it (a table not read)
    tools_choice: set[str] = field(default_factory=set)  # fields given as 0, "the tool's choice" (TOOLS_CHOICE)
    xy: list[str] = field(default_factory=list)   # [live] xy: the two recorded outputs of a position [m] (x, y)

    @property
    def iteration(self) -> IterationSpec | None:
        """[experiment.iteration], where the algorithm reads it: the iterated coupling's settings."""
        return self.settings.get(algorithms.ITERATION_TABLE)

    @property
    def adaptive(self) -> AdaptiveSpec | None:
        """[experiment.adaptive], where the algorithm reads it: the step-size control's settings."""
        return self.settings.get(algorithms.ADAPTIVE_TABLE)

    def times(self) -> tuple[float, float, float]:
        """start, stop and step [s] once all three are known (given, or filled in by the resolution);
        ValueError while one is open."""
        if self.start is None or self.stop is None or self.step is None:
            raise ValueError(f"{self.file}: the experiment's start, stop and step are not all known yet")
        return self.start, self.stop, self.step


#: The arrays of tables a document EXTENDS from its base, each with the key by which one of its entries
#: replaces the base's entry of the same key in place (None: its entries are appended): a connection by the
#: input it drives (``to``: an input is driven once), a requirement and a run by their ``name``.  The
#: document's top-level ``replace = [...]`` names those it gives whole instead.  Every other array is a
#: field's value (``record.variables``, ``experiment.order``) and replaces the base's; tables merge key by key.
EXTENDED: dict[str, str | None] = {"connections": "to", "requirements": "name", "runs": "name", "events": None}
#: The noun of one entry of each extended list (what ``check`` counts).
_ENTRY = {"connections": "connection", "requirements": "requirement", "runs": "run", "events": "event"}


@dataclass
class Inheritance:
    """What one file takes from its base: per extended list (:data:`EXTENDED`), the base's entries kept,
    the keys of those the file replaces in place, the entries it adds, the base's entries it drops by
    ``replace``; and the fields whose arrays replace the base's (``record.variables``).  ``check`` prints
    :meth:`describe`."""

    file: str                 # the file that names the base
    base: str                 # the base as that file names it
    kept: dict[str, int] = field(default_factory=dict)
    replaced: dict[str, list[str]] = field(default_factory=dict)
    added: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    values: list[str] = field(default_factory=list)

    def describe(self, top: bool = True) -> str:
        """One line: "base g1_learn.toml: 11 connections inherited; this file adds 1 connection, replaces
        the connection to plant.u1, replaces record.variables" (``top``: the file is the one checked, else
        it is named)."""
        def listed(counts: dict[str, int]) -> str:
            return ", ".join(count(n, _ENTRY[k]) for k, n in counts.items() if n and k not in self.dropped)

        kept = listed(self.kept)
        what = [f"adds {listed(self.added)}"] if listed(self.added) else []
        for key, keys in self.replaced.items():
            if keys:
                by = "to" if EXTENDED[key] == "to" else "named"
                what.append(f"replaces the {plural(len(keys), _ENTRY[key])} {by} {', '.join(keys)}")
        for key, n in self.dropped.items():
            given = self.added.get(key, 0)
            what.append(f"{'gives ' + count(given, _ENTRY[key]) + ' in place of' if given else 'drops'} the base's "
                        f"{count(n, _ENTRY[key])} (replace)")
        what += [f"replaces {fld}" for fld in self.values]
        who = "this file" if top else self.file
        head = f"base {self.base}" + ("" if top else f" (of {self.file})")
        return (f"{head}: {kept + ' inherited' if kept else 'no entries inherited'}"
                + (f"; {who} {', '.join(what)}" if what else ""))


def replaced_lists(file: str, value: Any) -> list[str]:
    """A document's ``replace``: the extended lists (:data:`EXTENDED`) it gives whole; ScenarioError for
    anything else (not an array of those names; with the nearest name)."""
    if value is None:
        return []
    allowed = ", ".join(EXTENDED)
    if isinstance(value, str):
        raise ScenarioError(file, "replace", f"{value!r}: must be an array of the lists this file gives whole "
                                             f"(replace = [{json.dumps(value)}]; allowed: {allowed})")
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ScenarioError(file, "replace", f"{value!r}: must be an array of the lists this file gives whole "
                                             f"(allowed: {allowed})")
    for v in value:
        if v not in EXTENDED:
            table = v in _TOP_KEYS or v.split(".")[0] in _TOP_KEYS
            what = (" is not a list of tables (tables merge key by key, and arrays of values replace the base's "
                    "by themselves)" if table else " is not a list a base gives")
            raise ScenarioError(file, "replace", f"{v!r}{what}: allowed: {allowed}{did_you_mean(v, EXTENDED)}")
    return list(dict.fromkeys(value))


def merge(base: dict[str, Any], over: dict[str, Any], report: Inheritance,
          whole: tuple[str, ...] | list[str] = ()) -> dict[str, Any]:
    """``over`` (a document, its ``base`` and ``replace`` taken out) merged over ``base``: tables key by key,
    the lists of :data:`EXTENDED` extended (keyed entries replaced in place; those in ``whole`` given
    whole), every other value replaced; what the document takes from its base goes into ``report``."""
    out = _merge_tables(base, over, "", report)
    for key in EXTENDED:
        old = base.get(key)
        if key in whole and isinstance(old, list) and old:
            report.dropped[key] = len(old)
            out[key] = copy.deepcopy(over.get(key, []))
            report.added[key] = len(out[key]) if isinstance(out[key], list) else 0
        elif key in whole and key not in over:
            out.pop(key, None)   # (the base has none to drop)
        elif key in over:
            out[key] = _extend(report, key, base.get(key), over[key])
        elif isinstance(base.get(key), list):
            report.kept[key] = len(base[key])
    return out


def _merge_tables(base: dict[str, Any], over: dict[str, Any], where: str, report: Inheritance) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if not where and k in EXTENDED:
            continue   # (extended by :func:`merge`)
        fld = f"{where}.{k}" if where else str(k)
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge_tables(out[k], v, fld, report)
        else:
            if isinstance(v, list) and isinstance(out.get(k), list) and out[k] != v:
                report.values.append(fld)
            out[k] = copy.deepcopy(v)
    return out


def _extend(report: Inheritance, key: str, old: Any, new: Any) -> Any:
    """The base's list ``old`` extended by the document's ``new``: an entry with the key of a base's entry
    replaces it in place (once; a second such entry is appended, for the checks to refuse), the others
    appended.  Where either is not a list, ``new`` as given (the checks judge it)."""
    old = [] if old is None else old
    if not isinstance(old, list) or not isinstance(new, list):
        return copy.deepcopy(new)
    if not new and old:
        raise ScenarioError(report.file, key, f"an empty array adds nothing to the base's "
                                              f"{count(len(old), _ENTRY[key])} (a base's lists are extended): to "
                                              f"drop them, write replace = [{json.dumps(key)}]")
    name = EXTENDED[key]
    out = copy.deepcopy(old)
    at: dict[str, int] = {}
    if name is not None:
        for i, entry in enumerate(old):
            k = entry.get(name) if isinstance(entry, dict) else None
            if isinstance(k, str):
                at.setdefault(k, i)
    replaced: list[str] = []
    for entry in new:
        k = entry.get(name) if name is not None and isinstance(entry, dict) else None
        if isinstance(k, str) and k in at and k not in replaced:
            out[at[k]] = copy.deepcopy(entry)
            replaced.append(k)
        else:
            out.append(copy.deepcopy(entry))
    report.kept[key] = len(old) - len(replaced)
    report.replaced[key] = replaced
    report.added[key] = len(new) - len(replaced)
    return out


#: Top-level keys of other files a scenario may be mistaken for, and what each makes the file
#: (:class:`~.errors.OtherFileError`: the application can add how to run it).
OTHER_FILES = {"tasks": "a paper manifest", "grid": "a sweep file", "random": "a sweep file",
               "samples": "a sweep file"}
#: The longest instance or run name (it names files and folders: logs/<instance>.log, <out>/<run>/).
MAX_NAME = 100


def _not_too_long(file: str, fld: str, name: str, what: str, names: str) -> None:
    """ScenarioError for a name of more than MAX_NAME characters (``what``: "an instance name"; ``names``:
    the file or folder it names), before anything is written under it."""
    if len(name) > MAX_NAME:
        raise ScenarioError(file, fld if len(fld) <= 60 else fld[:60] + "...",
                            f"{what} of {len(name)} characters: at most {MAX_NAME} (it names {names})")


def _check_file(path: Path, asked_by: tuple[str, str] | None, shipped: Path | None) -> None:
    """ScenarioError where ``path`` is not a file to read (named as the ``base`` of ``asked_by``: (file, the
    base it names), where given)."""
    name = str(path)
    try:
        is_file = path.is_file()
    except OSError as exc:   # a name the system cannot look up (too long, ...)
        if asked_by is not None:
            raise ScenarioError(asked_by[0], "base", f"{asked_by[1][:60]!r}...: cannot be read "
                                                     f"({exc.strerror or exc})") from None
        raise ScenarioError(name[:100] + "...", "", f"cannot be read ({exc.strerror or exc})") from None
    if not is_file:
        if asked_by is not None:
            raise ScenarioError(asked_by[0], "base", f"{asked_by[1]!r}: "
                                                     f"{'a folder' if path.is_dir() else 'file not found'} ({path}; "
                                                     f"nor a shipped scenario{_shipped_hint(asked_by[1], shipped)})")
        raise ScenarioError(name, "", "a folder, not a scenario file" if path.is_dir() else "file not found")


def read_toml(path: Path) -> dict[str, Any]:
    """The TOML document of the file ``path`` (a scenario, a sweep, falsification or tasks file); ScenarioError
    naming the file where it is no file, cannot be read, is not UTF-8 text or not TOML (nested too deeply
    included)."""
    name = str(path)
    _check_file(path, None, None)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(name, "", f"not valid TOML ({' '.join(str(exc).split())})") from None
    except UnicodeDecodeError:
        raise ScenarioError(name, "", "not a text file (TOML is UTF-8 text)") from None
    except RecursionError:
        raise ScenarioError(name, "", "not valid TOML (nested too deeply)") from None
    except OSError as exc:
        raise ScenarioError(name, "", f"cannot be read ({exc.strerror or exc})") from None


def read_document(path: Path, seen: tuple[Path, ...] = (), asked_by: tuple[str, str] | None = None,
                  shipped: Path | None = None, inherited: list[Inheritance] | None = None) -> dict[str, Any]:
    """Read one scenario file, absolutise its FMU and input paths, and merge it over its ``base`` (the
    document :func:`parse` checks; see :func:`merge`).  ``shipped``: the application's folder of scenario
    files, where a ``base`` found neither beside the file nor by an absolute path is looked up (see
    :func:`base_path`).  ``inherited``: where given, gets what each file of the chain takes from its base
    (:class:`Inheritance`), the file's own first."""
    name = str(path)
    _check_file(path, asked_by, shipped)
    if path.resolve() in seen:
        raise ScenarioError(name, "base", "circular base chain")
    doc = read_toml(path)
    unknown = set(doc) - _TOP_KEYS
    for key in sorted(unknown):
        if key in OTHER_FILES:
            raise OtherFileError(name, OTHER_FILES[key])
    if unknown:
        first = sorted(unknown)[0]
        raise ScenarioError(name, first, unknown_key(first, _TOP_KEYS))
    instances = doc.get("instances")
    for inst in instances.values() if isinstance(instances, dict) else ():   # not a table: parse says so
        if isinstance(inst, dict) and isinstance(inst.get("fmu"), str) and is_path(inst["fmu"]):
            inst["fmu"] = str((path.parent / inst["fmu"]).resolve())
    inputs = doc.get("inputs")
    if isinstance(inputs, dict) and isinstance(inputs.get("file"), str):
        inputs["file"] = str((path.parent / inputs["file"]).resolve())
    whole = replaced_lists(name, doc.pop("replace", None))
    if "base" not in doc and whole:
        raise ScenarioError(name, "replace", "this file has no base: replace names the lists of its base it gives "
                                             "whole")
    if "base" in doc:
        b = doc.pop("base")
        if not isinstance(b, str):
            raise ScenarioError(name, "base", "must be a file name")
        report = Inheritance(name, b)
        doc = merge(read_document(base_path(path, b, shipped), seen + (path.resolve(),), (name, b), shipped,
                                  inherited), doc, report, whole)
        if inherited is not None:
            inherited.insert(0, report)
    return doc




def _shipped_hint(base: str, folder: Path | None) -> str:
    """", did you mean 'paper/protocol.toml'?" where a shipped file of that name lies in a subfolder."""
    if folder is None or not folder.is_dir():
        return ""
    hits = sorted(p.relative_to(folder).as_posix() for p in folder.rglob(Path(base).name))
    return f", did you mean {hits[0]!r}?" if hits else ""


def base_path(path: Path, base: str, shipped: Path | None = None) -> Path:
    """The file a ``base`` names: relative to the file that names it, else (a relative name without ``..``)
    one of the scenario files in the folder ``shipped`` (``g1_learn.toml``, ``paper/protocol.toml``; a name
    may start with that folder's own name), so that a copy of a shipped file still finds its base."""
    beside = path.parent / base
    b = Path(base)
    try:
        exists = beside.exists()
    except OSError:   # a name the system cannot look up (too long): read_document says so
        return beside
    if exists or b.is_absolute() or ".." in b.parts or shipped is None:
        return beside
    parts = b.parts[1:] if b.parts[:1] == (shipped.name,) else b.parts
    found = shipped.joinpath(*parts) if shipped is not None and parts else None
    return found if found is not None and found.is_file() else beside


def is_path(fmu: str) -> bool:
    """Whether an instance's ``fmu`` names a file (an ``.fmu``, in any case, or a path) rather than a model."""
    return file_kind(fmu) is FileKind.FMU or "/" in fmu or os.sep in fmu




def _flag(file: str, fld: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise ScenarioError(file, fld, f"{v!r}: must be true or false")
    return v


def _num(file: str, fld: str, v: Any, *, positive: bool = False, allow_none: bool = False) -> float:
    if v is None and allow_none:
        return math.nan
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ScenarioError(file, fld, f"must be a number, not {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise ScenarioError(file, fld, f"must be finite, not {v!r}")
    if positive and v <= 0:
        raise ScenarioError(file, fld, f"must be > 0, not {v!r}")
    return v


def _count(file: str, fld: str, v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise ScenarioError(file, fld, f"{v!r}: must be an integer >= 1")
    return v


def _table(file: str, fld: str, v: Any) -> dict[str, Any]:
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise ScenarioError(file, fld, "must be a table")
    return v


def _tables(file: str, doc: dict[str, Any], key: str, allowed: set[str]) -> list[tuple[str, dict[str, Any]]]:
    """The array of tables ``[[key]]`` (none: empty), each as (its field, ``key[i]``; the table), each
    checked to be a table of allowed keys."""
    items = doc.get(key) or []
    if not isinstance(items, list):
        raise ScenarioError(file, key, f"must be an array of tables ([[{key}]])")
    out = []
    for i, item in enumerate(items):
        fld = f"{key}[{i}]"
        table = _table(file, fld, item)
        _keys(file, fld, table, allowed)
        out.append((fld, table))
    return out


def _keys(file: str, fld: str, d: dict[str, Any], allowed: set[str]) -> None:
    for k in d:
        if k not in allowed:
            raise ScenarioError(file, f"{fld}.{k}" if fld else k, unknown_key(k, allowed))


def split_ref(file: str, fld: str, ref: Any) -> tuple[str, str]:
    """'instance.variable' -> (instance, variable); the variable name may itself contain dots."""
    if not isinstance(ref, str) or "." not in ref:
        raise ScenarioError(file, fld, f"{ref!r} is not of the form \"instance.variable\"")
    inst, var = ref.split(".", 1)
    if not inst or not var:
        raise ScenarioError(file, fld, f"{ref!r} is not of the form \"instance.variable\"")
    return inst, var


def _instance_refs(file: str, fld: str, table: Any, sc: Scenario) -> dict[str, Any]:
    """A table keyed by "instance.variable" whose instances all exist."""
    table = _table(file, fld, table)
    for ref in table:
        inst, _ = split_ref(file, f"{fld}.{ref}", ref)
        if inst not in sc.instances:
            raise ScenarioError(file, f"{fld}.{ref}", f"unknown instance {inst!r}")
    return table


def parse(doc: dict[str, Any], file: str, resolver=None, limits: LimitOverrides | None = None) -> Scenario:
    """Check the structure of a merged scenario document and build a :class:`Scenario`.  TOML files, SSP
    archives and documents built in code all come through here, so every check exists once.

    ``resolver(model_name) -> Path | None`` turns an FMU given by model name (e.g. ``WmrPlant``) into a
    file; without one, every ``fmu`` must be a path.  A resolver's attribute ``model_names`` (where it has
    one) lists the names it knows, for the suggestion when a name is not one of them.  ``limits``: the
    caller's archive limits, each given one over the document's ``[limits]`` (the scenario's
    ``archive_limits``).
    """
    sc = Scenario(file=file, data=doc, archive_limits=parse_limits(file, doc.get("limits"), limits))
    _parse_experiment(sc, doc)
    _parse_instances(sc, doc, resolver)
    _parse_connections(sc, doc)
    _parse_record(sc, doc)
    _parse_runs(sc, doc)
    _parse_inputs(sc, doc)
    _parse_events(sc, doc)
    _parse_requirements(sc, doc)
    _parse_live(sc, doc)
    return sc


def _parse_experiment(sc: Scenario, doc: dict[str, Any]) -> None:
    """[experiment]: times, tolerance and algorithm (the order is checked with the instances)."""
    file = sc.file
    exp = _table(file, "experiment", doc.get("experiment"))
    _keys(file, "experiment", exp, _EXPERIMENT_KEYS)
    for key in ("start", "stop", "step", "tolerance"):
        if key in exp:
            if key in TOOLS_CHOICE and not isinstance(exp[key], bool) and exp[key] == 0:
                sc.tools_choice.add(key)   # left to this master: filled in when the FMUs are known
                continue
            setattr(sc, key, _num(file, f"experiment.{key}", exp[key], positive=key in ("step", "tolerance")))
    if "max_steps" in exp:
        sc.max_steps = _count(file, "experiment.max_steps", exp["max_steps"])
    if "max_internal_steps" in exp:
        sc.max_internal_steps = _count(file, "experiment.max_internal_steps", exp["max_internal_steps"])
    if "workers" in exp:
        sc.workers = _count(file, "experiment.workers", exp["workers"])
    if sc.start is not None and sc.stop is not None and sc.step is not None:
        check_experiment(sc)
    sc.algorithm = str(exp.get("algorithm", algorithms.DEFAULT)).lower()
    if sc.algorithm not in algorithms.NAMES:
        raise ScenarioError(file, "experiment.algorithm",
                            f"{sc.algorithm!r}: must be one of {', '.join(algorithms.NAMES)}")
    _parse_stepping(sc, exp)


def _parse_stepping(sc: Scenario, exp: dict[str, Any]) -> None:
    """The tables of settings of the algorithms (the table's rows': [experiment.iteration],
    [experiment.adaptive]), each checked as given and kept where the algorithm reads it (``sc.settings``).
    A table the algorithm does not read (the algorithm switched to "gauss-seidel" with ``--set``, say) is
    checked too but left unused, and a note says so (``check`` and ``run`` print it)."""
    file = sc.file

    def step_taken() -> str | None:
        """The step the step-size control takes, as its table names it (``coupling``; None: none named)."""
        for r in algorithms.ROWS:
            if r.varies_step and r.table is not None:
                own = _table(file, f"experiment.{r.table.name}", exp.get(r.table.name))
                named = str(own.get("coupling", "")).lower()
                if named:
                    return named
        return None

    try:
        for t in algorithms.TABLES:
            if t.name not in exp:
                continue
            table = _table(file, f"experiment.{t.name}", exp[t.name])
            read = algorithms.reads(sc.algorithm, t.name, step_taken())
            spec = t.read(table, sc.step)
            if read:
                sc.settings[t.name] = spec
            else:
                sc.notes.append(f"[experiment.{t.name}] is not read under algorithm = {sc.algorithm!r} (it is read "
                                f"by {algorithms.readers(t.name)})")
    except SpecError as exc:
        raise ScenarioError(file, exc.key, exc.reason) from None


def _parse_instances(sc: Scenario, doc: dict[str, Any], resolver=None) -> None:
    """[instances.NAME]: the FMU (a path or a model name), parameters, name map, units, logging; then the order."""
    file = sc.file
    insts = _table(file, "instances", doc.get("instances"))
    if not insts:
        raise ScenarioError(file, "instances", "no FMU instances")
    for iname, inst in insts.items():
        fld = f"instances.{iname}"
        if not isinstance(iname, str) or not iname.isidentifier():
            raise ScenarioError(file, fld, f"instance name {iname!r} must be an identifier")
        _not_too_long(file, fld, iname, "an instance name", "the instance's log file")
        inst = _table(file, fld, inst)
        _keys(file, fld, inst, _INSTANCE_KEYS)
        fmu = inst.get("fmu")
        if not isinstance(fmu, str) or not fmu:
            raise ScenarioError(file, f"{fld}.fmu", "missing: a model name or a path to an .fmu file")
        if is_path(fmu):
            path: Path | None = Path(fmu)
            if not Path(fmu).is_file():
                raise ScenarioError(file, f"{fld}.fmu", f"FMU file not found: {fmu}")
        else:
            path = resolver(fmu) if resolver is not None else None
            if path is None:
                raise ScenarioError(file, f"{fld}.fmu", f"unknown model name {fmu!r} and not a path to an .fmu file"
                                                        f"{did_you_mean(fmu, getattr(resolver, 'model_names', ()))}")
        params = _table(file, f"{fld}.parameters", inst.get("parameters"))
        names = _table(file, f"{fld}.names", inst.get("names"))
        for their, ours in names.items():
            if not isinstance(ours, str):
                raise ScenarioError(file, f"{fld}.names.{their}", "must map to a variable name (a string)")
        if len(set(names.values())) != len(names):
            raise ScenarioError(file, f"{fld}.names", "two of the FMU's variables map to the same name")
        units = _table(file, f"{fld}.units", inst.get("units"))
        for var, u in units.items():
            if not isinstance(u, str):
                raise ScenarioError(file, f"{fld}.units.{var}", "must be a unit name (a string)")
        logging = inst.get("logging", "warning")
        if logging not in LOGGING:
            raise ScenarioError(file, f"{fld}.logging", f"{logging!r}: must be one of {', '.join(LOGGING)}")
        flag = {key: _flag(file, f"{fld}.{key}", inst.get(key, False)) for key in ("isolate", "override_declared_units")}
        timeout, tol, own_step = (_num(file, f"{fld}.{key}", inst[key], positive=True) if inst.get(key) is not None
                                  else None for key in ("step_timeout", "tolerance", "step"))
        sc.instances[iname] = InstanceSpec(iname, fmu, path, dict(params), dict(names), dict(units), logging,
                                           flag["isolate"], timeout, flag["override_declared_units"], tol,
                                           **_interface_fields(file, fld, inst), step=own_step,
                                           clock_ticks=_clock_ticks(file, f"{fld}.clock_ticks", inst.get("clock_ticks")))


    exp = doc.get("experiment") or {}
    order = exp.get("order", list(sc.instances))
    if not isinstance(order, list) or not all(isinstance(o, str) for o in order) \
            or sorted(order) != sorted(sc.instances):
        raise ScenarioError(file, "experiment.order",
                            f"{order!r} must list every instance exactly once ({', '.join(sc.instances)})")
    sc.order = list(order)


def _clock_ticks(file: str, fld: str, v: Any) -> dict[str, list[float]]:
    """``clock_ticks``: a table of clock name -> a list of times [s], each finite, in increasing order."""
    out: dict[str, list[float]] = {}
    for clock, times in _table(file, fld, v).items():
        if not isinstance(times, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                  and math.isfinite(x) for x in times):
            raise ScenarioError(file, f"{fld}.{clock}", "must be a list of times [s] (finite numbers)")
        if any(b <= a for a, b in zip(times, times[1:])):
            raise ScenarioError(file, f"{fld}.{clock}", "the times must increase")
        out[clock] = [float(x) for x in times]
    return out


def _interface_fields(file: str, fld: str, inst: dict[str, Any]) -> dict[str, Any]:
    """An instance's ``interface`` and its integrator's settings (``solver``, ``max_step`` [s] and
    ``event_tolerance`` [s], each > 0 and finite), checked as given; settings of an integrator with
    ``interface = "co-simulation"`` are refused (a co-simulation FMU brings its own)."""
    interface = _choice(file, f"{fld}.interface", inst.get("interface"), INTERFACES)
    solver = _choice(file, f"{fld}.solver", inst.get("solver"), SOLVERS)
    max_step, event_tol = (_num(file, f"{fld}.{key}", inst[key], positive=True) if inst.get(key) is not None
                           else None for key in ("max_step", "event_tolerance"))
    given = [key for key in SOLVER_KEYS if inst.get(key) is not None]
    if given and interface == CO_SIMULATION:
        raise ScenarioError(file, f"{fld}.{given[0]}", "an integrator setting is for a model exchange instance, "
                                                       "and this one says interface = \"co-simulation\" (a "
                                                       "co-simulation FMU integrates itself)")
    return {"interface": interface, "solver": solver, "max_step": max_step, "event_tolerance": event_tol}


def _choice(file: str, fld: str, v: Any, allowed: tuple[str, ...]) -> str | None:
    """``v`` if it is one of ``allowed`` (None if not given), else ScenarioError with the closest name."""
    if v is None:
        return None
    if not isinstance(v, str) or v not in allowed:
        hint = did_you_mean(v, allowed) if isinstance(v, str) else ""
        raise ScenarioError(file, fld, f"{v!r}: must be one of {', '.join(allowed)}{hint}")
    return v


def _parse_connections(sc: Scenario, doc: dict[str, Any]) -> None:
    """[[connections]]: output -> input with factor, offset, conversion."""
    file = sc.file
    for i, (fld, c) in enumerate(_tables(file, doc, "connections", _CONNECTION_KEYS)):
        for end in ("from", "to"):
            if end not in c:
                raise ScenarioError(file, f"{fld}.{end}", "missing")
            inst, _ = split_ref(file, f"{fld}.{end}", c[end])
            if inst not in sc.instances:
                raise ScenarioError(file, f"{fld}.{end}", f"unknown instance {inst!r}")
        convert = c.get("convert", False)
        if not isinstance(convert, bool):
            raise ScenarioError(file, f"{fld}.convert", f"{convert!r}: must be true or false")
        sc.connections.append(ConnectionSpec(c["from"], c["to"], _num(file, f"{fld}.factor", c.get("factor", 1.0)),
                                             _num(file, f"{fld}.offset", c.get("offset", 0.0)), i, convert,
                                             _num(file, f"{fld}.threshold", c.get("threshold", 0.5))))


def _parse_record(sc: Scenario, doc: dict[str, Any]) -> None:
    """[record]: the variables (names or patterns), decimation, CSV, MAT."""
    file = sc.file
    rec = _table(file, "record", doc.get("record"))
    _keys(file, "record", rec, _RECORD_KEYS)
    variables = rec.get("variables", [])
    if not isinstance(variables, list) or not all(isinstance(v, str) for v in variables):
        raise ScenarioError(file, "record.variables", "must be an array of \"instance.variable\" patterns")
    sc.record = list(variables)
    dec = rec.get("decimation", 1)
    if isinstance(dec, bool) or not isinstance(dec, int) or dec < 1:
        raise ScenarioError(file, "record.decimation", f"{dec!r}: must be an integer >= 1")
    sc.decimation = dec
    sc.csv = _flag(file, "record.csv", rec.get("csv", True))
    sc.mat = _flag(file, "record.mat", rec.get("mat", False))
    sc.event_rows = _flag(file, "record.event_rows", rec.get("event_rows", False))
    if "max_bytes" in rec:
        sc.max_bytes = _count(file, "record.max_bytes", rec["max_bytes"])


def _parse_live(sc: Scenario, doc: dict[str, Any]) -> None:
    """[live]: what the live view draws beyond the time plots; ``xy``, the two outputs of a position
    ("instance.variable", x then y) drawn as a path (the resolution checks that both are recorded)."""
    file = sc.file
    live = _table(file, "live", doc.get("live"))
    _keys(file, "live", live, _LIVE_KEYS)
    if "xy" in live:
        xy = live["xy"]
        if not isinstance(xy, list) or len(xy) != 2 or not all(isinstance(v, str) for v in xy):
            raise ScenarioError(file, "live.xy", f"{xy!r}: must be two names, [\"instance.x\", \"instance.y\"]")
        for i, ref in enumerate(xy):
            inst, _ = split_ref(file, f"live.xy[{i}]", ref)
            if inst not in sc.instances:
                raise ScenarioError(file, f"live.xy[{i}]", f"unknown instance {inst!r}")
        if xy[0] == xy[1]:
            raise ScenarioError(file, "live.xy", f"{xy!r}: must be two different names")
        sc.xy = list(xy)


def _parse_runs(sc: Scenario, doc: dict[str, Any]) -> None:
    """[[runs]] and [variants.NAME] of a protocol."""
    file = sc.file
    names: list[str] = []
    for fld, r in _tables(file, doc, "runs", _RUN_KEYS):
        name = r.get("name")
        if not isinstance(name, str) or not name.isidentifier():
            raise ScenarioError(file, f"{fld}.name", f"{name!r}: a run needs a name that is an identifier")
        _not_too_long(file, f"{fld}.name", name, "a run name", "the run's results folder")
        if name in names:
            raise ScenarioError(file, f"{fld}.name", f"{name!r}: two runs with this name")
        params = _instance_refs(file, f"{fld}.parameters", r.get("parameters"), sc)
        carry = _table(file, f"{fld}.carry", r.get("carry"))
        for ref, src in carry.items():
            inst, _ = split_ref(file, f"{fld}.carry.{ref}", ref)
            if inst not in sc.instances:
                raise ScenarioError(file, f"{fld}.carry.{ref}", f"unknown instance {inst!r}")
            if not isinstance(src, str) or src.count(".") < 2:
                raise ScenarioError(file, f"{fld}.carry.{ref}", f"{src!r}: must be \"run.instance.variable\"")
            run = src.split(".", 1)[0]
            if run not in names:
                raise ScenarioError(file, f"{fld}.carry.{ref}", f"{src!r}: no earlier run named {run!r}")
        sc.runs.append(RunSpec(name, dict(params), dict(carry), str(r.get("description", ""))))
        names.append(name)
    variants = _table(file, "variants", doc.get("variants"))
    for vname, v in variants.items():
        fld = f"variants.{vname}"
        v = _table(file, fld, v)
        _keys(file, fld, v, _VARIANT_KEYS)
        params = _instance_refs(file, f"{fld}.parameters", v.get("parameters"), sc)
        sc.variants[vname] = dict(params)


def _parse_inputs(sc: Scenario, doc: dict[str, Any]) -> None:
    """[inputs]: a CSV table of input signals and the interpolation of its columns."""
    file = sc.file
    inputs = _table(file, "inputs", doc.get("inputs"))
    _keys(file, "inputs", inputs, _INPUTS_KEYS)
    if inputs:
        f = inputs.get("file")
        if not isinstance(f, str) or not Path(f).is_file():
            raise ScenarioError(file, "inputs.file", f"{f!r}: not a file (a CSV table of input signals)")
        sc.inputs_file = Path(f)
        interp = _table(file, "inputs.interpolation", inputs.get("interpolation"))
        for ref, mode in interp.items():
            if mode not in ("linear", "hold"):
                raise ScenarioError(file, f"inputs.interpolation.{ref}", f"{mode!r}: must be linear or hold")
        sc.interpolation = dict(interp)


def _parse_events(sc: Scenario, doc: dict[str, Any]) -> None:
    """[[events]]: at a ``time`` or ``when`` a condition becomes true: override, bias, reset or set a
    variable, or stop the run."""
    from .condition import ConditionError, parse as parse_condition, variables as condition_variables

    file = sc.file
    for i, (fld, e) in enumerate(_tables(file, doc, "events", _EVENT_KEYS)):
        if ("time" in e) == ("when" in e):
            raise ScenarioError(file, fld, "needs either a time or a when condition" if "time" not in e
                                else "has both a time and a when condition: give one")
        t, cond, when = None, None, None
        trigger, delay = "once", 0.0
        if "time" in e:
            t = _num(file, f"{fld}.time", e.get("time"))
            for key in ("trigger", "delay"):
                if key in e:
                    raise ScenarioError(file, f"{fld}.{key}", "only an event with a when condition takes one")
        else:
            when = e["when"]
            try:
                cond = parse_condition(when)
            except ConditionError as exc:
                raise ScenarioError(file, f"{fld}.when", str(exc)) from None
            for ref in condition_variables(cond):
                inst = ref.split(".", 1)[0]
                if inst not in sc.instances:
                    raise ScenarioError(file, f"{fld}.when", f"{ref}: unknown instance {inst!r}")
            trigger = e.get("trigger", "once")
            if trigger not in TRIGGERS:
                raise ScenarioError(file, f"{fld}.trigger", f"{trigger!r}: must be one of {', '.join(TRIGGERS)}")
            delay = _num(file, f"{fld}.delay", e.get("delay", 0.0))
            if delay < 0:
                raise ScenarioError(file, f"{fld}.delay", f"{delay!r}: must be >= 0 [s]")
        action = e.get("action", "override")
        if action not in ACTIONS:
            raise ScenarioError(file, f"{fld}.action", f"{action!r}: must be one of {', '.join(ACTIONS)}")
        if action == "stop":
            for key in ("variable", "value"):
                if key in e:
                    raise ScenarioError(file, f"{fld}.{key}", "a stop takes no variable or value")
            sc.events.append(EventSpec(t, None, action, None, i, when, cond, trigger, delay))
            continue
        if "variable" not in e:
            raise ScenarioError(file, f"{fld}.variable", "missing")
        inst, _ = split_ref(file, f"{fld}.variable", e["variable"])
        if inst not in sc.instances:
            raise ScenarioError(file, f"{fld}.variable", f"unknown instance {inst!r}")
        if action != "reset" and "value" not in e:
            raise ScenarioError(file, f"{fld}.value", f"missing (needed by {action})")
        if action == "reset" and "value" in e:
            raise ScenarioError(file, f"{fld}.value", "a reset takes no value")
        sc.events.append(EventSpec(t, e["variable"], action, e.get("value"), i, when, cond, trigger, delay))


#: Names a requirement cannot take, with why: requirements.npy's columns are the requirements' names beside
#: the time's.
RESERVED_REQUIREMENT_NAMES = {"time": "requirements.npy's column of the time"}


def _parse_requirements(sc: Scenario, doc: dict[str, Any]) -> None:
    """[[requirements]]: a name, a formula (parsed here: its syntax; its variables, types, units and bounds
    are checked with the FMUs), what a violation does, a description, the runs it is monitored in."""
    from ..requirements.formula import FormulaError, parse as parse_formula, variables as formula_variables

    file = sc.file
    seen: set[str] = set()
    for i, (fld, r) in enumerate(_tables(file, doc, "requirements", _REQUIREMENT_KEYS)):
        name = r.get("name")
        if name is not None and not isinstance(name, str):
            raise ScenarioError(file, f"{fld}.name", f"must be a string, not {name!r}")
        if not isinstance(name, str) or not name.strip():
            raise ScenarioError(file, f"{fld}.name", "missing: every requirement has a name")
        if not name.isprintable():
            raise ScenarioError(file, f"{fld}.name", f"{name!r}: a name of printable characters (no control "
                                                     "characters, tabs or line breaks)")
        if name in RESERVED_REQUIREMENT_NAMES:
            raise ScenarioError(file, f"{fld}.name", f"{name!r} is reserved: "
                                                     f"{RESERVED_REQUIREMENT_NAMES[name]}; another name")
        if name in seen:
            raise ScenarioError(file, f"{fld}.name", f"{name!r} names two requirements")
        seen.add(name)
        formula = r.get("formula")
        if not isinstance(formula, str):
            raise ScenarioError(file, f"{fld}.formula", f"requirement {name!r}: missing (a formula in signal "
                                                        "temporal logic, e.g. \"always abs(plant.u1) < 8 N.m\")")
        try:
            node = parse_formula(formula)
        except FormulaError as exc:
            raise ScenarioError(file, f"{fld}.formula", f"requirement {name!r}: {exc}") from None
        for ref, pos in formula_variables(node).items():
            inst = ref.split(".", 1)[0]
            if inst not in sc.instances:
                raise ScenarioError(file, f"{fld}.formula", f"requirement {name!r}: at character {pos}: {ref}: "
                                                            f"unknown instance {inst!r}")
        action = r.get("on_violation", "record")
        if action not in ON_VIOLATION:
            raise ScenarioError(file, f"{fld}.on_violation", f"{action!r}: must be one of {', '.join(ON_VIOLATION)}")
        description = r.get("description", "")
        if not isinstance(description, str):
            raise ScenarioError(file, f"{fld}.description", "must be a string")
        runs = r.get("runs")
        if runs is not None:
            names = [run.name for run in sc.runs] or ["run"]
            if not isinstance(runs, list) or not runs or not all(isinstance(x, str) for x in runs):
                raise ScenarioError(file, f"{fld}.runs", "must be a list of the protocol's run names")
            for x in runs:
                if x not in names:
                    raise ScenarioError(file, f"{fld}.runs", f"{x!r} is not a run of this file ({', '.join(names)})")
        sc.requirements.append(RequirementSpec(name, formula, action, description, i, runs, node))


def check_experiment(sc: Scenario, where: str = "experiment") -> None:
    """The run's times: stop after start, a finite number of steps (a step that does not divide the run
    ends it with a short last step: see :func:`steps_of`; whether every instance can take one is checked
    with the FMUs)."""
    file = sc.file
    start, stop, step = sc.times()
    if stop <= start:
        raise ScenarioError(file, f"{where}.stop", f"{stop!r} is not after the start {start!r}")
    if not math.isfinite((stop - start) / step):
        raise ScenarioError(file, f"{where}.step", f"{step!r} s: not a finite number of steps from {start!r} to "
                                                   f"{stop!r} s")


def steps_of(start: float, stop: float, step: float) -> tuple[int, float | None]:
    """The number of communication steps from ``start`` to ``stop`` [s] and the length [s] of a short last
    step (None when ``step`` divides the run into whole steps, to within 1e-6 of a step): the steps from
    start + k step, k = 0 .. n - 2, then the last one to ``stop``, as FMPy ends a run."""
    n = (stop - start) / step
    whole = round(n)
    if abs(n - whole) <= 1e-6 * max(1.0, n) and whole >= 1:
        return int(whole), None
    n_steps = int(math.ceil(n))
    return n_steps, stop - (start + (n_steps - 1) * step)


#: The [experiment] fields that 0 leaves to the master, as the FMI Cross-Check's option files say
#: "StepSize 0" and "RelTol 0": the step the FMUs' default experiments give, else (stop - start) / 500 as
#: FMPy chooses; the tolerance each FMU's own (see :func:`cosim.plan.resolution.resolve`, which notes the value used).
TOOLS_CHOICE = ("step", "tolerance")


#: The tables whose fields ``--set`` may also set ("experiment.stop=5", "record.variables=[...]"), with
#: their fields; an instance of the same name takes precedence.
SET_TABLES = {"experiment": _EXPERIMENT_KEYS, "record": _RECORD_KEYS}
#: The tables inside those whose keys ``--set`` may set ("experiment.iteration.method=newton"), with their
#: keys; the table is made when the document has none.
SET_SUBTABLES = {("experiment", t.name): t.keys for t in algorithms.TABLES}


def settable_table(key: str) -> str | None:
    """The table whose field ``key`` is, as ``--set TABLE.KEY=VALUE`` sets it ("experiment" for "algorithm",
    "record" for "decimation", "experiment.iteration" for "max_iterations"); None for a key of none."""
    for table, keys in SET_TABLES.items():
        if key in keys:
            return table
    return next((".".join(path) for path, keys in SET_SUBTABLES.items() if key in keys), None)


def _subtable(doc: dict[str, Any], file: str, path: tuple[str, ...]) -> dict[str, Any]:
    """The table at ``path`` ("experiment", "iteration") of the document, made where it is missing;
    ScenarioError naming it where the document has something else there."""
    table = doc
    for i, key in enumerate(path):
        table = table.setdefault(key, {})
        if not isinstance(table, dict):
            raise ScenarioError(file, ".".join(path[:i + 1]), "must be a table")
    return table


def _set_table_field(doc: dict[str, Any], file: str, fld: str, inst: str, var: str, value: Any) -> None:
    """``--set experiment.FIELD=VALUE`` (or record.FIELD, or a key of a table inside one:
    experiment.iteration.method): the field set in the document, made where missing, for the scenario's
    checks to judge as the file's own; an unknown field refused naming the ``--set``."""
    head, dot, key = var.partition(".")
    if dot and (inst, head) in SET_SUBTABLES:
        known = SET_SUBTABLES[(inst, head)]
        if key not in known:
            raise ScenarioError(file, fld, unknown_key(key, known, f"{inst}.{head} field {key!r}"))
        _subtable(doc, file, (inst, head))[key] = value
        return
    if var not in SET_TABLES[inst]:
        nested = "".join(f", {t}.KEY" for s, t in SET_SUBTABLES if s == inst)
        raise ScenarioError(file, fld, unknown_key(var, SET_TABLES[inst], f"{inst} field {var!r}", nested))
    insts = doc["instances"]
    if (inst, var) == ("record", "variables"):   # one name alone; with one instance, its variables
        value = [value] if isinstance(value, str) else value
        if isinstance(value, list) and len(insts) == 1:
            value = [f"{next(iter(insts))}.{v}" if isinstance(v, str) and "." not in v else v for v in value]
    _subtable(doc, file, (inst,))[var] = value


def apply_overrides(doc: dict[str, Any], overrides: dict[str, Any] | None, file: str) -> dict[str, Any]:
    """Set ``overrides`` ({'inst.param': value}, from ``--set`` or the API) as parameters in a document.

    A key without an instance (``"e"``) is the variable of the document's one instance (refused when it
    has several); ``"experiment.FIELD"`` and ``"record.FIELD"`` set a field of [experiment] or [record],
    and ``"experiment.iteration.KEY"``, ``"experiment.adaptive.KEY"`` a key of those tables, made when
    missing (unless an instance is so named), checked as the file's own values are (``record.variables``:
    a name alone is the variable of the one instance, as in a key)."""
    for ref, value in (overrides or {}).items():
        fld = f"--set {ref}"
        insts = doc.setdefault("instances", {})
        if isinstance(ref, str) and "." not in ref and ref and isinstance(insts, dict) and len(insts) == 1:
            ref = f"{next(iter(insts))}.{ref}"
        inst, var = split_ref(file, fld, ref)
        if not isinstance(insts, dict):
            raise ScenarioError(file, "instances", "must be a table")
        if inst not in insts and inst in SET_TABLES:
            _set_table_field(doc, file, fld, inst, var, value)
            continue
        if inst not in insts:
            raise ScenarioError(file, fld, f"unknown instance {inst!r}"
                                           f"{did_you_mean(inst, [*insts, *(t for t in SET_TABLES if t not in insts)])}")
        if not isinstance(insts[inst], dict):
            raise ScenarioError(file, f"instances.{inst}", "must be a table")
        params = insts[inst].setdefault("parameters", {})
        if not isinstance(params, dict):
            raise ScenarioError(file, f"instances.{inst}.parameters", "must be a table")
        params[var] = value
    return doc


def parse_value(text: str) -> Any:
    """A value given on the command line: true/false, a JSON number, string or array, else the text."""
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        return text


def parse_set(items: list[str] | None, form: str = "INSTANCE.PARAM=VALUE") -> dict[str, Any]:
    """['plant.foam_da1=0.4', 'controller.task="line"'] -> {'plant.foam_da1': 0.4, ...}; repeated options
    add up (the last value of a name wins).  A key without an instance (``e=0.5``) is kept as it is: it
    names the variable of a scenario of one instance (:func:`apply_overrides`)."""
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError("--set", item, f"expected {form}")
        out[key.strip()] = parse_value(text)
    return out


def load(path: str | os.PathLike, resolver=None, overrides: dict[str, Any] | None = None,
         limits: LimitOverrides | None = None, shipped: Path | None = None) -> Scenario:
    """Read a scenario file (following its ``base`` chain; ``shipped``: see :func:`read_document`), apply
    ``overrides`` ({'inst.param': value}), and check its structure (``limits``: see :func:`parse`)."""
    path = Path(path)
    doc = apply_overrides(read_document(path, shipped=shipped), overrides, str(path))
    return parse(doc, str(path), resolver, limits)
