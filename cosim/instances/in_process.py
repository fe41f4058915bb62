"""One FMU instance: its life cycle under the FMI 2.0 rules, its log, and raw ctypes entry points.

Life cycle, in the order FMPy and libcosim use (some tools' FMUs, 20-sim's among them, reset their
parameters in fmi2SetupExperiment, so values set before it would be lost): instantiate, set up the
experiment, set parameters and start values, enter initialisation mode, (inputs exchanged by the
execution), exit initialisation mode, step, terminate, free.

Rules kept here: every instance that reported OK, Warning, Discard or Error is terminated (if it was
initialised) and freed exactly once; an instance that reported Fatal gets no further call at all (FMI 2.0;
freeing a pythonfmu instance after Fatal corrupts its heap and crashes the host at the next garbage
collection).

Logging: a level per instance ("error", "warning", "info", "all"; default "warning").  The FMU is asked
through fmi2SetDebugLogging for the categories of that level it declares, so a verbose FMU does not call
back at every step, and messages below the level are dropped on this side too.  Lines go to the
instance's log file as they come; only the last few are kept in memory (for error messages).
"""
from __future__ import annotations

import ctypes
import itertools
import math
import os
import weakref
from collections import deque
from pathlib import Path
from typing import Any

from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2LastSuccessfulTime, fmi2Real,
                       fmi2Terminated, fmi2ValueReference)
from fmpy.fmi1 import FMICallException

from ..messages.errors import RunError
from ..model import binary
from ..model.description import Variable, fmi2_cs_declares
from .contract import FastPath, FmuInstance, status_label

from fmpy import calloc, free   # the C calloc/free FMPy hands to FMUs


# FMPy's C logger proxy (it formats the variadic arguments ctypes cannot pass) forwards every message to ONE
# process-wide logger, the one last registered with addLoggerProxy.  So the master registers one dispatcher,
# alive for the whole process, that routes each message to its Instance by the componentEnvironment the
# Instance gave at instantiation.  (Registering each Instance's own logger sent every FMU's messages to the
# last Instance created, and, once that Instance was collected, made any later proxied message -- FMPy's
# default callbacks included -- call freed memory: a segfault.)
_LIVE: "weakref.WeakValueDictionary[int, Instance]" = weakref.WeakValueDictionary()
_BY_NAME: "weakref.WeakValueDictionary[bytes, Instance]" = weakref.WeakValueDictionary()
_IDS = itertools.count(1)

#: Logging levels: the lowest status kept.
LOG_LEVELS = {"all": 0, "info": 0, "warning": 1, "error": 3}
_LEVEL_WORDS = {"warning": ("warn", "discard", "error", "fatal", "pending"), "error": ("error", "fatal")}


def _text(raw: bytes | None) -> str:
    """A C string from an FMU as text: UTF-8, undecodable bytes replaced (an FMU may log in another
    encoding), "" for NULL."""
    return (raw or b"").decode("utf-8", "replace")


def _dispatch(env, instance_name, status, category, message) -> None:
    # some tools' FMUs (20-sim) pass back a componentEnvironment other than the one they were given:
    # then the instance name routes the message
    inst = _LIVE.get(env) or _BY_NAME.get(instance_name)
    if inst is not None:
        inst._logger(status, category, message)
    else:  # an FMU this master did not instantiate (FMPy's own defaults): print as FMPy does
        print(f"[{status_label(status)}] {_text(message)}")


_DISPATCH = fmi2CallbackLoggerTYPE(_dispatch)


