"""The declarations every slave of the project shares, whichever FMI version it is built for: variables
(:class:`Var`) with unit, range and true dependencies, the units as SI base-unit exponents, the declared
ranges, the step-snapping tolerance, and the parameters mirroring a component's parameter dataclass
(read from its fields' metadata, declared with components/params.py).

Bundled inside every FMU beside fmi_base.py (FMI 2.0, pythonfmu) or fmi3_base.py (FMI 3.0, pythonfmu3);
it imports only the standard library, so that neither FMU needs the other's pythonfmu.
"""
from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable
from typing import Any

DBL_MAX = sys.float_info.max
DBL_MIN = sys.float_info.min  # smallest positive normal double: "min = DBL_MIN" encodes "> 0"
INT_MAX = 2**31 - 1

#: Declared ranges (min, max).  ``max = DBL_MAX`` excludes +inf, ``min = -DBL_MAX`` excludes -inf; NaN
#: fails every range check, so FINITE encodes "a finite number".
FINITE = (-DBL_MAX, DBL_MAX)
POSITIVE = (DBL_MIN, DBL_MAX)
NON_NEGATIVE = (0.0, DBL_MAX)
SIGN = (-1.0, 1.0)

#: Units of the FMUs as SI base-unit exponents (FMI 2.0 <BaseUnit>).  "1" is dimensionless.
UNITS: dict[str, dict[str, int]] = {
    "1": {},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
    "N.m": {"kg": 1, "m": 2, "s": -2},
    "kg.m2": {"kg": 1, "m": 2},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "s": {"s": 1},
    "1/s": {"s": -1},
    "1/m": {"m": -1},
    "1/rad": {"rad": -1},
    "s/rad": {"s": 1, "rad": -1},
}

#: Display units (FMI 3.0 <DisplayUnit>) offered beside a unit: name -> factor, value in the display unit =
#: factor * value in the unit.
DISPLAY_UNITS: dict[str, dict[str, float]] = {
    "rad": {"deg": 180.0 / math.pi},
    "rad/s": {"deg/s": 180.0 / math.pi, "rpm": 30.0 / math.pi},
    "rad/s2": {"deg/s2": 180.0 / math.pi},
}

#: Relative tolerance within which a step size equals the previous one, or a time a multiple of it.
#: The snapping rule (inlined in do_step, the controller's step and the FMI 3.0 clock's sample, all on the
#: hot path): a time t within STEP_RTOL * |t| of round(t / h) * h is that multiple, so a master that
#: accumulates time sees the times k h of the direct loop.
STEP_RTOL = 1e-9
#: Relative tolerance within which a step of a slave that takes steps of one length only (``variable_step``
#: false) is its sample period: a host that accumulates time in floating point ends its last step a little
#: short (OMSimulator's last step of G1 is 1.5e-11 s short of 2 ms after 25,000 steps: 7.6e-9 relative).
FIXED_STEP_RTOL = 1e-6


_KINDS = ("Real", "Integer", "Boolean", "String")
#: A declaration's kind -> the Python type of its values.
_PYTHON_TYPE: dict[str, Any] = {"Real": float, "Integer": int, "Boolean": bool, "String": str}
_CAUSALITIES = ("parameter", "input", "output")


def xml_number(v: float | int) -> str:
    """Shortest text that reads back as the same double (pythonfmu's '%.16g' does not always)."""
    if isinstance(v, bool):
        raise TypeError("a boolean is not a number")
    if isinstance(v, int):
        return str(v)
    v = float(v)
    if math.isnan(v):
        return "NaN"
    if math.isinf(v):
        return "INF" if v > 0 else "-INF"
    return repr(v)


