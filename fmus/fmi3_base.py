"""The FMI 3.0 side of the project's slaves (pythonfmu3): the same declarations, components and slave
classes as the FMI 2.0 FMUs, exposed through FMI 3.0.

fmus/build.py builds an FMI 3.0 FMU from the same slave script as the FMI 2.0 one: the script's import
of ``fmi_base`` is rewritten to this module, whose :class:`WmrSlave` offers the slave script the same
interface (``declare``, ``self._vals`` indexed by declaration position, ``_in0``/``_out0`` slices,
``parameter_values``, ``_build``/``_step``/``_retune``), so a model's variables and equations have one
source.  Bundled inside the FMU, this module imports only pythonfmu3, the standard library and the
bundled fmi_decl.py.

What FMI 3.0 adds, used here:

* Float64 variables with units and display units (degrees beside radians, rpm beside rad/s);
  Int32 for the integers; choices stay String parameters (same values as in FMI 2.0).
* Arrays: scalars declared with ``Var.array`` become one Float64 array (the controller's W_init, W
  (3) and the symmetric 3 x 3 P_init, P).  Setting a symmetric array with P[i, j] != P[j, i] is refused.
* The independent variable ``time`` (value reference 0; FMI 3.0 requires one); every other variable
  follows in declaration order, an array taking one value reference.
* ModelStructure: every output with its true direct-feedthrough dependencies (value references of
  inputs), and as InitialUnknown with its initialisation dependencies (inputs and parameters), except
  the outputs of a slave with a sample clock: clocked variables are no InitialUnknowns in FMI 3.0.
* State: fmi3GetFMUState/SetFMUState and serialisation (JSON) save every variable and the component's
  whole internal state.

* A sample clock (slaves that set ``sample_clock``: the sensor chain and the controller): one periodic input
  Clock (``intervalVariability="constant"``), its sampled inputs and outputs clocked by it, and
  ``hasEventMode="true"``.  Instantiated with eventModeUsed = false, the slave samples at the end of every
  communication step as the FMI 2.0 slave does (the clock is not used).  With eventModeUsed = true it
  samples only at the clock's ticks: the importer sets the clock (fmi3SetClock) in Event Mode, and the
  sample is taken at fmi3UpdateDiscreteStates, or at the first read of an output before it; between ticks
  fmi3DoStep only advances time (the outputs hold), with steps of any length that do not pass the next tick.
  pythonfmu3 has no clock calls: our loader (wmr_pyloader3.c) tells the slave eventModeUsed by a set of the
  Boolean value reference :data:`EVENT_MODE_VR` right after instantiation (and after fmi3Reset), routes
  fmi3SetClock/GetClock through fmi3SetBoolean/GetBoolean of the clock's value reference, and turns the
  result of :meth:`WmrSlave.update_discrete_states` into fmi3Error when the sample failed.

Failure rules (as in FMI 2.0): a failed step is logged with its cause and returned as fmi3Discard; later
steps are refused the same way.  Initialisation and refused calls fail as fmi3Fatal (pythonfmu3 turns
every exception into fmi3Fatal), after the one-line cause is logged.
"""
from __future__ import annotations

import math
from operator import itemgetter
from typing import Any, NoReturn
from xml.etree.ElementTree import Element, SubElement

from pythonfmu3 import DefaultExperiment, Fmi3Slave
from pythonfmu3.enums import Fmi3Status
from pythonfmu3.fmi3slave import Fmi3StepResult

from .fmi_decl import (SlaveCore, DBL_MAX, DBL_MIN, DISPLAY_UNITS, FINITE, INT_MAX, NON_NEGATIVE, POSITIVE, SIGN,  # noqa: F401
                       FIXED_STEP_RTOL, STEP_RTOL, UNITS, Var, exception_cause, xml_number, parameters_of)

