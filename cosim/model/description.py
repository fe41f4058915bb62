"""What the master knows of an FMU before running it: its model description, variables and units."""
from __future__ import annotations

import math
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from xml.parsers import expat

from fmpy import read_model_description

from ..messages.errors import FmuLoadError
from .archive import ArchiveLimits, check_archive
from .binary import library_problem
from .clocks import Clock, read_clocks
from .types import FLOAT64_TYPES, INT_RANGES, INTEGER_KINDS, KINDS, NUMERIC_KINDS, TEXT_KINDS
from .units import Unit, lookup, units_of

#: The FMU interfaces an instance can use (``[instances.X] interface``).
CO_SIMULATION, MODEL_EXCHANGE = "co-simulation", "model-exchange"
#: FMI 3.0 Scheduled Execution: the master activates the FMU's model partitions at its clocks' ticks.
SCHEDULED_EXECUTION = "scheduled-execution"

if TYPE_CHECKING:   # (FMPy has no type information: to mypy these are Any)
    from fmpy.model_description import ModelDescription, ScalarVariable

#: The interfaces the master runs -> the model description's attribute (FMPy) that declares each.
INTERFACES = {CO_SIMULATION: "coSimulation", MODEL_EXCHANGE: "modelExchange",
              SCHEDULED_EXECUTION: "scheduledExecution"}
#: The platform folder of the binaries by FMI version.
PLATFORMS = {2: "linux64", 3: "x86_64-linux"}


@dataclass
class Variable:
    """One variable of an FMU (FMI 2.0 or 3.0; an FMI 3.0 array with its shape)."""

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
    fmi_type: str = ""                 # the FMI type as declared (Float64, Int8, ...; FMI 2.0: = type)
    shape: tuple[int, ...] = ()        # FMI 3.0 arrays: the dimensions; () for a scalar

    def __post_init__(self) -> None:
        if not self.fmi_type:          # (FMI 2.0, and a variable made by hand: the FMI type is the type)
            self.fmi_type = self.type

    @property
    def is_float64(self) -> bool:
        """A 64-bit float: FMI 2.0 Real or FMI 3.0 Float64 (what the step's row of floats holds; not Float32)."""
        return self.fmi_type in FLOAT64_TYPES

    @property
    def is_integer(self) -> bool:
        """Of an integer kind: an FMI integer type or an enumeration."""
        return self.type in INTEGER_KINDS

    @property
    def is_numeric(self) -> bool:
        """Of a numeric kind: Real (any float type), an FMI integer type or an enumeration."""
        return self.type in NUMERIC_KINDS

    @property
    def is_text(self) -> bool:
        """Of a text kind: String or FMI 3.0 Binary."""
        return self.type in TEXT_KINDS

    @property
    def size(self) -> int:
        n = 1
        for d in self.shape:
            n *= d
        return n

    def element_names(self) -> list[str]:
        """``x`` for a scalar; ``x[1]``, ``x[2]``, ... (``A[1,1]``, ``A[1,2]``, ... row-major) for an array."""
        if not self.shape:
            return [self.name]
        import itertools
        return [f"{self.name}[{','.join(str(i + 1) for i in idx)}]"
                for idx in itertools.product(*(range(d) for d in self.shape))]

    def settable(self) -> str | None:
        """None if a master may set this variable before initialisation (FMI 2.0, 4.2.4: variability not
        constant and initial exact or approx, or an input), else the reason."""
        if self.variability == "constant":
            return f"{self.name} is a constant"
        if self.causality == "structuralParameter":
            return f"{self.name} is a structural parameter (it sizes arrays): not supported"
        if self.causality == "input" or self.initial in ("exact", "approx"):
            return None
        if self.causality == "independent":
            return f"{self.name} is the independent variable"
        why = f"initial=\"{self.initial}\"" if self.initial else f"a {self.causality} with no start value"
        return f"{self.name} is {self.causality} with {why}: only parameters, inputs and variables with " \
               "initial exact or approx can be set"

    def check_range(self, value: Any) -> str | None:
        """None if value is within [min, max] (and the range of its integer type), else the reason."""
        if not self.is_numeric or isinstance(value, bool):
            return None
        lo, hi = INT_RANGES.get(self.fmi_type, (None, None))
        if lo is not None and not lo <= value <= hi:
            return f"value {value!r} does not fit the {self.fmi_type} range {lo}..{hi}"
        if self.min is not None and value < self.min:
            return f"value {value!r} is below the minimum {self.min!r} declared by the FMU"
        if self.max is not None and value > self.max:
            return f"value {value!r} is above the maximum {self.max!r} declared by the FMU"
        return None


