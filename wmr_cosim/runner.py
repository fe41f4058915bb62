"""Glue between the generic master (wmr_cosim.cosim) and this project's FMUs: model names such as
``WmrPlant`` resolve to FMUs built on demand; the ``run`` and ``check`` commands."""
from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from .cosim import (apply_overrides, CosimError, export_remarks, export_ssp as write_ssp, file_kind, FileKind, is_ssp,
                    LimitOverrides, load as load_scenario, load_model, load_ssp, parse as parse_scenario,
                    parse_set, Plan, Protocol, resolve, run as run_plan, RunResult, ScenarioError)
from .fmus.build import FMI_VERSION
from .scenario_files import shipped_folder


def resolve_model(name: str) -> Path | None:
    """Our FMU for a model name (WmrPlant, WmrSensor, WmrController; their FMI 3.0 versions WmrPlant3,
    WmrSensor3, WmrController3; WmrCPlant, the plant in C), built when missing or when its sources changed;
    None for any other name."""
    from .fmus.build import BuildError, build_all

    if name == "WmrCPlant":
        from .fmus.cplant_build import CBuildError, build_c_plant
        try:
            return build_c_plant()
        except CBuildError as exc:
            raise CosimError(f"building {name}: {' '.join(str(exc).split())}") from None
    if name not in FMI_VERSION:
        return None
    try:
        return build_all(models=(name,))[name]
    except BuildError as exc:
        raise CosimError(f"building {name}: {' '.join(str(exc).split())}") from None


#: The model names :func:`resolve_model` knows (the suggestion for a misspelt one reads them).
MODEL_NAMES = (*FMI_VERSION, "WmrCPlant")
resolve_model.model_names = MODEL_NAMES  # type: ignore[attr-defined]


def resolver(fmi: int = 2) -> Callable[[str], Path | None]:
    """A model-name resolver for FMI version ``fmi``: 2 is :func:`resolve_model`; 3 resolves our FMI 2.0
    model names (WmrPlant, WmrSensor, WmrController) to their FMI 3.0 versions (WmrPlant3, ...), so a
    scenario written for the FMI 2.0 FMUs runs through the FMI 3.0 ones unchanged."""
    if fmi == 2:
        return resolve_model
    if fmi != 3:
        raise CosimError(f"FMI version {fmi}: 2 or 3")
    from .fmus.build import SLAVES3
    to3 = {v: k for k, v in SLAVES3.items()}

    def resolve3(name: str) -> Path | None:
        return resolve_model(to3.get(name, name))
    resolve3.model_names = MODEL_NAMES  # type: ignore[attr-defined]
    return resolve3


def carry_fmi3(carry: dict[str, str], finals: dict[str, dict[str, float]]) -> dict[str, Any]:
    """A protocol's carry written for our FMI 2.0 controller (``controller.W1_init`` = ``learn.controller.W1``,
    ``P12_init`` = ``P12``, ...) applied to the FMI 3.0 one: sources read from the array columns
    (``W[1]``, ``P[1,2]``), the element parameters gathered into the arrays ``W_init`` (3) and ``P_init``
    (3 x 3, symmetric).  Other carried values pass as they are."""
    import re

    out: dict[str, Any] = {}
    arrays: dict[str, dict[tuple[int, ...], float]] = {}
    for ref, src in carry.items():
        run, col = src.split(".", 1)
        m = re.fullmatch(r"(.*\.)(W|P)(\d)(\d)?", col)
        if m:
            col = f"{m.group(1)}{m.group(2)}[{','.join(g for g in m.group(3, 4) if g)}]"
        if col not in finals[run]:
            raise CosimError(f"carry {ref} = {src!r}: {col!r} was not recorded by run {run!r}")
        value = finals[run][col]
        r = re.fullmatch(r"(.*\.)(W|P)(\d)(\d)?_init", ref)
        if not r:
            out[ref] = value
            continue
        idx = tuple(int(g) - 1 for g in r.group(3, 4) if g)
        arrays.setdefault(f"{r.group(1)}{r.group(2)}_init", {})[idx] = value
        if len(idx) == 2:
            arrays[f"{r.group(1)}{r.group(2)}_init"].setdefault(idx[::-1], value)
    for ref, elems in arrays.items():
        if len({len(i) for i in elems}) > 1:   # P1_init beside P12_init: no one shape holds both
            raise CosimError(f"carry {ref}: elements of one index and of two ({', '.join(map(str, sorted(elems)))}, "
                             "0-based); carry each element with the indices of its array")
        shape = [max(i[d] for i in elems) + 1 for d in range(len(next(iter(elems))))]
        cells: list[tuple[int, ...]] = [(i,) for i in range(shape[0])] if len(shape) == 1 else \
            [(i, j) for i in range(shape[0]) for j in range(shape[1])]
        missing = [c for c in cells if c not in elems]
        if missing:
            raise CosimError(f"carry {ref}: elements {missing} (0-based) are not carried; carry every element")
        out[ref] = [elems[c] for c in cells]
    return out