#: FMI 2.0 kind of a declaration -> FMI 3.0 type.
TYPE3 = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}
_CONV = {"Float64": float, "Int32": int, "Boolean": bool, "String": str}
#: What do_step returns: pythonfmu3 reads the attributes status and terminateSimulation of the result; a
#: bool lacks them, and each failed attribute lookup costs an exception inside pythonfmu3 (measured: the
#: plant's step took 8 us longer with a bool).
_OK = Fmi3StepResult(status=Fmi3Status.ok)
_DISCARD = Fmi3StepResult(status=Fmi3Status.discard)
#: The value reference our loader (wmr_pyloader3.c, WMR_EVENT_MODE_VR) sets true through fmi3SetBoolean when
#: the instance was instantiated with eventModeUsed = true.  No variable has it; the model description
#: does not name it.  (pythonfmu3 passes value references to Python as C ints: the largest one is kept.)
EVENT_MODE_VR = 2**31 - 1


class _Event:
    """What update_discrete_states returns; pythonfmu3 reads these attributes into fmi3UpdateDiscreteStates'
    outputs.  ``nominalContinuousStatesChanged`` (meaningless in co-simulation) carries to our loader that the
    sample failed: the loader then returns fmi3Error and reports false to the importer."""

    __slots__ = ("discreteStatesNeedUpdate", "terminateSimulation", "nominalContinuousStatesChanged",
                 "valuesOfContinuousStatesChanged", "nextEventTimeDefined", "nextEventTime")

    def __init__(self, failed: bool) -> None:
        self.discreteStatesNeedUpdate = False
        self.terminateSimulation = False
        self.nominalContinuousStatesChanged = failed
        self.valuesOfContinuousStatesChanged = False
        self.nextEventTimeDefined = False
        self.nextEventTime = 0.0


_EVENT_OK = _Event(False)
_EVENT_FAILED = _Event(True)


class Var3:
    """One FMI 3.0 variable: a scalar declaration, or an array over several (``slots``: the positions in
    ``_vals`` of its elements in row-major order; a symmetric array lists a slot twice)."""

    __slots__ = ("name", "type", "vr", "decl", "slots", "shape", "sym", "description", "deps", "init_deps",
                 "range")

    def __init__(self, name: str, type_: str, vr: int, decl: list[Var], slots: list[int], shape: tuple[int, ...],
                 sym: bool, description: str) -> None:
        self.name, self.type, self.vr, self.decl, self.slots = name, type_, vr, decl, slots
        self.shape, self.sym, self.description = shape, sym, description
        self.deps = _union([v.deps for v in decl])
        self.init_deps = _union([v.init_deps for v in decl])
        # the widest range of the elements; an end that one element leaves open (None) stays open
        los = [v.range[0] for v in decl if v.range[0] is not None]
        his = [v.range[1] for v in decl if v.range[1] is not None]
        self.range = (min(los) if len(los) == len(decl) else None, max(his) if len(his) == len(decl) else None)

    @property
    def causality(self) -> str:
        return self.decl[0].causality

    @property
    def variability(self) -> str:
        return self.decl[0].variability

    @property
    def unit(self) -> str | None:
        return self.decl[0].unit


def _union(groups: list[tuple[str, ...] | None]) -> tuple[str, ...] | None:
    """The names in ``groups`` (dependencies of an array's elements), each once in order of first appearance;
    None (every input) if the first element's are None."""
    if groups[0] is None:
        return None
    out: dict[str, None] = {}
    for names in groups:
        # the elements of an array are declared alike (slave_controller.py): all with dependencies, or none
        assert names is not None
        out.update(dict.fromkeys(names))
    return tuple(out)