class Var:
    """One variable of an FMU: what the model description says about it.

    ``kind`` Real, Integer, Boolean or String; ``causality`` parameter, input or output;
    ``variability`` fixed or tunable for parameters, continuous or discrete for inputs and outputs;
    ``unit`` a key of :data:`UNITS` (Real only); ``range`` (min, max), either may be None;
    ``deps``: for an output, the names of the inputs it depends on directly (direct feedthrough) in a
    step, None meaning all inputs; ``init_deps``: the inputs it depends on in initialization mode
    (default ``deps``; every parameter is added, as a sound over-approximation).

    ``array`` (name, index, description): in an FMI 3.0 FMU this scalar is the element ``index``
    (0-based, one int per dimension) of the Float64 array ``name``, described by ``description``; the
    elements of one array are declared consecutively.  A 2-d array whose elements are given only on and
    above the diagonal is symmetric: element (j, i) is element (i, j).  FMI 2.0 FMUs ignore it.
    """

    __slots__ = ("name", "kind", "causality", "description", "unit", "range", "variability", "start",
                 "deps", "init_deps", "vr", "array")

    def __init__(self, name: str, kind: str, causality: str, description: str, unit: str | None = None,
                 range: tuple[float | None, float | None] = (None, None), variability: str | None = None,
                 start: Any = None, deps: tuple[str, ...] | None = None,
                 init_deps: tuple[str, ...] | None = None,
                 array: tuple[str, tuple[int, ...], str] | None = None) -> None:
        if kind not in _KINDS:
            raise ValueError(f"variable {name}: kind {kind!r}")
        if causality not in _CAUSALITIES:
            raise ValueError(f"variable {name}: causality {causality!r}")
        if unit is not None and (kind != "Real" or unit not in UNITS):
            raise ValueError(f"variable {name}: unit {unit!r} (only Real variables have units, from UNITS)")
        if variability is None:
            variability = "fixed" if causality == "parameter" else ("continuous" if kind == "Real" else "discrete")
        self.name, self.kind, self.causality, self.description = name, kind, causality, description
        self.unit, self.range, self.variability, self.start = unit, range, variability, start
        self.deps = deps
        self.init_deps = deps if init_deps is None else init_deps
        self.vr = -1
        self.array = array



def parameters_of(defaults: Any, expanded: tuple[str, ...] = ()) -> list[Var]:
    """FMU parameters mirroring the fields of a component's parameter dataclass instance ``defaults``:
    same names, start values from the component's defaults, the kind from the default's type, and the
    rest from each field's metadata (components/params.py): ``unit``, ``doc`` (the description),
    ``tunable`` and ``check``, whose ``bounds`` are the declared range (min, max).

    Every field must carry that metadata, or be listed in ``expanded`` (the caller declares it itself,
    e.g. a tuple as several scalars), so that a new component parameter cannot be forgotten silently.
    """
    out: list[Var] = []
    owner = type(defaults).__name__
    fields = dataclasses.fields(defaults)
    unknown = [n for n in expanded if n not in {f.name for f in fields}]
    bare = [f.name for f in fields if f.name not in expanded and "check" not in f.metadata]
    if unknown or bare:
        raise ValueError(f"{owner}: no parameter metadata for {bare}, unknown expanded fields {unknown}")
    for f in fields:
        name, meta = f.name, f.metadata
        if name in expanded:
            continue
        value = getattr(defaults, name)
        variability = "tunable" if meta["tunable"] else "fixed"
        doc = meta["doc"]
        bounds = tuple(meta["check"].bounds)
        if isinstance(value, bool):
            out.append(Var(name, "Boolean", "parameter", doc, variability=variability, start=value))
        elif isinstance(value, int):
            out.append(Var(name, "Integer", "parameter", doc, range=bounds, variability=variability, start=value))
        elif isinstance(value, float):
            out.append(Var(name, "Real", "parameter", doc, unit=meta["unit"], range=bounds,
                           variability=variability, start=value))
        elif isinstance(value, str):
            out.append(Var(name, "String", "parameter", doc, variability=variability, start=value))
        else:
            raise TypeError(f"{owner}.{name}: no FMU type for {value!r}")
    return out


