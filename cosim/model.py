"""What the master knows of an FMU before running it: its model description, variables and units."""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from xml.etree import ElementTree

from fmpy import read_model_description

from .archive import check_archive
from .errors import FmuLoadError
from .units import Unit, lookup, units_of

#: FMI 2.0 type -> the Python types a scenario value of that variable may have.
PY_TYPES: dict[str, tuple[type, ...]] = {"Real": (float, int), "Integer": (int,), "Enumeration": (int,),
                                          "Boolean": (bool,), "String": (str,)}


@dataclass
class Variable:
    """One scalar variable of an FMU (FMI 2.0)."""

    name: str
    vr: int
    type: str
    causality: str
    variability: str
    unit: Unit | None
    min: float | None
    max: float | None
    start: Any
    description: str = ""
    initial: str | None = None

    def settable(self) -> str | None:
        """None if a master may set this variable before initialisation (FMI 2.0, 4.2.4: variability not
        constant and initial exact or approx, or an input), else the reason."""
        if self.variability == "constant":
            return f"{self.name} is a constant"
        if self.causality == "input" or self.initial in ("exact", "approx"):
            return None
        if self.causality == "independent":
            return f"{self.name} is the independent variable"
        why = f"initial=\"{self.initial}\"" if self.initial else f"a {self.causality} with no start value"
        return f"{self.name} is {self.causality} with {why}: only parameters, inputs and variables with " \
               "initial exact or approx can be set"

    def check_range(self, value: Any) -> str | None:
        """None if value is within [min, max], else the reason."""
        if self.type not in ("Real", "Integer", "Enumeration") or isinstance(value, bool):
            return None
        if self.min is not None and value < self.min:
            return f"value {value!r} is below the minimum {self.min!r} declared by the FMU"
        if self.max is not None and value > self.max:
            return f"value {value!r} is above the maximum {self.max!r} declared by the FMU"
        return None


@dataclass
class FmuModel:
    """An FMU file and its model description (FMI 2.0 co-simulation checked)."""

    path: Path
    md: Any
    variables: dict[str, Variable] = field(default_factory=dict)

    @property
    def model_name(self) -> str:
        return self.md.modelName

    @property
    def can_vary_step(self) -> bool:
        return bool(self.md.coSimulation.canHandleVariableCommunicationStepSize)

    @property
    def default_step(self) -> float | None:
        de = self.md.defaultExperiment
        return float(de.stepSize) if de is not None and de.stepSize is not None else None

    def outputs(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "output"]


def _num(text: Any, typ: str) -> float | None:
    if text is None:
        return None
    try:
        return int(text) if typ in ("Integer", "Enumeration") else float(text)
    except (TypeError, ValueError):
        return None


def _start(v: Any) -> Any:
    s = v.start
    if s is None:
        return None
    if v.type == "Real":
        return float(s)
    if v.type in ("Integer", "Enumeration"):
        return int(s)
    if v.type == "Boolean":
        return s in ("true", "1", True)
    return s


def _initial(v: Any) -> str | None:
    """The variable's ``initial``, or its default by causality and variability (FMI 2.0, table of 2.2.7)."""
    if v.initial:
        return v.initial
    if v.causality in ("parameter",) or v.variability == "constant":
        return "exact"
    if v.causality == "calculatedParameter":
        return "calculated"
    if v.causality in ("output", "local"):
        return "calculated" if v.start is None else "exact"
    return None


def _fmi_version(path: Path) -> str:
    """The fmiVersion attribute of the model description, read before FMPy parses it."""
    try:
        with zipfile.ZipFile(path) as zf, zf.open("modelDescription.xml") as fh:
            for _, elem in ElementTree.iterparse(fh, events=("start",)):
                return elem.get("fmiVersion", "?")
    except KeyError:
        raise FmuLoadError(f"{path}: no modelDescription.xml: not an FMU") from None
    except ElementTree.ParseError as exc:
        raise FmuLoadError(f"{path}: modelDescription.xml is not well-formed XML ({exc})") from None
    return "?"


def _check_binary(path: Path, identifier: str) -> None:
    """FmuLoadError unless the archive holds the binary for this platform, named by the model identifier."""
    from fmpy import platform, sharedLibraryExtension

    want = f"binaries/{platform}/{identifier}{sharedLibraryExtension}"
    with zipfile.ZipFile(path) as zf:
        names = zf.namelist()
    if want in names:
        return
    here = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2})
    others = [n for n in names if n.startswith(f"binaries/{platform}/") and n.endswith(sharedLibraryExtension)]
    if others:
        raise FmuLoadError(f"{path}: no {want} (the binary for this platform must be named after the model "
                           f"identifier {identifier!r}; the archive has {others[0]})")
    raise FmuLoadError(f"{path}: no binary for this platform ({platform}): the FMU has binaries for "
                       f"{', '.join(here) or 'no platform'} (a source-only or other-platform FMU cannot run here)")


def load_model(path: str | os.PathLike) -> FmuModel:
    """Read and check an FMU: it exists, is a safe archive, and is FMI 2.0 with co-simulation."""
    path = Path(path)
    check_archive(path)
    version = _fmi_version(path)
    if version != "2.0":
        raise FmuLoadError(f"{path}: FMI version {version}: only FMI 2.0 is supported")
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # FMPy raises plain Exceptions for unreadable descriptions
        raise FmuLoadError(f"{path}: cannot read modelDescription.xml ({' '.join(str(exc).split())})") from None
    if md.fmiVersion != "2.0":
        raise FmuLoadError(f"{path}: FMI version {md.fmiVersion}: only FMI 2.0 is supported")
    if md.coSimulation is None:
        raise FmuLoadError(f"{path}: not a co-simulation FMU (model exchange only)")
    _check_binary(path, md.coSimulation.modelIdentifier)
    defined = units_of(md)
    model = FmuModel(path, md)
    for v in md.modelVariables:
        typ = v.type
        unit_name = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        vmin = v.min if v.min is not None else (v.declaredType.min if v.declaredType is not None else None)
        vmax = v.max if v.max is not None else (v.declaredType.max if v.declaredType is not None else None)
        model.variables[v.name] = Variable(
            v.name, int(v.valueReference), typ, v.causality or "local", v.variability or "continuous",
            lookup(unit_name, defined) if typ == "Real" else None,
            _num(vmin, typ), _num(vmax, typ), _start(v), v.description or "", _initial(v))
    return model