def _group(decl: list[Var], first_vr: int) -> list[Var3]:
    """The FMI 3.0 variables of the scalar declarations (arrays from consecutive ``Var.array`` hints)."""
    out: list[Var3] = []
    i = 0
    while i < len(decl):
        v = decl[i]
        vr = first_vr + len(out)
        if v.array is None:
            out.append(Var3(v.name, TYPE3[v.kind], vr, [v], [v.vr], (), False, v.description))
            i += 1
            continue
        name, _, doc = v.array
        members = []
        index: dict[tuple[int, ...], Var] = {}   # element index -> its declaration
        while i < len(decl):
            hint = decl[i].array
            if hint is None or hint[0] != name:
                break
            members.append(decl[i])
            index[hint[1]] = decl[i]
            i += 1
        if any(m.kind != "Real" or (m.causality, m.variability, m.unit) != (v.causality, v.variability, v.unit)
               for m in members):
            raise ValueError(f"array {name}: elements must be Real of one causality, variability and unit")
        ndim = len(v.array[1])
        shape = tuple(max(k[d] for k in index) + 1 for d in range(ndim))
        sym = ndim == 2 and shape[0] == shape[1] and all(a <= b for a, b in index) and len(index) < shape[0] * shape[1]
        slots = []
        for pos in _positions(shape):
            m = index.get(pos) or (index.get(pos[::-1]) if sym else None)
            if m is None:
                raise ValueError(f"array {name}: no element {pos}")
            slots.append(m.vr)
        out.append(Var3(name, "Float64", vr, members, slots, shape, sym, doc))
    return out


def _positions(shape: tuple[int, ...]) -> list[tuple[int, ...]]:
    out: list[tuple[int, ...]] = [()]
    for n in shape:
        out = [p + (k,) for p in out for k in range(n)]
    return out