class Instance(FmuInstance):
    """An instantiated FMU (FMI 2.0 co-simulation) with its log."""

    fmi_version = 2

    def __init__(self, name: str, md: Any, unzipdir: str, log_path: str | os.PathLike | None = None,
                 logging: str = "warning", log_size: int = 200) -> None:
        self.name = name
        self.md = md
        self.log: deque[str] = deque(maxlen=log_size)
        self.log_lines = 0
        self.n_errors = 0          # messages of status Discard, Error or Fatal, kept or not
        self.received = 0          # messages the FMU sent, kept or not
        self.min_status = LOG_LEVELS[logging]
        self.logging = logging
        self._log_fh = open(log_path, "w", encoding="utf-8") if log_path is not None else None
        self.fatal = False
        self.initialised = False
        self.freed = False
        self.c = None
        self.python = runs_python(unzipdir)
        self.fmu = self._slave(md, unzipdir)

    def _slave(self, md: Any, unzipdir: str) -> Any:
        """The FMPy slave of the FMU, its callbacks registered with the logger dispatcher."""
        self._register_callbacks()
        return FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                         modelIdentifier=md.coSimulation.modelIdentifier, instanceName=self.name)

    def _register_callbacks(self) -> None:
        """The FMI 2.0 callbacks of this instance, its log messages routed to it by the dispatcher."""
        self._callbacks = fmi2CallbackFunctions()
        self._env = next(_IDS)
        _LIVE[self._env] = self
        _BY_NAME[self.name.encode("utf-8")] = self
        self._callbacks.componentEnvironment = self._env
        self._callbacks.logger = _DISPATCH
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:  # FMPy's C proxy formats the variadic message arguments
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(ctypes.byref(self._callbacks))
        except Exception:  # pragma: no cover
            pass

    # ------------------------------------------------------------------ log
    def _logger(self, status, category, message) -> None:
        self.received += 1
        if status >= 2:   # Discard, Error, Fatal: a failed step explains itself (see execution._failed)
            self.n_errors += 1
        if status < self.min_status:
            return
        line = f"[{status_label(status)}] {_text(category)}: {_text(message)}"
        self.log.append(line)
        self.log_lines += 1
        if self._log_fh is not None:
            self._log_fh.write(line + "\n")

    def last_log(self, n: int = 3) -> str:
        lines = list(self.log)[-n:]
        return " | ".join(" ".join(ln.split()) for ln in lines) if lines else "(the FMU logged nothing)"

    def flush_log(self) -> None:
        """The log file's lines on disk now (a child process answers for its instance's log)."""
        if self._log_fh is not None and not self._log_fh.closed:
            self._log_fh.flush()

    def close_log(self) -> None:
        if self._log_fh is not None and not self._log_fh.closed:
            self._log_fh.close()

    # ------------------------------------------------------------------ life cycle
    def call(self, what: str, fn, *args, t: float | None = None) -> Any:
        """Call an FMPy wrapper method; a non-OK status becomes a RunError naming this instance."""
        try:
            return fn(*args)
        except FMICallException as exc:
            raise self.fail_status(what, int(exc.status), t) from None
        except RunError:
            raise
        except Exception as exc:
            raise RunError(f"{self.name}: {what} failed: {' '.join(str(exc).split())}; last log: {self.last_log()}",
                           self.name, t) from None

    def instantiate(self) -> None:
        """fmi2Instantiate (logging on), then fmi2SetDebugLogging with the categories of the level."""
        self.call("fmi2Instantiate", self.fmu.instantiate, False, self._callbacks, True)
        self.c = self.fmu.component  # the stepping loop calls the library through raw()
        # pythonfmu FMUs report exceptions with no category, which a category list filters out: they
        # get no list (they do not log at every step anyway), and the level is applied on this side
        pythonfmu = (self.md.generationTool or "").lower().startswith("pythonfmu")
        self._debug_logging("fmi2SetDebugLogging", lists_categories=not pythonfmu)

    def _debug_logging(self, what: str, lists_categories: bool = True) -> None:
        """Ask the FMU for the log categories it declares that the level keeps (all of them for "all";
        with ``lists_categories`` False, only "all" asks for anything)."""
        words = _LEVEL_WORDS.get(self.logging)
        cats = [c.name for c in getattr(self.md, "logCategories", None) or []]
        if self.logging == "all" and cats:
            self.call(what, self.fmu.setDebugLogging, True, [])
        elif words and cats and lists_categories:
            chosen = [c for c in cats if any(w in c.lower() for w in words)]
            self.call(what, self.fmu.setDebugLogging, bool(chosen), chosen)

    def setup_experiment(self, start: float, stop: float | None, tolerance: float | None) -> None:
        self.call("fmi2SetupExperiment", self.fmu.setupExperiment, tolerance, start, stop)

    def set_values(self, pairs: list[tuple[Variable, Any]]) -> None:
        """Set start values / parameters by type."""
        for var, value in pairs:
            vr = [var.vr]
            if var.type == "Real":
                self.call(f"fmi2SetReal({var.name})", self.fmu.setReal, vr, [float(value)])
            elif var.is_integer:
                self.call(f"fmi2SetInteger({var.name})", self.fmu.setInteger, vr, [int(value)])
            elif var.type == "Boolean":
                self.call(f"fmi2SetBoolean({var.name})", self.fmu.setBoolean, vr, [bool(value)])
            elif var.type == "String":
                self.call(f"fmi2SetString({var.name})", self.fmu.setString, vr, [str(value)])

    def get_value(self, var: Variable) -> Any:
        """The current value of one scalar variable, as a Python value of its type."""
        t = "Integer" if var.type == "Enumeration" else var.type
        if t not in ("Real", "Integer", "Boolean", "String"):
            raise RunError(f"{self.name}: variables of type {var.type} cannot be read", self.name)
        value = self.call(f"fmi2Get{t}({var.name})", getattr(self.fmu, f"get{t}"), [var.vr])[0]
        return _text(value) if isinstance(value, bytes) else value

    def enter_initialization(self) -> None:
        self.call("fmi2EnterInitializationMode", self.fmu.enterInitializationMode)

    def exit_initialization(self) -> None:
        self.call("fmi2ExitInitializationMode", self.fmu.exitInitializationMode)
        self.initialised = True

    def terminated_at(self) -> float | None:
        """After a Discard from fmi2DoStep: the FMU's last successful time if it says it has ended the
        simulation (fmi2Terminated), else None."""
        try:
            if not self.fmu.getBooleanStatus(fmi2Terminated):
                return None
        except Exception:
            return None
        try:
            return float(self.fmu.getRealStatus(fmi2LastSuccessfulTime))
        except Exception:
            return math.nan

    # ------------------------------------------------------------------ the step's fast path
    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                  in_val: Any = None) -> FastPath:
        """fmi2SetReal, fmi2DoStep (noSetFMUStatePriorToCurrentPoint true), fmi2GetReal; ``in_val``: the
        input array to use (default: a new one)."""
        dll = self.fmu.dll
        return self._handed(FastPath(ctypes.c_void_p(self.c), raw(dll, "fmi2SetReal"), raw(dll, "fmi2DoStep"),
                                     raw(dll, "fmi2GetReal"),
                                     in_val if in_val is not None else (ctypes.c_double * max(1, n_in))(),
                                     step_tail=(1,), abi=2, **self._threading(dll, "fmi2DoStep")))

    def _threading(self, dll: Any, do_step: str) -> dict[str, Any]:
        """The fast path's step for threads (:attr:`FastPath.threaded_step`), or why there is none."""
        if self.python:
            return {"alone": binary.PYTHON_FMU}
        return {"threaded_step": released(dll, do_step)}

    def _handed(self, fp: FastPath) -> FastPath:
        """A fast path handed out: kept, so that :meth:`allow_rollback` reaches it."""
        fasts = self.__dict__.setdefault("_fasts", [])
        fasts.append(fp)
        if getattr(self, "_rollback", False):
            self._rollback_tail(fp)
        return fp

    def allow_rollback(self) -> None:
        """noSetFMUStatePriorToCurrentPoint false in every step from now on (the first argument after h)."""
        self._rollback = True
        for fp in self.__dict__.get("_fasts", []):
            self._rollback_tail(fp)

    @staticmethod
    def _rollback_tail(fp: FastPath) -> None:
        if fp.step_tail:
            fp.step_tail = (type(fp.step_tail[0])(0),) + fp.step_tail[1:]

    @property
    def can_interpolate_inputs(self) -> bool:
        """FMI 2.0 co-simulation: canInterpolateInputs (FMI 3.0 has no input derivatives)."""
        return fmi2_cs_declares(self.md, "canInterpolateInputs")

    def set_input_derivatives(self, vrs: list[int], values: list[float]) -> int:
        """fmi2SetRealInputDerivatives of order 1."""
        if not self.can_interpolate_inputs:
            return super().set_input_derivatives(vrs, values)
        fn = self.__dict__.get("_set_der")
        if fn is None:
            fn = self._set_der = raw(self.fmu.dll, "fmi2SetRealInputDerivatives")
        n = len(vrs)
        return fn(ctypes.c_void_p(self.c), vr_array(vrs), ctypes.c_size_t(n), (ctypes.c_int * n)(*([1] * n)),
                  real_array(values))

    @property
    def provides_directional_derivative(self) -> bool:
        """FMI 2.0 co-simulation that declares providesDirectionalDerivative (FMI 3.0's are not used: no
        FMI 3.0 co-simulation FMU here declares them, so that call is untested)."""
        return fmi2_cs_declares(self.md, "providesDirectionalDerivative")

    def directional_derivative(self, unknowns: list[int], knowns: list[int], seed: list[float]) -> tuple[int, list[float]]:
        """fmi2GetDirectionalDerivative."""
        if not self.provides_directional_derivative:
            return super().directional_derivative(unknowns, knowns, seed)
        fn = self.__dict__.get("_dd")
        if fn is None:
            fn = self._dd = raw(self.fmu.dll, "fmi2GetDirectionalDerivative")
        nu, nk = len(unknowns), len(knowns)
        out = (ctypes.c_double * max(1, nu))()
        st = fn(ctypes.c_void_p(self.c), vr_array(unknowns), ctypes.c_size_t(nu), vr_array(knowns),
                ctypes.c_size_t(nk), real_array(seed), out)
        return int(st), list(out[:nu])

    def accessor(self, fmi_type: str, op: str) -> tuple[Any, Any]:
        ctype, tname = ACCESS[2][fmi_type]
        what = f"fmi2{op}{tname}"
        fn, c = raw(self.fmu.dll, what), ctypes.c_void_p(self.c)

        def call(vrs: Any, n: Any, buf: Any, nv: Any) -> int:
            try:
                return fn(c, vrs, n, buf)
            except Exception as exc:
                return self.raised_in(what, exc)
        return call, ctype

    def raised_in(self, what: str, exc: BaseException) -> int:
        """fmi2Error for a raw call that left a Python exception behind (a pythonfmu FMU whose own code
        failed after the call had begun, e.g. an Integer too large for C: the values it gave are not valid),
        the exception logged as the FMU's error message."""
        self._logger(3, b"exception", f"{what}: {type(exc).__name__}: {exc} (raised in the FMU's code)".encode("utf-8"))
        return 3

    # ------------------------------------------------------------------ state (FMPy names both versions' alike)
    def _state_call(self, op: str) -> str:
        return f"fmi{self.fmi_version}{op}FMU{'state' if self.fmi_version == 2 else 'State'}"

    def get_state(self) -> Any:
        self._not_freed(self._state_call("Get"))
        return self.call(self._state_call("Get"), self.fmu.getFMUState)

    def set_state(self, state: Any) -> None:
        self._not_freed(self._state_call("Set"))
        self.call(self._state_call("Set"), self.fmu.setFMUState, state)

    def free_state(self, state: Any) -> None:
        self._not_freed(self._state_call("Free"))
        self.call(self._state_call("Free"), self.fmu.freeFMUState, state)

    def _not_freed(self, what: str) -> None:
        """RunError for a call on an instance freed already (FMPy unloads the FMU's library with it: the
        call would jump into unmapped memory); its saved states went with it."""
        if self.freed:
            raise RunError(f"{self.name}: {what} after the instance was freed (its states went with it)", self.name)

    def shutdown(self) -> None:
        """Terminate (if initialised) and free, exactly once; nothing at all after a Fatal.  The log file
        is closed last: an FMU may log while it is terminated and freed (an FMU in an error state says
        "Illegal call sequence" again)."""
        try:
            if self.freed or self.fatal or self.c is None:
                return
            self.freed = True
            try:
                if self.initialised:
                    self.fmu.terminate()
            except Exception:
                pass
            try:
                self.fmu.freeInstance()
            except Exception:
                pass
        finally:
            self.close_log()


