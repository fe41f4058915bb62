"""What the project's three pythonfmu slaves share: variable declarations with unit, min and max, a
truthful ModelStructure, fast value-reference paths, complete state save/restore, and failure handling.

This module is bundled inside every FMU next to a copy of the components (see fmus/build.py), so it
imports nothing of the project but the bundled fmi_decl.py (the declarations it shares with the FMI 3.0
slaves): only pythonfmu and the standard library.

Design (each point answers a measured behaviour of pythonfmu 0.7 under FMPy):

* Every value of the FMU lives in one list ``self._vals`` indexed by value reference; the overridden
  ``get_real``/``set_real``/... read and write it directly (no per-variable lambdas in the hot path).
* Parameters are read in ``exit_initialization_mode``, where the component is built: a master sets
  parameter start values after ``__init__`` has run (the builder also runs ``__init__`` once, at build
  time, to read start values).  Before that, outputs hold the initial state of the default parameters
  (an output's value before the first step is whatever ``__init__`` set) and, inside initialization
  mode, are recomputed from the current parameters and inputs whenever they are read.
* Outputs are listed in ModelStructure/Outputs with their true direct-feedthrough ``dependencies``
  and in InitialUnknowns: pythonfmu writes neither, so FMPy's validator rejects its FMUs and other tools
  assume every output depends on every input (an algebraic loop for OMSimulator).  Real variables
  carry unit, min and max, declared in UnitDefinitions (pythonfmu's ``Real`` takes none of them).
* ``do_step`` never raises: a failure is logged with its cause and returned as fmi2Discard; later steps
  are refused the same way.  (pythonfmu turns any exception into fmi2Fatal, after which freeing the
  instance corrupts its heap and crashes the host.)  Initialisation can fail only as fmi2Fatal: the
  one-line cause is logged first.
* The FMU state holds every variable value and the component's own ``get_state()`` (pythonfmu's
  default state saves only the registered variables, silently dropping integrator, filter and RLS states).
* pythonfmu 0.7 releases a reference it does not own at every instantiation (its ``findClass`` calls
  ``Py_DECREF`` on the slave script module's dict, a borrowed reference): a script whose class defines no
  methods of its own (nothing else holds that dict) has its module dict freed under it, and the host
  crashes at its next garbage collection.  Every class derived from :class:`WmrSlave` holds one reference
  to its module's dict, taken when the class is created (``__init_subclass__``); ``findClass`` executes the
  script again at every instantiation, before that release, so each instantiation adds the reference it
  takes away (see :data:`_HELD_MODULE_DICTS`).
* The communication step is whatever the master gives; a step or time within 1e-9 (relative) of the
  previous step or of a whole multiple of it is snapped to it, so that the rounding of other masters
  neither recomputes discretisations nor perturbs the results.
"""
from __future__ import annotations

import sys
from _thread import get_ident
from operator import itemgetter
from typing import Any, NoReturn
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Boolean, DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.logmsg import LogMsg
from pythonfmu.variables import ScalarVariable

from .fmi_decl import (SlaveCore, DBL_MAX, DBL_MIN, FINITE, INT_MAX, NON_NEGATIVE, POSITIVE, SIGN, STEP_RTOL, UNITS,  # noqa: F401
                       Var, exception_cause, xml_number, parameters_of)

_CAUSALITY = {"parameter": Fmi2Causality.parameter, "input": Fmi2Causality.input,
              "output": Fmi2Causality.output}
_VARIABILITY = {"fixed": Fmi2Variability.fixed, "tunable": Fmi2Variability.tunable,
                "discrete": Fmi2Variability.discrete, "continuous": Fmi2Variability.continuous}
_KINDS = {"Real": Real, "Integer": Integer, "Boolean": Boolean, "String": String}


