"""``wmr-cosim info``: describe any FMU whose model description can be read (FMI 1.0, 2.0 or 3.0;
co-simulation, model exchange or scheduled execution; with or without a binary for this platform), and
say in one line what would stop the master from running it, or how it runs it (co-simulation, or model
exchange through the master's integrator).

Only an archive that is unsafe (a decompression bomb, an entry outside the archive), has no readable
model description, or declares XML entities is refused (:class:`~wmr_cosim.cosim.messages.errors.FmuLoadError`,
one line, exit code 2): the same checks every FMU gets before its description is parsed.
"""
from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import Any

from fmpy import read_model_description

from ..cosim import (ArchiveLimits, check_archive, CO_SIMULATION, DEFAULT_LIMITS, fmi_version, FmuLoadError,
                    FmuModel, load_model, MODEL_EXCHANGE)

#: The largest double: a bound of this size (or infinite) is no bound, and is shown as nothing.
UNBOUNDED = 1.7976931348623157e308


def _bound(value: Any) -> str:
    """A min or max as the model description gives it; "" for none and for an unbounded one (±DBL_MAX)."""
    if value is None:
        return ""
    text = str(value).strip()
    try:
        v = float(text)
    except ValueError:
        return text
    return "" if not math.isfinite(v) or abs(v) >= UNBOUNDED else text


def _text(value: Any) -> str:
    return "" if value is None else str(value)


def _platforms(path: Path) -> tuple[list[str], bool]:
    """The platform folders under binaries/ that hold a file, and whether the archive has sources/."""
    with zipfile.ZipFile(path) as zf:
        names = [n for n in zf.namelist() if not n.endswith("/")]
    platforms = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2})
    return platforms, any(n.startswith("sources/") for n in names)


def kinds(md: Any) -> list[str]:
    """The interface kinds a model description declares: CS (co-simulation), ME (model exchange), SE
    (scheduled execution, FMI 3.0)."""
    return [k for k, attr in (("CS", "coSimulation"), ("ME", "modelExchange"), ("SE", "scheduledExecution"))
            if getattr(md, attr, None) is not None]


def verdict(path: Path, md: Any, limits: ArchiveLimits = DEFAULT_LIMITS) -> str:
    """One line: why the master cannot run this FMU here ("cannot run here: ..."), or how it runs it
    ("runs here as: ...", the interface an instance uses by default and how to ask for the other); its
    archive within ``limits``."""
    version = str(md.fmiVersion)
    if version != "2.0" and not version.startswith("3."):
        return f"cannot run here: FMI {version} (the master runs FMI 2.0 and 3.0 FMUs)"
    if md.coSimulation is None and md.modelExchange is None and getattr(md, "scheduledExecution", None) is None:
        return "cannot run here: no interface (the master runs co-simulation, model exchange and scheduled " \
               "execution FMUs)"
    try:
        model = load_model(path, limits)
    except FmuLoadError as exc:
        return "cannot run here: " + str(exc).replace(f"{path}: ", "", 1)
    return f"runs here as: {_runs_as(model)}"


def _runs_as(model: FmuModel) -> str:
    """How ``wmr-cosim run`` runs a runnable FMU: the interface it uses by default, how to ask for the other."""
    usable = [i for i in model.interfaces if i not in model.missing_binaries]
    if not model.has_cs and not model.has_me:
        return ("scheduled execution, its partitions activated at its input clocks' ticks by the master's scheduler "
                "(a scenario gives a triggered clock's ticks: clock_ticks)")
    if CO_SIMULATION not in usable:
        no_cs = "" if not model.has_cs else " (no co-simulation binary for this platform)"
        return f"model exchange{no_cs}, integrated by the master (cvode; --solver euler or rk4, or an instance's solver)"
    if MODEL_EXCHANGE not in usable:
        return "co-simulation"
    return ("co-simulation (or model exchange, integrated by the master: --solver NAME, or an instance's "
            "interface = \"model-exchange\")")