def exception_cause(exc: BaseException) -> str:
    """One line: the exception's type and message."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else '(no message)'}"


class SlaveCore:
    """What the FMI 2.0 and FMI 3.0 slave bases (fmi_base.WmrSlave, fmi3_base.WmrSlave) do alike, free of
    pythonfmu: the slave's state and its declarations (the values by declaration position, the parameters,
    the inputs and outputs as slices), the parameter values, the model description's version, the life
    cycle through initialization mode (outputs recomputed from the current parameters and inputs when read
    there), refusing a step after a failed one, snapping or adopting the step size, applying tunable
    parameters, and saving and restoring the FMU state with every internal state.  A base sets
    ``_DISCARD`` and ``_FATAL`` to its pythonfmu's Discard and Fatal statuses, ``_ACCESS`` and ``_SETS`` to
    the names of its get and set methods, implements :meth:`_reads_output`, and may extend
    :meth:`_after_restore`."""

    _DISCARD: Any = None
    _FATAL: Any = None
    #: The names of the base's get and set methods: in initialization mode they are replaced by instance
    #: attributes that keep the outputs current (no cost to the stepping paths, which never see them).
    _ACCESS: tuple[str, ...] = ()
    _SETS: tuple[str, ...] = ()
    #: Whether it takes communication steps of any length (canHandleVariableCommunicationStepSize).  A
    #: sampled-data block (the sensor chain, the controller) samples at the end of every step: its sample
    #: period is the step, so a step of another length changes what it computes.  Such a slave declares
    #: false and refuses (Discard) a step whose length differs from its first one.
    variable_step: bool = True

    # Annotations for the type checker only (no class attributes): what the pythonfmu slave class
    # (Fmi2Slave, Fmi3Slave) provides, and what the base's ``_index`` sets (kind or type -> value references).
    modelName: str
    instance_name: str
    log: Callable[..., None]                        # log(message, status)
    _settable_before: dict[str, frozenset[int]]     # settable before initialization mode ends
    _settable_running: dict[str, frozenset[int]]    # settable after it (tunable parameters, inputs)
    _settable: dict[str, frozenset[int]]            # the one of the two in force
    _tunable: frozenset[int]                        # the tunable parameters
    _watch: frozenset[int]                          # what, when set, marks the tunable parameters dirty

    # ------------------------------------------------------------------ state and declarations
    def _init_state(self) -> None:
        """The state of a slave before its variables are declared (the base's ``__init__`` calls it)."""
        self._vals: list[Any] = []
        self._decl: list[Var] = []
        self._by_name: dict[str, Var] = {}
        self._comp: Any = None          # the component object (Plant, Sensor, Controller)
        self._mode = "instantiated"     # -> "init" -> "run"
        self._failed = ""               # cause of the failed step; steps are refused after one
        self._dirty = False             # a tunable parameter was set since the last step
        self._stale = False             # initialization mode: outputs not recomputed since a set
        self._h = math.nan              # the step size in use [s]
        self._t0 = 0.0                  # start time [s] (setup_experiment)

    def _add(self, var: Var) -> int:
        """Declare ``var``: its position in ``_vals`` (``var.vr``, returned) holds its start value."""
        if var.name in self._by_name:
            raise ValueError(f"duplicate variable {var.name}")
        var.vr = len(self._vals)
        self._vals.append(var.start)
        self._decl.append(var)
        self._by_name[var.name] = var
        return var.vr

    def _group_declarations(self) -> None:
        """The parameters, inputs and outputs of the declarations; the inputs and the outputs each a slice
        of ``_vals`` (``_in0:_in1``, ``_out0:_out1``)."""
        decl = self._decl
        self._params = [v for v in decl if v.causality == "parameter"]
        self._inputs = [v for v in decl if v.causality == "input"]
        self._outputs = [v for v in decl if v.causality == "output"]
        for group in (self._inputs, self._outputs):  # contiguous, so that slices read and write them
            vrs = [v.vr for v in group]
            if vrs and vrs != list(range(vrs[0], vrs[0] + len(vrs))):
                raise ValueError(f"{type(self).__name__}: declare the inputs, and the outputs, consecutively")
        self._in0 = self._inputs[0].vr if self._inputs else 0
        self._in1 = self._in0 + len(self._inputs)
        self._out0 = self._outputs[0].vr if self._outputs else 0
        self._out1 = self._out0 + len(self._outputs)

    def parameter_values(self) -> dict[str, Any]:
        """The current parameter values by name (scalar names, the types of the declaration)."""
        vals = self._vals
        return {v.name: _PYTHON_TYPE[v.kind](vals[v.vr]) for v in self._params}

    # ------------------------------------------------------------------ to be implemented by a slave
    def _build(self) -> None:
        """Build the component from the current parameter and input values; write the initial outputs."""
        raise NotImplementedError

    def _step(self, t: float, h: float) -> None:
        """One communication step from t to t + h [s]: read inputs, write outputs in ``self._vals``."""
        raise NotImplementedError

    def _retune(self) -> None:
        """Apply tunable parameters set since the last step (default: none are declared)."""

    # ------------------------------------------------------------------ model description
    def _describe(self, root: Any, co_simulation: Any) -> None:
        """What both versions' model descriptions say alike: the version (the source version the FMU's
        package name ends with, "development" from the tree) and whether the step length may vary."""
        pkg = __name__.rpartition(".")[0]
        root.set("version", "development" if pkg.startswith("wmr_cosim") else pkg.rpartition("_")[2])
        co_simulation.set("canHandleVariableCommunicationStepSize", "true" if self.variable_step else "false")

    # ------------------------------------------------------------------ life cycle
    def enter_initialization_mode(self) -> None:
        self._mode = "init"
        self._stale = True
        self._install_init_paths()

    def exit_initialization_mode(self) -> None:
        self._remove_init_paths()
        self._build_logged()
        self._mode = "run"
        self._settable = self._settable_running
        self._watch = self._tunable
        self._dirty = False

    def _build_logged(self) -> None:
        """:meth:`_build`, logging the one-line cause of a failure before re-raising it (-> Fatal)."""
        try:
            self._build()
        except Exception as exc:
            self.log(f"{self.modelName} instance {self.instance_name}: initialisation failed: "
                     f"{exception_cause(exc)}", self._FATAL)
            raise
        self._stale = False

    def _install_init_paths(self) -> None:
        cls = type(self)
        for name in self._ACCESS:
            setattr(self, name, self._init_getter(getattr(cls, name).__get__(self)))
        for name in self._SETS:
            setattr(self, name, self._init_setter(getattr(cls, name).__get__(self)))

    def _remove_init_paths(self) -> None:
        for name in self._ACCESS + self._SETS:
            self.__dict__.pop(name, None)

    def _reads_output(self, vrs: list[int]) -> bool:
        """Whether the value references ``vrs`` (of the base's FMI version) name an output."""
        raise NotImplementedError

    def _init_getter(self, fast: Any) -> Any:
        def get(vrs: list[int]) -> list[Any]:
            if self._stale and self._reads_output(vrs):
                self._build_logged()
            return fast(vrs)
        return get

    def _init_setter(self, fast: Any) -> Any:
        def set_(vrs: list[int], values: list[Any]) -> None:
            fast(vrs, values)
            self._stale = True
        return set_

    # ------------------------------------------------------------------ stepping
    def _before_step(self, current_time: float, h: float) -> float | None:
        """Refuse a step after a failed one; snap or adopt a new step size; apply tunable parameters."""
        if self._failed:
            self.log(f"{self.modelName} instance {self.instance_name}: step at t = {current_time!r} s refused: "
                     f"an earlier step failed ({self._failed})", self._DISCARD)
            return None
        if h != self._h:
            if abs(h - self._h) <= STEP_RTOL * self._h:
                h = self._h
            elif not self.variable_step and not math.isnan(self._h):   # (the first step sets the period)
                if abs(h - self._h) > FIXED_STEP_RTOL * self._h:
                    self.log(f"{self.modelName} instance {self.instance_name}: step of h = {h!r} s at t = "
                             f"{current_time!r} s refused: it samples every {self._h!r} s (its first step) and "
                             "declares canHandleVariableCommunicationStepSize = false", self._DISCARD)
                    return None
                h = self._h
            elif h > 0.0 and math.isfinite(h):
                self._h = h
            else:
                raise ValueError(f"step size h = {h!r} s: must be finite and > 0")
        if self._dirty:
            self._dirty = False
            self._retune()
        return h

    def terminate(self) -> None:
        pass

    # ------------------------------------------------------------------ FMU state (every internal state too)
    def _get_fmu_state(self) -> dict[str, Any]:
        return {"vals": list(self._vals), "comp": None if self._comp is None else self._comp.get_state(),
                "mode": self._mode, "failed": self._failed, "dirty": self._dirty, "stale": self._stale,
                "h": None if math.isnan(self._h) else self._h, "t0": self._t0}

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        vals = list(state["vals"])
        if len(vals) != len(self._vals):
            raise ValueError(f"{self.modelName}: FMU state of {len(vals)} variables, expected {len(self._vals)}")
        old = self._vals
        same_params = self._comp is not None and all(old[v.vr] == vals[v.vr] for v in self._params)
        self._vals = vals
        self._t0 = float(state["t0"])
        if state["comp"] is not None:
            if not same_params:
                self._build()  # the component of the saved parameters; its state is then overwritten
            self._comp.set_state(state["comp"])
            self._vals = list(state["vals"])  # _build wrote initial outputs: restore the saved ones
        else:
            self._comp = None
        self._failed = state["failed"]
        self._stale = bool(state["stale"])
        self._h = math.nan if state["h"] is None else float(state["h"])
        self._mode = state["mode"]
        self._remove_init_paths()
        if self._mode == "init":
            self._install_init_paths()
        running = self._mode == "run"
        self._settable = self._settable_running if running else self._settable_before
        self._watch = self._tunable if running else frozenset()
        # re-apply the tunable parameters of the restored values at the next step (idempotent)
        self._dirty = bool(state["dirty"]) or (running and bool(self._tunable))
        self._after_restore()

    def _after_restore(self) -> None:
        """Called at the end of :meth:`_set_fmu_state`."""
