"""What the master knows of an FMU before running it: its model description, variables and units."""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from xml.parsers import expat

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


def _fmi_version(path: Path) -> str:
    """The fmiVersion attribute of the model description, read before FMPy parses it.  A model description
    that declares XML entities is refused: an external entity can read a local file into the model, and
    nested internal ones expand without bound ("billion laughs"); FMI needs neither."""
    class _Root(Exception):
        pass

    def start(name: str, attrs: dict[str, str]) -> None:
        raise _Root(attrs.get("fmiVersion", "?"))

    def entity(name: str, *_: Any) -> None:
        raise FmuLoadError(f"{path}: modelDescription.xml declares the XML entity {name!r}: refused (entities can "
                           "read local files or expand without bound)")

    parser = expat.ParserCreate()
    parser.StartElementHandler = start
    parser.EntityDeclHandler = entity
    try:
        with zipfile.ZipFile(path) as zf, zf.open("modelDescription.xml") as fh:
            parser.ParseFile(fh)
    except _Root as root:
        return str(root.args[0])
    except KeyError:
        raise FmuLoadError(f"{path}: no modelDescription.xml: not an FMU") from None
    except expat.ExpatError as exc:
        raise FmuLoadError(f"{path}: modelDescription.xml is not well-formed XML ({exc})") from None
    return "?"


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
            _num(vmin, typ), _num(vmax, typ), _start(v), v.description or "")
    return model