#: The readable name of each interface (messages, ``check``, ``info``).
INTERFACE_NAMES = {CO_SIMULATION: "co-simulation", MODEL_EXCHANGE: "model exchange",
                   SCHEDULED_EXECUTION: "scheduled execution"}


def declares_state(element: Any) -> bool:
    """Whether an interface element of a model description (FMPy's CoSimulation or ModelExchange, or None)
    declares canGetAndSetFMUstate (FMI 2.0) / canGetAndSetFMUState (FMI 3.0)."""
    return element is not None and bool(getattr(element, "canGetAndSetFMUstate", False) or
                                        getattr(element, "canGetAndSetFMUState", False))


def fmi2_cs_declares(md: Any, flag: str) -> bool:
    """Whether a model description (FMPy's) is FMI 2.0 with a co-simulation interface that declares the
    capability ``flag`` (canInterpolateInputs, providesDirectionalDerivative: what the master uses of FMI
    2.0 only)."""
    cs = getattr(md, "coSimulation", None)
    return fmi_of(md) == 2 and cs is not None and bool(getattr(cs, flag, False))


@dataclass
class FmuModel:
    """An FMU file and its model description (FMI 2.0 or 3.0, co-simulation and/or model exchange,
    checked).  ``missing_binaries``: for each interface it declares whose binary for this platform the
    archive lacks, the reason (no instance can use that interface: :meth:`check_binary`)."""

    path: Path
    md: ModelDescription   # FMPy's reading of modelDescription.xml
    variables: dict[str, Variable] = field(default_factory=dict)
    fmi: int = 2           # the FMI major version, 2 or 3 (decided at load by fmi_major)
    missing_binaries: dict[str, str] = field(default_factory=dict)
    clocks: list[Clock] = field(default_factory=list)   # FMI 3.0: its clocks (:mod:`.clocks`)

    @property
    def model_name(self) -> str:
        return self.md.modelName

    @property
    def has_cs(self) -> bool:
        """The FMU declares the co-simulation interface."""
        return self.md.coSimulation is not None

    @property
    def has_me(self) -> bool:
        """The FMU declares the model exchange interface."""
        return self.md.modelExchange is not None

    @property
    def interfaces(self) -> tuple[str, ...]:
        """The interfaces the FMU declares that the master runs, of "co-simulation", "model-exchange",
        "scheduled-execution"."""
        return tuple(name for name, attr in INTERFACES.items() if getattr(self.md, attr, None) is not None)

    @property
    def identifier(self) -> str:
        """The model identifier (of the co-simulation interface where there is one)."""
        return self.identifier_of(CO_SIMULATION if self.has_cs else MODEL_EXCHANGE if self.has_me
                                  else SCHEDULED_EXECUTION)

    @property
    def has_event_mode(self) -> bool:
        """Whether the FMI 3.0 co-simulation interface declares ``hasEventMode``."""
        return bool(getattr(self.md.coSimulation, "hasEventMode", False)) if self.has_cs else False

    def declares_state(self, interface: str) -> bool:
        """Whether ``interface`` ("co-simulation" | "model-exchange") can get and set the FMU state."""
        return declares_state(getattr(self.md, INTERFACES[interface], None))

    def identifier_of(self, interface: str) -> str:
        """The model identifier (the binary's name) of one interface the FMU declares."""
        return str(getattr(self.md, INTERFACES[interface]).modelIdentifier)

    def check_binary(self, interface: str) -> None:
        """FmuLoadError unless the archive holds the binary of ``interface`` for this platform."""
        if interface in self.missing_binaries:
            raise FmuLoadError(self.missing_binaries[interface])

    @property
    def can_vary_step(self) -> bool:
        """Whether it takes communication steps of any length: the co-simulation interface's
        canHandleVariableCommunicationStepSize; a Model Exchange FMU only (the master integrates it) can."""
        cs = self.md.coSimulation
        return cs is None or bool(cs.canHandleVariableCommunicationStepSize)

    @property
    def default_step(self) -> float | None:
        de = self.md.defaultExperiment
        return float(de.stepSize) if de is not None and de.stepSize is not None else None

    @property
    def internal_step(self) -> float | None:
        """The fixed internal step [s] an FMI 3.0 co-simulation FMU declares (fixedInternalStepSize), else None
        (also for a Model Exchange FMU only: its steps are the master's integrator's)."""
        if not self.has_cs or self.fmi != 3:
            return None
        try:
            h = float(self.md.coSimulation.fixedInternalStepSize)
        except (AttributeError, TypeError, ValueError):   # not declared, or not a number
            return None
        return h if math.isfinite(h) and h > 0 else None

    def outputs(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "output"]