class WmrSlave(SlaveCore, Fmi3Slave):
    """Base of the project's FMI 3.0 slaves; the slave scripts' interface is that of the FMI 2.0 base."""

    default_experiment = DefaultExperiment(start_time=0.0, stop_time=50.0, step_size=0.002)

    _DISCARD = Fmi3Status.discard   # the status of a refused or failed step (see SlaveCore)
    _FATAL = Fmi3Status.fatal
    _ACCESS = ("get_float64", "get_int32", "get_boolean", "get_string")
    _SETS = ("set_float64", "set_int32", "set_boolean", "set_string")

    #: The sample clock of a sampled-data slave: (name, interval [s], description), or None (no clock).
    sample_clock: tuple[str, float, str] | None = None

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.author = "wmr-cosim"
        self.default_experiment = type(self).default_experiment
        self.description = getattr(type(self), "description", None)  # (pythonfmu3's __init__ set None)
        self._init_state()
        self._clock_vr = -1                  # the clock's value reference (-1: no clock)
        self._specials: frozenset[int] = frozenset({EVENT_MODE_VR})   # Boolean sets that are not variables
        self._event_mode = False             # instantiated with eventModeUsed = true (our loader says so)
        self._tick = False                   # the clock is active: a sample is due
        self._t_sample = math.nan            # time of the last sample [s] (event mode)
        self._samples = 0                    # samples taken since initialisation (event mode)

    # ------------------------------------------------------------------ declaration
    def declare(self, variables: list[Var]) -> None:
        """Register the variables: position in ``_vals`` = declaration order (as in FMI 2.0); the FMI 3.0
        value references are 0 for time, then one per variable or array."""
        for var in variables:
            self._add(var)
        self._tslot = len(self._vals)
        self._vals.append(self._t0)        # the value of the independent variable time [s]
        time = Var("time", "Real", "input", "simulation time", unit="s")
        time.vr = self._tslot
        tvar = Var3("time", "Float64", 0, [time], [self._tslot], (), False, "simulation time")
        self._v3 = [tvar] + _group(self._decl, 1)
        self._v3_by_name = {v.name: v for v in self._v3}
        if self.sample_clock is not None:   # the clock: the value reference after every variable's
            self._clock_vr = len(self._v3)
            self._specials = frozenset({EVENT_MODE_VR, self._clock_vr})
        self._index()

    def _index(self) -> None:
        self._group_declarations()
        v3 = self._v3
        self._types = {t: frozenset(v.vr for v in v3 if v.type == t) for t in _CONV}
        params = {v.vr for v in v3 if v.causality == "parameter" and v.name != "time"}
        inputs = {v.vr for v in v3 if v.causality == "input" and v.name != "time"}
        tunable = {v.vr for v in v3 if v.causality == "parameter" and v.variability == "tunable"}
        self._settable_before = {t: frozenset(vs & (params | inputs)) for t, vs in self._types.items()}
        self._settable_running = {t: frozenset(vs & (tunable | inputs)) for t, vs in self._types.items()}
        self._tunable = frozenset(tunable)
        self._settable = self._settable_before
        self._watch: frozenset[int] = frozenset()
        self._input_vrs = frozenset(inputs)
        self._gets: dict[tuple[str | int, ...], Any] = {}   # (type, *value references) -> getter
        self._get_key: list[int] = [-1]
        self._get_items: Any = None
        self._int_key: list[int] = [-1]
        self._int_items: Any = None
        self._bool_key: list[int] = [-1]
        self._bool_items: Any = None
        self._set_key: list[int] = [-1]
        self._set_a = self._set_b = 0

    def vr(self, name: str) -> int:
        """FMI 3.0 value reference of a variable or array."""
        return self._v3_by_name[name].vr

    # ------------------------------------------------------------------ model description
    def to_xml(self, model_options: dict[str, str] = dict()) -> Element:  # noqa: B006 (pythonfmu3's signature)
        root = super().to_xml(model_options)
        cs = root.find("CoSimulation")
        self._describe(root, cs)
        cs.set("canGetAndSetFMUState", "true")
        cs.set("canSerializeFMUState", "true")
        for tag in ("UnitDefinitions", "ModelVariables", "ModelStructure"):
            for node in root.findall(tag):
                root.remove(node)
        used = sorted({v.unit for v in self._v3 if v.unit is not None})
        units = Element("UnitDefinitions")
        for name in used:
            unit = SubElement(units, "Unit", {"name": name})
            SubElement(unit, "BaseUnit", {k: str(e) for k, e in UNITS[name].items()})
            for dname, factor in DISPLAY_UNITS.get(name, {}).items():
                SubElement(unit, "DisplayUnit", {"name": dname, "factor": xml_number(factor)})
        root.insert(list(root).index(cs) + 1, units)
        variables = SubElement(root, "ModelVariables")
        for v in self._v3:
            variables.append(self._variable_xml(v))
        if self.sample_clock is not None:
            name, interval, doc = self.sample_clock
            cs.set("hasEventMode", "true")
            SubElement(variables, "Clock", {"name": name, "valueReference": str(self._clock_vr), "description": doc,
                                            "causality": "input", "variability": "discrete",
                                            "intervalVariability": "constant", "intervalDecimal": xml_number(interval)})
        structure = SubElement(root, "ModelStructure")
        group_of = {d.name: v for v in self._v3 for d in v.decl}
        inputs = [v for v in self._v3 if v.causality == "input" and v.name != "time"]
        params = [v.vr for v in self._v3 if v.causality == "parameter"]
        outputs = [v for v in self._v3 if v.causality == "output"]

        def refs(names: tuple[str, ...] | None) -> list[int]:
            if names is None:
                return [v.vr for v in inputs]
            return sorted({group_of[n].vr for n in names})

        for v in outputs:
            SubElement(structure, "Output", {"valueReference": str(v.vr),
                                             "dependencies": " ".join(map(str, refs(v.deps)))})
        for v in outputs if self.sample_clock is None else ():   # (FMI 3.0: clocked variables are no InitialUnknowns)
            deps = sorted(set(params) | set(refs(v.init_deps)))
            SubElement(structure, "InitialUnknown", {"valueReference": str(v.vr),
                                                     "dependencies": " ".join(map(str, deps))})
        return root

    def _variable_xml(self, v: Var3) -> Element:
        a: dict[str, str] = {"name": v.name, "valueReference": str(v.vr), "description": v.description}
        if v.name == "time":
            a.update(causality="independent", variability="continuous", unit="s")
            return Element("Float64", a)
        a["causality"] = v.causality
        a["variability"] = v.variability
        if self.sample_clock is not None and v.causality in ("input", "output"):
            a["variability"] = "discrete"   # sampled at the clock's ticks
            a["clocks"] = str(self._clock_vr)
        if v.causality == "parameter":
            a["initial"] = "exact"
        if v.unit is not None:
            a["unit"] = v.unit
        lo, hi = v.range
        if v.type in ("Float64", "Int32"):
            num = xml_number if v.type == "Float64" else (lambda x: str(int(x)))
            if lo is not None:
                a["min"] = num(lo)
            if hi is not None:
                a["max"] = num(hi)
        starts = [self._vals[s] for s in v.slots]
        has_start = v.causality != "output" and all(x is not None for x in starts)
        if has_start and v.type == "Float64":
            a["start"] = " ".join(xml_number(float(x)) for x in starts)
        elif has_start and v.type == "Int32":
            a["start"] = str(int(starts[0]))
        elif has_start and v.type == "Boolean":
            a["start"] = "true" if starts[0] else "false"
        node = Element(v.type, a)
        if has_start and v.type == "String":
            SubElement(node, "Start", {"value": str(starts[0])})
        for n in v.shape:
            SubElement(node, "Dimension", {"start": str(n)})
        return node

    # ------------------------------------------------------------------ value access
    def _slots_of(self, vrs: list[int], type_: str) -> list[int]:
        if not self._types[type_].issuperset(vrs):
            self._wrong_type(vrs, type_)
        v3 = self._v3
        out: list[int] = []
        for i in vrs:
            out += v3[i].slots
        return out

    def _getter(self, vrs: list[int], type_: str) -> Any:
        key: tuple[str | int, ...] = (type_, *vrs)
        g = self._gets.get(key)
        if g is None:
            slots = self._slots_of(vrs, type_)
            conv = _CONV[type_]
            if type_ == "Float64":
                items = itemgetter(*slots) if len(slots) > 1 else (lambda v, i=slots[0]: (v[i],))
                g = (lambda vals: list(items(vals)))
            else:
                g = (lambda vals: [conv(vals[i]) for i in slots])
            self._gets[key] = g
        return g

    def get_float64(self, vrs: list[int]) -> list[float]:
        # fast path: a master asks for the same value references every step
        if vrs == self._get_key:
            return list(self._get_items(self._vals))
        g = self._getter(vrs, "Float64")
        self._get_key, self._get_items = list(vrs), self._items(vrs, "Float64")
        return g(self._vals)

    def get_int32(self, vrs: list[int]) -> list[int]:
        if vrs == self._int_key:
            return [int(x) for x in self._int_items(self._vals)]
        self._int_key, self._int_items = list(vrs), self._items(vrs, "Int32")
        return self._getter(vrs, "Int32")(self._vals)

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        if vrs == self._bool_key:
            return [bool(x) for x in self._bool_items(self._vals)]
        if self._clock_vr >= 0 and self._clock_vr in vrs:   # fmi3GetClock (our loader: as fmi3GetBoolean)
            return [self._get_clock(i) for i in vrs]
        self._bool_key, self._bool_items = list(vrs), self._items(vrs, "Boolean")
        return self._getter(vrs, "Boolean")(self._vals)

    def _items(self, vrs: list[int], type_: str) -> Any:
        slots = self._slots_of(vrs, type_)
        return itemgetter(*slots) if len(slots) > 1 else (lambda v, i=slots[0]: (v[i],))

    def get_string(self, vrs: list[int]) -> list[str]:
        return self._getter(vrs, "String")(self._vals)

    def get_int64(self, vrs: list[int]) -> list[int]:
        self._wrong_type(vrs, "Int64")

    def get_uint64(self, vrs: list[int]) -> list[int]:
        self._wrong_type(vrs, "UInt64")

    def set_float64(self, vrs: list[int], values: list[float]) -> None:
        # fast path: the same input value references as last time (inputs: settable in every mode, unwatched)
        if vrs == self._set_key:
            self._vals[self._set_a:self._set_b] = values
            return
        self._set(vrs, values, "Float64")

    def set_int32(self, vrs: list[int], values: list[int]) -> None:
        self._set(vrs, values, "Int32")

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        if not self._specials.isdisjoint(vrs):   # fmi3SetClock, or our loader's eventModeUsed
            self._set_clock(vrs, values)
            return
        self._set(vrs, values, "Boolean")

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._set(vrs, values, "String")

    def set_int64(self, vrs: list[int], values: list[int]) -> None:
        self._wrong_type(vrs, "Int64")

    def set_uint64(self, vrs: list[int], values: list[int]) -> None:
        self._wrong_type(vrs, "UInt64")

    def _set(self, vrs: list[int], values: list[Any], type_: str) -> None:
        if not self._settable[type_].issuperset(vrs):
            self._refuse_set(vrs, type_)
        conv = _CONV[type_]
        v3 = self._v3
        vals = self._vals
        k = 0
        for i in vrs:
            var = v3[i]
            n = len(var.slots)
            chunk = values[k:k + n]
            k += n
            if len(chunk) != n:
                self._fatal(f"set{type_} of {var.name}: {len(chunk)} values for {n} elements")
            if var.sym:
                m = var.shape[0]
                bad = [(a, b) for a in range(m) for b in range(a + 1, m) if chunk[a * m + b] != chunk[b * m + a]]
                if bad:
                    a, b = bad[0]
                    self._fatal(f"set{type_} refused for {var.name}: not symmetric ({var.name}[{a + 1},{b + 1}] = "
                                f"{chunk[a * m + b]!r}, {var.name}[{b + 1},{a + 1}] = {chunk[b * m + a]!r})")
            for s, x in zip(var.slots, chunk):
                vals[s] = conv(x)
        if self._watch and not self._watch.isdisjoint(vrs):
            self._dirty = True
        elif type_ == "Float64" and self._input_vrs.issuperset(vrs) and self._mode == "run":
            slots = self._slots_of(vrs, type_)
            if slots == list(range(slots[0], slots[0] + len(slots))):  # contiguous inputs: one slice
                self._set_key = list(vrs)
                self._set_a, self._set_b = slots[0], slots[0] + len(slots)

    def _name_of(self, vr: int) -> str:
        return self._v3[vr].name if 0 <= vr < len(self._v3) else f"<unknown value reference {vr}>"

    def _fatal(self, what: str) -> NoReturn:
        msg = f"{self.modelName} instance {self.instance_name}: {what}"
        self.log(msg, Fmi3Status.fatal)
        raise ValueError(msg)

    def _wrong_type(self, vrs: list[int], type_: str) -> NoReturn:
        bad = [self._name_of(i) for i in vrs if i not in self._types.get(type_, ())]
        msg = f"{self.modelName} instance {self.instance_name}: get/set{type_} on variables that are not {type_}: {', '.join(bad)}"
        self.log(msg, Fmi3Status.fatal)
        raise TypeError(msg)

    def _refuse_set(self, vrs: list[int], type_: str) -> NoReturn:
        bad = []
        for i in vrs:
            if i not in self._settable[type_]:
                name = self._name_of(i)
                if i == 0:
                    why = "the independent variable time"
                elif i in self._types[type_]:
                    var = self._v3[i]
                    why = (f"output {name}" if var.causality == "output" else
                           f"{var.variability} parameter {name} after initialisation")
                else:
                    why = f"{name} (not {type_})"
                bad.append(why)
        self._fatal(f"set{type_} refused for {', '.join(bad)}")

    # ------------------------------------------------------------------ life cycle
    def setup_experiment(self, start_time: float = 0.0, *args: Any) -> None:
        self._t0 = float(start_time)
        self._vals[self._tslot] = self._t0

    def _reads_output(self, vrs: list[int]) -> bool:
        v3, out0, out1 = self._v3, self._out0, self._out1
        return any(out0 <= s < out1 for i in vrs if 0 <= i < len(v3) for s in v3[i].slots)

    def do_step(self, current_time: float, step_size: float) -> Fmi3StepResult:
        if self._event_mode and self._clock_vr >= 0:
            return self._event_step(current_time, step_size)
        h: float | None = step_size   # None: the step refused (_before_step)
        try:
            if h != self._h or self._dirty or self._failed:  # the rare cases, out of the hot path
                h = self._before_step(current_time, step_size)
                if h is None:
                    return _DISCARD
            t = current_time
            tn = round(t / h) * h
            if tn != t and abs(tn - t) <= STEP_RTOL * abs(t):
                t = tn
            self._step(t, h)
            self._vals[self._tslot] = current_time + step_size
            return _OK
        except Exception as exc:
            self._failed = exception_cause(exc)
            self.log(f"{self.modelName} instance {self.instance_name}: step from t = {current_time!r} s "
                     f"over h = {step_size!r} s failed: {self._failed}", Fmi3Status.discard)
            return _DISCARD

    def _after_restore(self) -> None:
        self._get_key = [-1]
        self._set_key = [-1]
        self._remove_tick_paths()
        if self._tick:
            self._install_tick_paths()

    def _get_fmu_state(self) -> dict[str, Any]:
        state = super()._get_fmu_state()
        state["clock"] = {"tick": self._tick, "t_sample": None if math.isnan(self._t_sample) else self._t_sample,
                          "samples": self._samples}
        return state

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        clock = state.get("clock") or {}
        self._tick = bool(clock.get("tick", False))
        t = clock.get("t_sample")
        self._t_sample = math.nan if t is None else float(t)
        self._samples = int(clock.get("samples", 0))
        super()._set_fmu_state(state)

    # ------------------------------------------------------------------ the sample clock (event mode)
    def exit_initialization_mode(self) -> None:
        super().exit_initialization_mode()
        self._t_sample = self._vals[self._tslot]   # initialisation is the sample at the start time
        self._samples = 0
        self._tick = False

    def _clock_name(self) -> str:
        return self.sample_clock[0] if self.sample_clock is not None else "(no clock)"

    def _get_clock(self, vr: int) -> bool:
        if vr != self._clock_vr:
            self._fatal(f"fmi3GetClock of {self._name_of(vr)}: not a clock (the clock is {self._clock_name()}, "
                        f"value reference {self._clock_vr})")
        return self._tick

    def _set_clock(self, vrs: list[int], values: list[bool]) -> None:
        """fmi3SetClock of the sample clock (active: a sample is due), or our loader's eventModeUsed."""
        if len(values) != len(vrs):
            self._fatal(f"fmi3SetClock: {len(values)} values for {len(vrs)} value references")
        for vr, on in zip(vrs, values):
            if vr == EVENT_MODE_VR:
                self._event_mode = bool(on)
                continue
            name = self._clock_name()
            if vr != self._clock_vr:
                self._fatal(f"fmi3SetClock of {self._name_of(vr)}: not a clock (the clock is {name}, value "
                            f"reference {self._clock_vr})")
            if not self._event_mode:
                self._fatal(f"fmi3SetClock of {name} refused: the instance was instantiated with eventModeUsed = "
                            "false (it samples at the end of every communication step)")
            if self._mode != "run":
                self._fatal(f"fmi3SetClock of {name} refused in initialization mode (the clock ticks from "
                            "the Event Mode after fmi3ExitInitializationMode on)")
            if on and not self._tick:
                self._tick = True
                self._install_tick_paths()
            elif not on and self._tick:
                self._tick = False
                self._remove_tick_paths()

    def _install_tick_paths(self) -> None:
        """While a sample is due, reading an output takes it first (instance attributes, as in
        initialization mode: no cost to the stepping paths)."""
        cls = type(self)
        for name in self._ACCESS:
            fast = getattr(cls, name).__get__(self)
            setattr(self, name, self._tick_getter(fast))

    def _remove_tick_paths(self) -> None:
        if self._mode == "run":
            for name in self._ACCESS:
                self.__dict__.pop(name, None)

    def _tick_getter(self, fast: Any) -> Any:
        def get(vrs: list[int]) -> list[Any]:
            if self._tick and self._reads_output(vrs):
                self._sample()
            return fast(vrs)
        return get

    def update_discrete_states(self) -> _Event:
        """fmi3UpdateDiscreteStates: take the sample due at an active clock (if an output read has not
        already); the clock is then inactive.  A failed or mistimed sample is logged and returned as failed
        (our loader: fmi3Error)."""
        if self._tick:
            return _EVENT_OK if self._sample() else _EVENT_FAILED
        return _EVENT_OK

    def _sample(self) -> bool:
        """The sample at the clock's tick at the current time: the fixed-step slave's step from the last
        sample over the clock's interval, with the inputs set now.  A tick at the time of the last sample
        takes none, except the tick at the start time, which recomputes the outputs from the current inputs
        and parameters as initialization mode does.  Returns False (logged) if the sample failed or the tick
        is not one interval after the last sample; every later sample and step is then refused."""
        self._tick = False
        self._remove_tick_paths()
        assert self.sample_clock is not None
        name, h, _ = self.sample_clock
        t = self._vals[self._tslot]
        last = self._t_sample
        where = f"{self.modelName} instance {self.instance_name}: sample of clock {name} at t = {t!r} s"
        if self._failed:
            self.log(f"{where} refused: an earlier step failed ({self._failed})", Fmi3Status.error)
            return False
        if abs(t - last) <= STEP_RTOL * h:
            if self._samples == 0:
                try:
                    self._build()
                except Exception as exc:
                    self._failed = exception_cause(exc)
                    self.log(f"{where} failed: {self._failed}", Fmi3Status.error)
                    return False
            return True
        if abs(t - last - h) > FIXED_STEP_RTOL * h:
            self._failed = f"a tick of clock {name} at t = {t!r} s, not {h!r} s after the last sample"
            self.log(f"{where} refused: the clock ticks every {h!r} s (intervalVariability constant) and the "
                     f"last sample was at t = {last!r} s", Fmi3Status.error)
            return False
        try:
            if h != self._h or self._dirty:
                if self._before_step(last, h) is None:
                    return False
            tk = last
            tn = round(tk / h) * h
            if tn != tk and abs(tn - tk) <= STEP_RTOL * abs(tk):
                tk = tn
            self._step(tk, h)
        except Exception as exc:
            self._failed = exception_cause(exc)
            self.log(f"{where} failed: {self._failed}", Fmi3Status.error)
            return False
        self._t_sample = t
        self._samples += 1
        return True

    def _event_step(self, current_time: float, step_size: float) -> Fmi3StepResult:
        """fmi3DoStep of an instance in event mode: a due sample first, then time advances; the outputs hold.
        A step past the next tick (one interval after the last sample) is refused (Discard)."""
        if self._tick and not self._sample():
            return _DISCARD
        assert self.sample_clock is not None
        name, h, _ = self.sample_clock
        end = current_time + step_size
        if self._failed:
            self.log(f"{self.modelName} instance {self.instance_name}: step at t = {current_time!r} s refused: "
                     f"an earlier step failed ({self._failed})", Fmi3Status.discard)
            return _DISCARD
        tick = self._t_sample + h
        if end - tick > FIXED_STEP_RTOL * h:
            self.log(f"{self.modelName} instance {self.instance_name}: step from t = {current_time!r} s over h = "
                     f"{step_size!r} s refused: it passes the tick of clock {name} at t = {tick!r} s (set the "
                     "clock in Event Mode there: the instance samples only at the clock's ticks)", Fmi3Status.discard)
            return _DISCARD
        self._vals[self._tslot] = end
        return _OK
