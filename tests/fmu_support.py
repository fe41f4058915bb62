"""Support for the FMU tests (not a test module): drive one FMU under FMPy by variable name, capture its
log, and step the matching component directly.

Also runnable as a script in a fresh process (see test_fmu_run.py): ``python fmu_support.py DIR N``
runs the closed loop of the three FMUs in DIR for N steps and prints the recorded outputs as JSON.
"""
from __future__ import annotations

import json
import math
import shutil
import sys
import tempfile
import weakref
from ctypes import byref
from pathlib import Path
from typing import Any

from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.logging import addLoggerProxy

H = 0.002
PLANT_IN = ("u1", "u2", "tau_d1", "tau_d2")
SENSOR_IN = ("alpha1", "alpha2")
CONTROLLER_IN = ("alpha_m1", "alpha_m2", "alpha_dot_m1", "alpha_dot_m2", "x_true", "y_true", "beta_true")
INPUTS = {"WmrPlant": PLANT_IN, "WmrSensor": SENSOR_IN, "WmrController": CONTROLLER_IN}

__all__ = ["Fmu", "FMICallException", "H", "INPUTS", "closed_loop"]


class Fmu:
    """One instance of an FMU under FMPy, addressed by variable names; log messages in ``self.log``."""

    def __init__(self, path: Path, instance_name: str = "inst", unzip_dir: Path | None = None,
                 logging_on: bool = True) -> None:
        self.md = read_model_description(str(path))
        self._own_dir = unzip_dir is None
        self.dir = extract(str(path), unzipdir=None if unzip_dir is None else str(unzip_dir))
        if self._own_dir:  # removed when the instance goes, also one leaked after fmi2Fatal (at exit)
            weakref.finalize(self, shutil.rmtree, self.dir, True)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.log: list[tuple[int, str, str]] = []

        def logger(env, name, status, category, message):  # noqa: ANN001 (ctypes callback)
            self.log.append((status, (category or b"").decode(), (message or b"").decode()))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(cb))
        self._cb = cb  # keep the callbacks alive as long as the instance
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=instance_name)
        self.fmu.instantiate(callbacks=cb, loggingOn=logging_on)
        self.freed = False

    def vrs(self, names: tuple[str, ...] | list[str]) -> list[int]:
        return [self.vars[n].valueReference for n in names]

    def set(self, **values: Any) -> None:
        for name, value in values.items():
            v = self.vars[name]
            if v.type == "Real":
                self.fmu.setReal([v.valueReference], [float(value)])
            elif v.type == "Integer":
                self.fmu.setInteger([v.valueReference], [int(value)])
            elif v.type == "Boolean":
                self.fmu.setBoolean([v.valueReference], [bool(value)])
            else:
                self.fmu.setString([v.valueReference], [str(value)])

    def get(self, name: str) -> Any:
        v = self.vars[name]
        getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger, "Boolean": self.fmu.getBoolean,
                  "String": self.fmu.getString}[v.type]
        return getter([v.valueReference])[0]

    def outputs(self) -> tuple[Any, ...]:
        """All outputs in model-description order (Real as float, Integer as int, Boolean as bool)."""
        if not hasattr(self, "_out_plan"):
            outs = [v for v in self.md.modelVariables if v.causality == "output"]
            self._out_plan = {t: ([i for i, v in enumerate(outs) if v.type == t],
                                  [v.valueReference for v in outs if v.type == t]) for t in ("Real", "Integer", "Boolean")}
            self._n_out = len(outs)
        res: list[Any] = [None] * self._n_out
        for t, getter in (("Real", self.fmu.getReal), ("Integer", self.fmu.getInteger),
                          ("Boolean", self.fmu.getBoolean)):
            idx, vrs = self._out_plan[t]
            if vrs:
                for i, x in zip(idx, getter(vrs)):
                    res[i] = bool(x) if t == "Boolean" else x
        return tuple(res)

    def output_names(self) -> list[str]:
        return [v.name for v in self.md.modelVariables if v.causality == "output"]

    def init(self, start_time: float = 0.0, params: dict[str, Any] | None = None,
             inputs: dict[str, Any] | None = None) -> None:
        self.fmu.setupExperiment(startTime=start_time)
        if params:
            self.set(**params)
        self.fmu.enterInitializationMode()
        if inputs:
            self.set(**inputs)
        self.fmu.exitInitializationMode()

    def step(self, t: float, h: float, inputs: tuple[float, ...] = ()) -> None:
        if inputs:
            names = INPUTS[self.md.modelName]
            self.fmu.setReal(self.vrs(names), list(inputs))
        self.fmu.doStep(t, h)

    def free(self) -> None:
        """Terminate and free (never after fmi2Fatal: the instance is then leaked on purpose)."""
        if not self.freed:
            self.fmu.terminate()
            self.fmu.freeInstance()
            self.freed = True


def closed_loop(fmu_dir: Path, n: int, h: float = H) -> dict[str, list[float]]:
    """Gauss-Seidel plant -> sensor -> controller over n steps, as components/direct_loop.py does;
    returns every output of every FMU at every sample (n + 1 samples), names prefixed as the direct loop."""
    with tempfile.TemporaryDirectory(prefix="wmr fmu loop ") as tmp:
        p = Fmu(fmu_dir / "WmrPlant.fmu", "plant", Path(tmp) / "p")
        s = Fmu(fmu_dir / "WmrSensor.fmu", "sensor", Path(tmp) / "s")
        c = Fmu(fmu_dir / "WmrController.fmu", "controller", Path(tmp) / "c")
        rec: dict[str, list[float]] = {}
        names = {f: f.output_names() for f in (p, s, c)}
        prefix = {p: "plant", s: "sensor", c: "controller"}

        def record() -> None:
            for f in (p, s, c):
                for name, val in zip(names[f], f.outputs()):
                    rec.setdefault(f"{prefix[f]}.{name}", []).append(float(val))

        p.init()
        po = p.outputs()
        s.init(inputs={"alpha1": po[0], "alpha2": po[1]})
        so = s.outputs()
        c.init(inputs=dict(zip(CONTROLLER_IN, (*so[:4], *po[4:7]))))
        co = c.outputs()
        record()
        for k in range(n):
            t = k * h
            p.step(t, h, (co[0], co[1], 0.0, 0.0))
            po = p.outputs()
            s.step(t, h, (po[0], po[1]))
            so = s.outputs()
            c.step(t, h, (*so[:4], *po[4:7]))
            co = c.outputs()
            record()
        for f in (p, s, c):
            f.free()
    return rec


if __name__ == "__main__":
    out = closed_loop(Path(sys.argv[1]), int(sys.argv[2]))
    print(json.dumps({k: [repr(x) if not math.isfinite(x) else x for x in v] for k, v in out.items()}))
