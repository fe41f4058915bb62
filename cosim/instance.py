"""One FMU instance under FMPy: life cycle with the FMI 2.0 rules, its log, and raw ctypes entry points
for the stepping loop.

Rules kept here: every instance that reported OK, Warning, Discard or Error is terminated (if it was
initialised) and freed exactly once; an instance that reported Fatal gets no further call at all (FMI 2.0;
freeing a pythonfmu instance after Fatal corrupts its heap and crashes the host at the next garbage
collection).
"""
from __future__ import annotations

import ctypes
import itertools
import weakref
from collections import deque
from typing import Any

from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Real, fmi2ValueReference)
from fmpy.fmi1 import FMICallException

from .errors import RunError
from .model import Variable

STATUS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
FATAL = 4

try:  # the C calloc/free FMPy hands to FMUs
    from fmpy import calloc, free
except ImportError:  # pragma: no cover
    from fmpy.fmi1 import calloc, free  # type: ignore


# FMPy's C logger proxy (it formats the variadic arguments ctypes cannot pass) forwards every message to ONE
# process-wide logger, the one last registered with addLoggerProxy.  So the master registers one dispatcher,
# alive for the whole process, that routes each message to its Instance by the componentEnvironment the
# Instance gave at instantiation.  (Registering each Instance's own logger sent every FMU's messages to the
# last Instance created, and, once that Instance was collected, made any later proxied message -- FMPy's
# default callbacks included -- call freed memory: a segfault.)
_LIVE: "weakref.WeakValueDictionary[int, Instance]" = weakref.WeakValueDictionary()
_IDS = itertools.count(1)


def _dispatch(env, instance_name, status, category, message) -> None:
    inst = _LIVE.get(env or 0)
    if inst is not None:
        inst._logger(env, instance_name, status, category, message)
    else:  # an FMU this master did not instantiate (FMPy's own defaults): print as FMPy does
        label = STATUS[status] if 0 <= status < len(STATUS) else status
        print(f"[{label}] {(message or b'').decode('utf-8', 'replace')}")


_DISPATCH = fmi2CallbackLoggerTYPE(_dispatch)


class Instance:
    """An instantiated FMU (FMI 2.0 co-simulation) with its log lines."""

    def __init__(self, name: str, md: Any, unzipdir: str, log_size: int = 2000) -> None:
        self.name = name
        self.md = md
        self.log: deque[str] = deque(maxlen=log_size)
        self.all_log: list[str] = []
        self.fatal = False
        self.initialised = False
        self.freed = False
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self._callbacks = fmi2CallbackFunctions()
        self._env = next(_IDS)
        _LIVE[self._env] = self
        self._callbacks.componentEnvironment = self._env
        self._callbacks.logger = _DISPATCH
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:  # FMPy's C proxy formats the variadic message arguments
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(ctypes.byref(self._callbacks))
        except Exception:  # pragma: no cover
            pass
        self.c = None

    # ------------------------------------------------------------------ log
    def _logger(self, env, instance_name, status, category, message) -> None:
        line = f"[{STATUS[status] if 0 <= status < len(STATUS) else status}] " \
               f"{(category or b'').decode('utf-8', 'replace')}: {(message or b'').decode('utf-8', 'replace')}"
        self.log.append(line)
        self.all_log.append(line)

    def last_log(self, n: int = 3) -> str:
        lines = [ln for ln in list(self.log)[-n:]]
        return " | ".join(" ".join(ln.split()) for ln in lines) if lines else "(the FMU logged nothing)"

    # ------------------------------------------------------------------ life cycle
    def fail_status(self, what: str, status: int, t: float | None) -> RunError:
        if status == FATAL:
            self.fatal = True
        at = f" at t = {t:.6g} s" if t is not None else ""
        return RunError(f"{self.name}: {what} returned {STATUS[status] if 0 <= status < 6 else status}{at}; "
                        f"last log: {self.last_log()}", self.name, t)

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
        self.call("fmi2Instantiate", self.fmu.instantiate, False, self._callbacks, True)
        self.c = self.fmu.component  # the stepping loop calls the library through stepper.raw()

    def set_values(self, pairs: list[tuple[Variable, Any]]) -> None:
        """Set start values / parameters by type."""
        for var, value in pairs:
            vr = [var.vr]
            if var.type == "Real":
                self.call(f"fmi2SetReal({var.name})", self.fmu.setReal, vr, [float(value)])
            elif var.type in ("Integer", "Enumeration"):
                self.call(f"fmi2SetInteger({var.name})", self.fmu.setInteger, vr, [int(value)])
            elif var.type == "Boolean":
                self.call(f"fmi2SetBoolean({var.name})", self.fmu.setBoolean, vr, [bool(value)])
            elif var.type == "String":
                self.call(f"fmi2SetString({var.name})", self.fmu.setString, vr, [str(value)])

    def shutdown(self) -> None:
        """Terminate (if initialised) and free, exactly once; nothing at all after a Fatal."""
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


def real_array(values) -> Any:
    """A ctypes fmi2Real array of the values."""
    values = list(values)
    return (fmi2Real * len(values))(*values)


def vr_array(vrs) -> Any:
    vrs = list(vrs)
    return (fmi2ValueReference * len(vrs))(*vrs)