_PYDLLS: dict[int, Any] = {}


def _fmi3_call_type(var: Variable) -> str:
    """The type in the name of the FMI 3.0 get/set function of a variable: an Enumeration is an Int64."""
    return "Int64" if var.fmi_type == "Enumeration" else var.fmi_type


class Instance3(Instance):
    """An instantiated FMI 3.0 co-simulation FMU (no event mode, no early return) with its log."""

    fmi_version = 3

    def _slave(self, md: Any, unzipdir: str) -> Any:
        from fmpy.fmi3 import FMU3Slave

        self._experiment: tuple[float, float | None, float | None] = (0.0, None, None)
        return FMU3Slave(guid=md.guid, unzipDirectory=unzipdir,
                         modelIdentifier=md.coSimulation.modelIdentifier, instanceName=self.name)

    def _log3(self, env, status, category, message) -> None:  # fmi3LogMessageCallback: no variadic arguments
        self._logger(status, category, message)

    def instantiate(self) -> None:
        self.call("fmi3InstantiateCoSimulation", self.fmu.instantiate, False, True, False, False, self._log3)
        self.c = self.fmu.component
        self._debug_logging("fmi3SetDebugLogging")

    def setup_experiment(self, start: float, stop: float | None, tolerance: float | None) -> None:
        self._experiment = (start, stop, tolerance)   # FMI 3.0 takes them at fmi3EnterInitializationMode

    def set_values(self, pairs: list[tuple[Variable, Any]]) -> None:
        """Set start values / parameters (an array variable takes a list); Booleans need no conversion:
        FMPy hands them to ctypes' fmi3Boolean, which takes any value's truth."""
        for var, value in pairs:
            values = list(value) if isinstance(value, (list, tuple)) else [value]
            t = _fmi3_call_type(var)
            if var.type == "Real":
                values = [float(v) for v in values]
            elif var.type == "Binary":
                values = [bytes.fromhex(v) for v in values]
            self.call(f"fmi3Set{t}({var.name})", getattr(self.fmu, f"set{t}"), [var.vr], values)

    def get_value(self, var: Variable) -> Any:
        if var.fmi_type == "Binary" or var.shape:
            raise RunError(f"{self.name}: {var.name} ({var.fmi_type}{list(var.shape) if var.shape else ''}) cannot "
                           "be read as one value", self.name)
        t = _fmi3_call_type(var)
        # (FMPy decodes an FMI 3.0 string itself)
        return self.call(f"fmi3Get{t}({var.name})", getattr(self.fmu, f"get{t}"), [var.vr])[0]

    def enter_initialization(self) -> None:
        start, stop, tol = self._experiment
        self.call("fmi3EnterInitializationMode", self.fmu.enterInitializationMode, tol, start, stop)

    def exit_initialization(self) -> None:
        self.call("fmi3ExitInitializationMode", self.fmu.exitInitializationMode)
        self.initialised = True

    def terminated_at(self) -> float | None:
        return None   # FMI 3.0 says it in fmi3DoStep's terminateSimulation (FastPath.terminated)

    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int,
                  in_val: Any = None) -> FastPath:
        """fmi3SetFloat64 and fmi3GetFloat64 (with the count of values), fmi3DoStep with
        noSetFMUStatePriorToCurrentPoint true and its four outputs: eventHandlingNeeded (unused: no event
        mode), terminateSimulation, earlyReturn (not allowed), lastSuccessfulTime."""
        dll = self.fmu.dll
        flags = ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()
        return self._handed(FastPath(ctypes.c_void_p(self.c), raw(dll, "fmi3SetFloat64"), raw(dll, "fmi3DoStep"),
                                     raw(dll, "fmi3GetFloat64"),
                                     in_val if in_val is not None else (ctypes.c_double * max(1, n_in))(),
                                     set_tail=(ctypes.c_size_t(n_in),), get_tail=(ctypes.c_size_t(n_out),),
                                     step_tail=(True, *(ctypes.byref(f) for f in flags)), terminated=flags[1],
                                     last_time=flags[3], abi=3, **self._threading(dll, "fmi3DoStep")))

    def accessor(self, fmi_type: str, op: str) -> tuple[Any, Any]:
        ctype, tname = ACCESS[3][fmi_type]
        what = f"fmi3{op}{tname}"
        fn, c = raw(self.fmu.dll, what), ctypes.c_void_p(self.c)

        def call(vrs: Any, n: Any, buf: Any, nv: Any) -> int:
            try:
                return fn(c, vrs, n, buf, nv)
            except Exception as exc:
                return self.raised_in(what, exc)
        return call, ctype