def run_protocol(path: str | Path | Protocol, out_dir: str | Path,
                 resolver: Callable[[str], Path | None] | None = None,
                 on_run: Callable[[str, RunResult], None] | None = None,
                 judge: Callable[[RunResult], RunResult] | None = None, **options: Any) -> dict[str, RunResult]:
    """:func:`wmr_cosim.cosim.runtime.protocol.run_protocol` (same ``options``; the resolver defaults to
    :func:`resolve_model`; ``path`` may be a file already read) with every run judged by ``judge`` (the
    paper's controller: :func:`wmr_cosim.paper.judge_run`) as it finishes, before ``on_run``."""
    from .cosim import run_protocol as run_all

    return run_all(path, out_dir, resolver or resolve_model, on_run=on_run, judge=judge, **options)


def fmu_document(fmu: str | Path, inputs: str | Path | None = None, stop: float | None = None,
                 step: float | None = None, start: float | None = None,
                 limits: LimitOverrides | None = None, fields: dict[str, Any] | None = None) -> dict[str, Any]:
    """The scenario document of one FMU run alone (as ``fmpy simulate`` runs it): one instance named after
    the model identifier (of its co-simulation interface, else of its model exchange one), every output
    recorded, start, stop and step [s] from its default experiment unless given (with no default step, 500
    steps over the run, as FMPy; with no stop either, 1 s), inputs from a CSV table.  ``limits``: the
    caller's archive limits (over the defaults); ``fields``: more keys of the instance (``solver``,
    ``max_step``, ``interface``, ...), checked as a scenario file's."""
    import re

    path = Path(fmu).resolve()
    model = load_model(path, (limits or LimitOverrides()).over())
    name = re.sub(r"\W", "_", model.identifier) or "fmu"
    name = name if name.isidentifier() else f"fmu_{name}"
    doc: dict[str, Any] = {"instances": {name: {**(fields or {}), "fmu": str(path)}}, "record": {"variables": ["*.*"]}}
    de = model.md.defaultExperiment
    if step is None and model.default_step is None:  # as FMPy: 500 steps over the run
        begin = start if start is not None else float(de.startTime) if de is not None and de.startTime is not None \
            else 0.0
        end = stop if stop is not None else float(de.stopTime) if de is not None and de.stopTime is not None else 1.0
        step = (end - begin) / 500 if end > begin else 1.0   # (a stop not after the start: the check refuses it)
        stop = end
    exp = {k: v for k, v in (("stop", stop), ("step", step)) if v is not None}
    if exp:
        doc["experiment"] = exp
    if inputs is not None:
        doc["inputs"] = {"file": str(Path(inputs).resolve())}
    return doc


def fmu_plan(fmu: str | Path, overrides: dict[str, Any] | None = None, inputs: str | Path | None = None,
             stop: float | None = None, step: float | None = None, force: bool = False, isolate: bool = False,
             limits: LimitOverrides | None = None, fields: dict[str, Any] | None = None) -> Plan:
    """The checked plan of one FMU run alone (see :func:`fmu_document`); ``overrides`` may set the
    experiment (``experiment.stop``: its 500 default steps then span the new run); ``isolate`` hosts it in a
    child process; ``limits``: the caller's archive limits; ``fields``: more keys of its instance (the
    command line's ``--solver`` and ``--max-step``)."""
    given = {k: v for k in ("start", "stop", "step")
             if isinstance(v := (overrides or {}).get(f"experiment.{k}"), (int, float)) and not isinstance(v, bool)}
    try:
        doc = fmu_document(fmu, inputs, given.get("stop", stop), given.get("step", step), given.get("start"), limits,
                           fields)
    except CosimError as exc:
        raise ScenarioError(str(fmu), "", str(exc).replace(f"{Path(fmu).resolve()}: ", "", 1)) from None
    doc = apply_overrides(doc, overrides, str(fmu))
    return resolve(parse_scenario(doc, str(fmu), limits=limits), force, isolate_all=isolate)


def read_scenario(path: str | Path, limits: LimitOverrides | None = None) -> Protocol:
    """A scenario file (a protocol or a single run) read and parsed once, with our model names and shipped
    scenario files; ``limits``: the caller's archive limits."""
    from .cosim import read_protocol

    return read_protocol(path, resolve_model, limits, shipped_folder())