def _identifiers(md: Any) -> str:
    """The model identifier; where co-simulation and model exchange name different binaries, both."""
    cs, me = (getattr(getattr(md, a, None), "modelIdentifier", None) for a in ("coSimulation", "modelExchange"))
    se = getattr(getattr(md, "scheduledExecution", None), "modelIdentifier", None)
    if cs and me and cs != me:
        return f"{cs} (model exchange: {me})"
    return cs or me or se or "?"


def _capabilities(md: Any) -> list[str]:
    """One line per interface the master runs: co-simulation's variable step and state; model exchange's
    state, whether it needs completedIntegratorStep, its event indicators and continuous states."""
    if str(md.fmiVersion).startswith("1."):
        return []
    lines = []
    cs, me = md.coSimulation, md.modelExchange
    if cs is not None:
        lines.append(f"  co-simulation: variable step: {cs.canHandleVariableCommunicationStepSize}; get/set state: "
                     f"{cs.canGetAndSetFMUstate}; serialize state: {cs.canSerializeFMUstate}")
    if me is not None:
        needs = (bool(me.needsCompletedIntegratorStep) if str(md.fmiVersion).startswith("3")
                 else not me.completedIntegratorStepNotNeeded)      # (FMI 2.0 says it the other way round)
        lines.append(f"  model exchange: get/set state: {me.canGetAndSetFMUstate}; serialize state: "
                     f"{me.canSerializeFMUstate}; needsCompletedIntegratorStep: {needs}; event indicators: "
                     f"{md.numberOfEventIndicators or 0}; continuous states: {md.numberOfContinuousStates or 0}")
    return lines


def describe(path: str | Path, limits: ArchiveLimits = DEFAULT_LIMITS) -> str:
    """A readable description of an FMU: model, FMI version, kinds, platforms, default experiment, what
    would stop a run, and a table of the variables (causality, variability, type, unit, range, start).
    Raises FmuLoadError (one line) when the archive is unsafe (for ``limits``) or its model description
    unreadable."""
    path = Path(path)
    check_archive(path, limits)
    fmi_version(path)          # (refuses XML entities before FMPy parses the document)
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # FMPy raises plain Exceptions for unreadable descriptions
        raise FmuLoadError(f"{path}: cannot read modelDescription.xml ({' '.join(str(exc).split())})") from None
    names = {"CS": "co-simulation", "ME": "model exchange", "SE": "scheduled execution"}
    platforms, sources = _platforms(path)
    lines = [f"{path}",
             f"  model {md.modelName} (FMI {md.fmiVersion}; {', '.join(f'{names[k]} ({k})' for k in kinds(md)) or 'no interface'}; "
             f"identifier {_identifiers(md)})",
             f"  generated by {md.generationTool or '?'}; guid {md.guid}",
             f"  platforms: {', '.join(platforms) or 'no binaries'}{'; sources included' if sources else ''}"]
    lines += _capabilities(md)
    de = md.defaultExperiment
    given = [f"{k} {v}" for k, v in (("start", getattr(de, "startTime", None)), ("stop", getattr(de, "stopTime", None)),
                                      ("step", getattr(de, "stepSize", None)),
                                      ("tolerance", getattr(de, "tolerance", None))) if v is not None]
    lines.append(f"  default experiment: {', '.join(given) or 'none'}")
    lines.append(f"  {verdict(path, md, limits)}")
    rows = [("name", "causality", "variability", "type", "unit", "min", "max", "start", "description")]
    for v in md.modelVariables:
        dt = v.declaredType
        unit = v.unit or (dt.unit if dt is not None else None)
        vmin = v.min if v.min is not None else (dt.min if dt is not None else None)
        vmax = v.max if v.max is not None else (dt.max if dt is not None else None)
        rows.append((v.name, v.causality or "local", v.variability or "continuous", _text(v.type), _text(unit),
                     _bound(vmin), _bound(vmax), _text(v.start), v.description or ""))
    widths = [max(len(r[i]) for r in rows) for i in range(8)]
    for r in rows:
        lines.append(("  " + "  ".join(r[i].ljust(widths[i]) for i in range(8)) + "  " + r[8]).rstrip())
    return "\n".join(lines)