def raw(dll: Any, name: str) -> Any:
    """A fresh ctypes function for ``name`` without argtypes (FMPy's copy carries converting argtypes),
    called with the GIL held (through a PyDLL view of the library already loaded): an FMU's own Python
    code (pythonfmu) and its log callbacks take the GIL recursively, and a call saves the release and the
    re-acquisition of the GIL."""
    return _function(dll, name, ctypes.PyDLL, _PYDLLS)


def released(dll: Any, name: str) -> Any:
    """:func:`raw`'s function through a CDLL view of the library: ctypes lets go of the GIL for the call,
    so that another thread's FMU steps meanwhile (its log callbacks take the GIL back)."""
    return _function(dll, name, ctypes.CDLL, _CDLLS)


def _function(dll: Any, name: str, view: Any, views: dict[int, Any]) -> Any:
    """``name`` of the library ``dll`` already loaded, through its ``view`` (PyDLL or CDLL, kept in
    ``views`` by handle), returning an int status."""
    handle = dll._handle
    lib = views.get(handle)
    if lib is None:
        lib = views[handle] = view(dll._name, handle=handle)
    f = lib[name]
    f.restype = ctypes.c_int
    return f


_CDLLS: dict[int, Any] = {}


def runs_python(unzipdir: str) -> bool:
    """Whether the FMU unpacked in ``unzipdir`` runs Python code in its steps (:func:`.model.binary.runs_python`)."""
    folder = Path(unzipdir)   # (where the rule looks: the resources' top and the binaries' folders)
    return binary.runs_python(p.relative_to(folder).as_posix()
                              for p in (*folder.glob("resources/*"), *folder.glob("binaries/*/*")))