def load_plan(path: str | Path, overrides: dict[str, Any] | None = None, force: bool = False, isolate: bool = False,
              limits: LimitOverrides | None = None, parsed: Protocol | None = None) -> Plan:
    """Parse a scenario file (TOML; not an SSP archive: see :func:`ssp_plan`) and run every check against
    its FMUs; ``isolate`` hosts every instance in a child process; ``limits``: the caller's archive limits.
    ``parsed``: the file already read (:func:`wmr_cosim.cosim.runtime.protocol.read_protocol`), not read again."""
    if is_ssp(path):
        raise CosimError(f"{path}: an SSP archive, not a scenario file (.toml)")  # (run/check use ssp_plan)
    sc = parsed.with_parameters(overrides) if parsed is not None else \
        load_scenario(path, resolve_model, overrides, limits, shipped_folder())
    return resolve(sc, force, isolate_all=isolate)


@contextlib.contextmanager
def ssp_plan(path: str | Path, overrides: dict[str, Any] | None = None, force: bool = False, isolate: bool = False,
             limits: LimitOverrides | None = None) -> Iterator[Plan]:
    """The checked plan of an SSP archive, its FMUs extracted for the time of the ``with`` block."""
    arch = load_ssp(path, overrides=overrides, limits=limits)
    for w in arch.warnings:
        print(f"wmr-cosim: warning: {w}", file=sys.stderr)
    try:
        yield resolve(arch.scenario, force, isolate_all=isolate)
    finally:
        arch.cleanup()


def export_ssp(path: str | Path, out: str | Path, overrides: dict[str, Any] | None = None,
               limits: LimitOverrides | None = None) -> Path:
    """Write the scenario file ``path`` as an SSP 1.0 archive ``out``; what the export changes for other
    tools (String parameters, OMSimulator's Jacobi master) goes to stderr, one line each."""
    plan = load_plan(path, overrides, limits=limits)
    written = write_ssp(plan, out)
    for kind, text in export_remarks(plan):
        print(f"wmr-cosim: {kind}: {text}", file=sys.stderr)
    return written


def default_out(path: str | Path) -> Path:
    return Path("results") / Path(path).stem


def is_fmu(path: str | Path) -> bool:
    return file_kind(path) is FileKind.FMU


def is_scenario(path: str | Path) -> bool:
    """A scenario file (``.toml``, or any file that is neither an FMU nor an SSP archive)."""
    return file_kind(path) is FileKind.SCENARIO


def run_scenario(path: str | Path, out: str | Path | None = None, overrides: dict[str, Any] | None = None,
                 progress: bool | None = None, inputs: str | Path | None = None, stop: float | None = None,
                 step: float | None = None, force: bool = False, isolate: bool = False,
                 real_time: float | None = None, limits: LimitOverrides | None = None,
                 parsed: Protocol | None = None, fields: dict[str, Any] | None = None,
                 on_plan: Callable[[Plan], None] | None = None,
                 judge: Callable[[RunResult], RunResult] | None = None, live: Any = None) -> RunResult:
    """Run a scenario file (.toml), an SSP archive (.ssp) or one FMU alone (.fmu); ``isolate`` hosts every
    instance in a child process of its own; ``real_time=FACTOR`` paces the steps to the wall clock;
    ``limits``: the caller's archive limits; ``parsed``: a scenario file already read (see :func:`load_plan`);
    ``fields``: one FMU alone: more keys of its instance (``solver``, ``max_step``: see :func:`fmu_plan`);
    ``on_plan``: called with the checked plan before the run starts (the command line prints its notes);
    ``judge``: what a finished run of a scenario file becomes (see :func:`run_protocol`); ``live``: a
    :class:`wmr_cosim.live.LiveOptions`: the run served live while it goes (docs/live.md; not an SSP archive,
    whose FMUs are extracted for the run only: its replay.toml could not name them)."""
    out = out if out is not None else default_out(path)
    seen = on_plan or (lambda plan: None)

    def run(plan: Plan) -> RunResult:
        seen(plan)
        if live is not None:
            from .live import run_live
            return run_live(plan, out, live, real_time=real_time)
        return run_plan(plan, out, progress=progress, real_time=real_time)

    if is_fmu(path):
        return run(fmu_plan(path, overrides, inputs, stop, step, force, isolate, limits, fields))
    if is_ssp(path):
        if live is not None:
            raise CosimError(f"{path}: --live serves a scenario file (.toml) or one FMU, not an SSP archive "
                             "(its FMUs are extracted for the run only: its replay.toml could not name them)")
        with ssp_plan(path, overrides, force, isolate, limits) as plan:
            return run(plan)
    res = run(load_plan(path, overrides, force, isolate, limits, parsed))
    return judge(res) if judge is not None else res


__all__ = ["CosimError", "ScenarioError", "resolve_model", "parse_set", "load_plan", "ssp_plan", "export_ssp",
           "run_scenario"]