def _num(text: Any, typ: str) -> float | None:
    if text is None:
        return None
    try:
        return int(text) if typ in INTEGER_KINDS else float(text)
    except (TypeError, ValueError):
        return None


def _start(v: ScalarVariable, kind: str, shape: tuple[int, ...]) -> Any:
    s = v.start
    if s is None:
        return None
    if shape and isinstance(s, str) and kind not in TEXT_KINDS:
        return [_scalar(x, kind) for x in s.split()]
    return _scalar(s, kind)


def _scalar(s: Any, kind: str) -> Any:
    try:
        if kind == "Real":
            return float(s)
        if kind in INTEGER_KINDS:
            return int(s)
    except (TypeError, ValueError):
        return None
    if kind == "Boolean":
        return s in ("true", "1", True)
    return s


def _initial(v: ScalarVariable) -> str | None:
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


def fmi_major(version: str) -> int | None:
    """The FMI major version the master runs that a model description's ``fmiVersion`` attribute names: 2
    for "2.0", 3 for "3.x"; None for any other (refused at load).  The one place that reads the attribute:
    :attr:`FmuModel.fmi` is decided by it at load, once."""
    if version == "2.0":
        return 2
    return 3 if version.startswith("3.") else None


def fmi_of(md: Any) -> int:
    """The FMI major version (2 or 3) of a model description FMPy read, of an FMU :func:`load_model`
    accepted: for those that have the description only (an instance, the isolation child); the same as
    :attr:`FmuModel.fmi`."""
    return 3 if fmi_major(str(md.fmiVersion)) == 3 else 2


def fmi_version(path: Path) -> str:
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
    except LookupError as exc:   # the XML declaration names an encoding Python has no codec for
        raise FmuLoadError(f"{path}: modelDescription.xml cannot be read ({exc})") from None
    return "?"


def _binary_problem(path: Path, zf: zipfile.ZipFile, identifier: str, fmi: int, interface: str
                    ) -> tuple[str, bool] | None:
    """None if the archive ``zf`` holds the binary for this platform named by the model identifier, a
    shared library of this platform that exports the FMI functions of ``interface``
    (:func:`.binary.library_problem`), else why not (one line, starting with ``path``) and whether the
    file is there (then it cannot be loaded)."""
    from fmpy import sharedLibraryExtension

    names = zf.namelist()
    platform = PLATFORMS[fmi]
    want = f"binaries/{platform}/{identifier}{sharedLibraryExtension}"
    if want in names:
        why = library_problem(zf.read(want), fmi, interface)
        return None if why is None else (f"{path}: {want} cannot be loaded: {why}", True)
    here = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2})
    others = [n for n in names if n.startswith(f"binaries/{platform}/") and n.endswith(sharedLibraryExtension)]
    if others:
        return (f"{path}: no {want} (the binary for this platform must be named after the model "
                f"identifier {identifier!r}; the archive has {others[0]})", False)
    return (f"{path}: no binary for this platform ({platform}): the FMU has binaries for "
            f"{', '.join(here) or 'no platform'} (a source-only or other-platform FMU cannot run here)", False)


def _missing_binaries(path: Path, model: FmuModel) -> dict[str, str]:
    """For each interface the FMU declares whose binary is missing or cannot be loaded, why (reported when
    an instance uses that interface: :meth:`FmuModel.check_binary`); FmuLoadError when the archive holds
    the binary of no declared interface (the co-simulation one's reason first)."""
    with zipfile.ZipFile(path) as zf:
        found = {i: p for i in model.interfaces
                 if (p := _binary_problem(path, zf, model.identifier_of(i), model.fmi, i)) is not None}
    if len(found) == len(model.interfaces) and not any(present for _, present in found.values()):
        raise FmuLoadError(next(iter(found.values()))[0])
    return {i: why for i, (why, _) in found.items()}