#: FMI type -> (ctypes element type, the FMI function's type name) for FMI 2.0 and 3.0.
ACCESS = {
    2: {"Real": (ctypes.c_double, "Real"), "Integer": (ctypes.c_int, "Integer"),
        "Enumeration": (ctypes.c_int, "Integer"), "Boolean": (ctypes.c_int, "Boolean"),
        "String": (ctypes.c_char_p, "String")},
    3: {"Float64": (ctypes.c_double, "Float64"), "Float32": (ctypes.c_float, "Float32"),
        "Int8": (ctypes.c_int8, "Int8"), "UInt8": (ctypes.c_uint8, "UInt8"), "Int16": (ctypes.c_int16, "Int16"),
        "UInt16": (ctypes.c_uint16, "UInt16"), "Int32": (ctypes.c_int32, "Int32"),
        "UInt32": (ctypes.c_uint32, "UInt32"), "Int64": (ctypes.c_int64, "Int64"),
        "UInt64": (ctypes.c_uint64, "UInt64"), "Enumeration": (ctypes.c_int64, "Int64"),
        "Boolean": (ctypes.c_bool, "Boolean"), "String": (ctypes.c_char_p, "String")},
}


def real_array(values) -> Any:
    """A ctypes fmi2Real array of the values."""
    values = list(values)
    return (fmi2Real * len(values))(*values)


def vr_array(vrs) -> Any:
    vrs = list(vrs)
    return (fmi2ValueReference * len(vrs))(*vrs)