class RealU(Real):
    """pythonfmu's Real with the attributes it lacks: unit, min, max; start written exactly."""

    def __init__(self, name: str, unit: str | None = None, min: float | None = None,
                 max: float | None = None, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.unit, self.min, self.max = unit, min, max

    def to_xml(self) -> Element:
        node = ScalarVariable.to_xml(self)
        attrib: dict[str, str] = {}
        if self.unit is not None:
            attrib["unit"] = self.unit
        if self.min is not None:
            attrib["min"] = xml_number(self.min)
        if self.max is not None:
            attrib["max"] = xml_number(self.max)
        if self.start is not None:
            attrib["start"] = xml_number(self.start)
        SubElement(node, "Real", attrib)
        return node


class IntegerR(Integer):
    """pythonfmu's Integer with min and max (written as integers: a declared range may hold floats)."""

    def __init__(self, name: str, min: float | None = None, max: float | None = None, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.min, self.max = min, max

    def to_xml(self) -> Element:
        node = ScalarVariable.to_xml(self)
        attrib: dict[str, str] = {}
        if self.min is not None:
            attrib["min"] = str(int(self.min))
        if self.max is not None:
            attrib["max"] = str(int(self.max))
        if self.start is not None:
            attrib["start"] = str(int(self.start))
        SubElement(node, "Integer", attrib)
        return node


#: One reference to the module dict of every class derived from WmrSlave, per class created: pythonfmu
#: 0.7's findClass re-executes the slave script (creating its class again) and then releases the module
#: dict once, a reference it never took; without these, a script class with no methods of its own would
#: leave that dict with no owner but its module (freed at the first instantiation, a crash at the next
#: garbage collection).  Grows by one entry per instantiation, as pythonfmu's own leaks do.
_HELD_MODULE_DICTS: list[dict[str, Any]] = []


class WmrSlave(SlaveCore, Fmi2Slave):
    """Base of the project's slaves.  A subclass declares its variables with :meth:`declare` in
    ``__init__`` and implements :meth:`_build` (component from the parameters, initial outputs),
    :meth:`_step` and optionally :meth:`_retune`."""

    default_experiment = DefaultExperiment(start_time=0.0, stop_time=50.0, step_size=0.002)
    author = "wmr-cosim"

    _DISCARD = Fmi2Status.discard   # the status of a refused or failed step (see SlaveCore)
    _FATAL = Fmi2Status.fatal
    _ACCESS = ("get_real", "get_integer", "get_boolean", "get_string")
    _SETS = ("set_real", "set_integer", "set_boolean", "set_string")

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        module = sys.modules.get(cls.__module__)
        if module is not None:
            _HELD_MODULE_DICTS.append(vars(module))   # see _HELD_MODULE_DICTS

    # ------------------------------------------------------------------ declaration
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._init_state()
        self._held_slice: tuple[Any, int, int] = (None, -1, 0)   # (see _loader_step)
        self._got: tuple[Any, Any] = (None, None)
        # our loader waits for the slave it is constructing on this thread (see _loader_set_real)
        slots = getattr(sys, "_wmr_pyloader_slaves", None)
        if slots is not None and slots.get(get_ident(), 0) is None:
            slots[get_ident()] = self

    def declare(self, variables: list[Var]) -> None:
        """Register the variables (value reference = position) and prepare the fast paths."""
        for var in variables:
            vr = self._add(var)
            lo, hi = var.range
            common = dict(causality=_CAUSALITY[var.causality], description=var.description,
                          variability=_VARIABILITY[var.variability])
            if var.causality == "parameter":
                common["initial"] = Fmi2Initial.exact
            if var.kind == "Real":
                sv = RealU(var.name, unit=var.unit, min=lo, max=hi, **common)
            elif var.kind == "Integer":
                sv = IntegerR(var.name, min=lo, max=hi, **common)
            else:
                sv = _KINDS[var.kind](var.name, **common)
            sv.getter = (lambda i=vr: self._vals[i])
            sv.setter = (lambda x, i=vr: self._vals.__setitem__(i, x))
            self.register_variable(sv)
            assert sv.value_reference == vr
        self._index()

    def _index(self) -> None:
        decl = self._decl
        kinds = {k: frozenset(v.vr for v in decl if v.kind == k) for k in _KINDS}
        self._kind_vrs = kinds
        self._group_declarations()
        self._in_list = [v.vr for v in self._inputs if v.kind == "Real"]
        if self._in_list != list(range(self._in0, self._in1)):
            self._in_list = [-1]  # the fast path of set_real needs all inputs Real and contiguous
        self._get_key: list[int] = [-1]
        self._get_items: Any = None
        param_vrs = {v.vr for v in self._params}
        input_vrs = {v.vr for v in self._inputs}
        tunable = {v.vr for v in self._params if v.variability == "tunable"}
        self._settable_before = {k: frozenset(vs & (param_vrs | input_vrs)) for k, vs in kinds.items()}
        self._settable_running = {k: frozenset(vs & (tunable | input_vrs)) for k, vs in kinds.items()}
        self._tunable = frozenset(tunable)
        self._settable = self._settable_before
        self._watch: frozenset[int] = frozenset()

    def vr(self, name: str) -> int:
        """Value reference of a variable."""
        return self._by_name[name].vr

    # ------------------------------------------------------------------ model description
    def to_xml(self, model_options: dict[str, str] = dict()) -> Element:  # noqa: B006 (pythonfmu's signature)
        root = super().to_xml(model_options)
        cosim = root.find("CoSimulation")
        self._describe(root, cosim)
        # UnitDefinitions right after <CoSimulation> (schema order), only the units in use
        used = sorted({v.unit for v in self._decl if v.unit is not None})
        units = Element("UnitDefinitions")
        for name in used:
            SubElement(SubElement(units, "Unit", {"name": name}), "BaseUnit",
                       {k: str(e) for k, e in UNITS[name].items()})
        root.insert(list(root).index(cosim) + 1, units)
        # ModelStructure: Outputs and InitialUnknowns with their true dependencies (1-based indices)
        structure = root.find("ModelStructure")
        for child in list(structure):
            structure.remove(child)
        index = {v.name: v.vr + 1 for v in self._decl}
        all_inputs = tuple(v.name for v in self._inputs)
        params = [index[v.name] for v in self._params]
        if self._outputs:
            outs = SubElement(structure, "Outputs")
            for v in self._outputs:
                deps = all_inputs if v.deps is None else v.deps
                SubElement(outs, "Unknown", {"index": str(index[v.name]),
                                             "dependencies": " ".join(str(index[d]) for d in deps)})
            init = SubElement(structure, "InitialUnknowns")
            for v in self._outputs:
                deps = all_inputs if v.init_deps is None else v.init_deps
                idx = sorted(params + [index[d] for d in deps])
                SubElement(init, "Unknown", {"index": str(index[v.name]),
                                             "dependencies": " ".join(map(str, idx))})
        return root

    # ------------------------------------------------------------------ fast value access
    def get_real(self, vrs: list[int]) -> list[float]:
        # fast path: a master asks for the same value references every step (checked once, then cached)
        if vrs == self._get_key:
            return list(self._get_items(self._vals))
        if not self._kind_vrs["Real"].issuperset(vrs):
            self._wrong_type(vrs, "Real")
        v = self._vals
        if len(vrs) > 1:
            self._get_key = list(vrs)
            self._get_items = itemgetter(*vrs)
        return [v[i] for i in vrs]

    def get_integer(self, vrs: list[int]) -> list[int]:
        if not self._kind_vrs["Integer"].issuperset(vrs):
            self._wrong_type(vrs, "Integer")
        v = self._vals
        return [int(v[i]) for i in vrs]

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        if not self._kind_vrs["Boolean"].issuperset(vrs):
            self._wrong_type(vrs, "Boolean")
        v = self._vals
        return [bool(v[i]) for i in vrs]

    def get_string(self, vrs: list[int]) -> list[str]:
        if not self._kind_vrs["String"].issuperset(vrs):
            self._wrong_type(vrs, "String")
        v = self._vals
        return [str(v[i]) for i in vrs]

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        # fast path: all the Real inputs, in order (what a master sets every step); inputs are settable in
        # every mode and never watched, so nothing else needs checking
        if vrs == self._in_list:
            self._vals[self._in0:self._in1] = values
            return
        if not self._settable["Real"].issuperset(vrs):
            self._refuse_set(vrs, "Real")
        v = self._vals
        for i, x in zip(vrs, values):
            v[i] = x
        if self._watch and not self._watch.isdisjoint(vrs):
            self._dirty = True

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._set_other(vrs, values, "Integer", int)

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._set_other(vrs, values, "Boolean", bool)

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._set_other(vrs, values, "String", str)

    def _set_other(self, vrs: list[int], values: list[Any], kind: str, conv: Any) -> None:
        if not self._settable[kind].issuperset(vrs):
            self._refuse_set(vrs, kind)
        v = self._vals
        for i, x in zip(vrs, values):
            v[i] = conv(x)
        if self._watch and not self._watch.isdisjoint(vrs):
            self._dirty = True

    def _name_of(self, vr: int) -> str:
        return self._decl[vr].name if 0 <= vr < len(self._decl) else f"<unknown value reference {vr}>"

    def _wrong_type(self, vrs: list[int], kind: str) -> NoReturn:
        bad = [self._name_of(i) for i in vrs if i not in self._kind_vrs[kind]]
        msg = f"{self.modelName} instance {self.instance_name}: get{kind} on variables that are not {kind}: {', '.join(bad)}"
        self.log(msg, Fmi2Status.fatal)
        raise TypeError(msg)

    def _refuse_set(self, vrs: list[int], kind: str) -> NoReturn:
        bad = []
        for i in vrs:
            if i not in self._settable[kind]:
                name = self._name_of(i)
                if i in self._kind_vrs[kind] and 0 <= i < len(self._decl):
                    var = self._decl[i]
                    why = (f"{var.causality} {name}" if var.causality == "output" else
                           f"{var.variability} parameter {name} after initialisation")
                else:
                    why = f"{name} (not {kind})"
                bad.append(why)
        msg = f"{self.modelName} instance {self.instance_name}: set{kind} refused for {', '.join(bad)}"
        self.log(msg, Fmi2Status.fatal)
        raise ValueError(msg)

    # ------------------------------------------------------------------ our loader's direct path
    # fmus/pyloader/wmr_pyloader.c calls these three, and do_step, without pythonfmu's binary (its header
    # says why and how); each either does what the call through pythonfmu does, or changes nothing and
    # leaves the call to pythonfmu's binary (refusals, initialization mode: pythonfmu's messages and status).
    def _loader_set_real(self, vrs: list[int], values: list[float]) -> bool:
        """fmi2SetReal: True once set_real has set the values [their variables' units]; False (nothing set)
        where set_real would refuse them."""
        if vrs == self._in_list or self._settable["Real"].issuperset(vrs):
            self.set_real(vrs, values)
            return True
        return False

    def _loader_get_real(self, vrs: list[int]) -> list[float] | None:
        """fmi2GetReal: get_real's values [their variables' units]; None in initialization mode (where a read
        may build the component) or where get_real would refuse them."""
        if "get_real" not in self.__dict__ and (vrs == self._get_key or self._kind_vrs["Real"].issuperset(vrs)):
            return self.get_real(vrs)
        return None

    def _loader_held(self) -> list[int]:
        """The value references whose fmi2SetReal the loader may hold until this slave's next call: the Real
        inputs, which set_real takes in every mode, without a message."""
        return [v.vr for v in self._inputs if v.kind == "Real"]

    def _loader_step(self, current_time: float, step_size: float, vrs: list[int] | None,
                     values: list[float] | None, get_vrs: list[int] | None) -> bool | list[float]:
        """fmi2DoStep from t = ``current_time`` over h = ``step_size`` [s]: first the sets the loader held
        (``vrs``, ``values``: Real inputs only, each once), then do_step; after a step that succeeded, the
        values of ``get_vrs`` (what the loader's last fmi2GetReal asked for), else do_step's result.  The
        loader passes the same list objects while the value references stay the same: what is derived from
        them is kept by identity."""
        if vrs is not None:
            if "set_real" in self.__dict__:   # (initialization mode)
                self.set_real(vrs, values)  # type: ignore[arg-type]
            else:   # what set_real does with inputs: assign them (settable in every mode, never watched)
                held = self._held_slice
                if held[0] is not vrs:
                    first = vrs[0] if vrs else 0
                    contiguous = vrs == list(range(first, first + len(vrs)))
                    held = self._held_slice = (vrs, first if contiguous else -1, first + len(vrs))
                v = self._vals
                if held[1] >= 0:
                    v[held[1]:held[2]] = values  # type: ignore[assignment]
                else:
                    for i, x in zip(vrs, values):  # type: ignore[arg-type]
                        v[i] = x
        ok = self.do_step(current_time, step_size)
        if ok and get_vrs is not None and "get_real" not in self.__dict__:
            got = self._got
            if got[0] is not get_vrs:
                if not self._kind_vrs["Real"].issuperset(get_vrs):
                    return ok
                got = self._got = (get_vrs, itemgetter(*get_vrs) if len(get_vrs) > 1 else None)
            if got[1] is None:
                return [self._vals[get_vrs[0]]]
            return list(got[1](self._vals))
        return ok

    def _loader_fatal(self, message: str) -> None:
        """Queue pythonfmu's own line for an exception out of a call (Fatal, no category), after the
        messages queued before it."""
        self.log_queue.append(LogMsg(Fmi2Status.fatal, None, message))

    # ------------------------------------------------------------------ life cycle
    def setup_experiment(self, start_time: float = 0.0, stop_time: float | None = None,
                         tolerance: float | None = None) -> None:
        self._t0 = float(start_time)

    def _reads_output(self, vrs: list[int]) -> bool:
        return any(self._out0 <= i < self._out1 for i in vrs)

    def do_step(self, current_time: float, step_size: float) -> bool:
        h: float | None = step_size   # None: the step refused (_before_step)
        try:
            if h != self._h or self._dirty or self._failed:  # the rare cases, out of the hot path
                h = self._before_step(current_time, step_size)
                if h is None:
                    return False
            # a time within STEP_RTOL of a whole multiple of h is that multiple (see STEP_RTOL)
            t = current_time
            tn = round(t / h) * h
            if tn != t and abs(tn - t) <= STEP_RTOL * abs(t):
                t = tn
            self._step(t, h)
            return True
        except Exception as exc:
            self._failed = exception_cause(exc)
            self.log(f"{self.modelName} instance {self.instance_name}: step from t = {current_time!r} s "
                     f"over h = {step_size!r} s failed: {self._failed}", Fmi2Status.discard)
            return False