def _interfaces_checked(path: Path, md: Any) -> None:
    """FmuLoadError unless the FMU declares co-simulation, model exchange or scheduled execution."""
    if md.coSimulation is None and md.modelExchange is None and getattr(md, "scheduledExecution", None) is None:
        raise FmuLoadError(f"{path}: neither a co-simulation nor a model exchange FMU (it declares no interface)")


def _default_experiment_checked(path: Path, md: Any) -> None:
    """The default experiment's startTime, stopTime, stepSize and tolerance, where given, are finite numbers
    (every reader of them takes them as such): FmuLoadError naming the attribute otherwise."""
    de = md.defaultExperiment
    for attr in ("startTime", "stopTime", "stepSize", "tolerance"):
        v = getattr(de, attr, None) if de is not None else None
        if v is None:
            continue
        try:
            ok = math.isfinite(float(v))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise FmuLoadError(f"{path}: modelDescription.xml: DefaultExperiment {attr} {v!r} is not a finite number")


#: The models read in this process, by file (path, size, times, inode) and limits: a scenario's FMUs are
#: read when it is loaded (an SSP's) and again when it is planned, and a study plans one scenario many times.
_READ: dict[tuple[Any, ...], FmuModel] = {}
_READ_MAX = 64


def load_model(path: str | os.PathLike, limits: ArchiveLimits | None = None) -> FmuModel:
    """The FMU at ``path`` read and checked (:func:`read_model`), once per process while the file stays the
    same (its size, modification and change times and inode): the model is shared, and read only."""
    path = Path(path)
    try:
        st = path.stat()
    except OSError:
        return read_model(path, limits)   # (its one line for a file that is not there)
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino, limits)
    model = _READ.get(key)
    if model is None or model.path != path:
        model = read_model(path, limits)
        if len(_READ) >= _READ_MAX:
            _READ.pop(next(iter(_READ)))
        _READ[key] = model
    return model


def read_model(path: str | os.PathLike, limits: ArchiveLimits | None = None) -> FmuModel:
    """Read and check an FMU: it exists, is a safe archive (within ``limits``; default: the default
    limits), and is FMI 2.0 or 3.0 with co-simulation, model exchange or scheduled execution (its clocks:
    :attr:`FmuModel.clocks`), and holds the binary for this platform of at least one interface it declares
    (the one an instance uses is checked when it is planned: :meth:`FmuModel.check_binary`)."""
    path = Path(path)
    check_archive(path, limits)
    version = fmi_version(path)
    fmi = fmi_major(version)
    if fmi is None:
        raise FmuLoadError(f"{path}: FMI version {version}: only FMI 2.0 and 3.0 are supported")
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # FMPy raises plain Exceptions for unreadable descriptions
        raise FmuLoadError(f"{path}: cannot read modelDescription.xml ({' '.join(str(exc).split())})") from None
    _interfaces_checked(path, md)
    _default_experiment_checked(path, md)
    model = FmuModel(path, md, fmi=fmi)
    model.missing_binaries = _missing_binaries(path, model)
    if fmi == 3:
        model.clocks = read_clocks(path)
    defined = units_of(md)
    for v in md.modelVariables:
        kind = KINDS.get(v.type, v.type) if fmi == 3 else v.type
        if kind == "Clock":
            continue   # (in model.clocks: the resolver says which interfaces run them)
        # FMPy sizes each FMI 3.0 array (fixed dimensions, start values of structural parameters)
        shape = tuple(v.shape or ()) if fmi == 3 else ()
        unit_name = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        vmin = v.min if v.min is not None else (v.declaredType.min if v.declaredType is not None else None)
        vmax = v.max if v.max is not None else (v.declaredType.max if v.declaredType is not None else None)
        model.variables[v.name] = Variable(
            v.name, int(v.valueReference), kind, v.causality or "local", v.variability or "continuous",
            lookup(unit_name, defined) if kind == "Real" else None,
            _num(vmin, kind), _num(vmax, kind), _start(v, kind, shape), v.description or "", _initial(v),
            v.type, shape)
    return model


