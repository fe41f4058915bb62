"""Our FMU loader's direct path (fmus/pyloader/wmr_pyloader.c): fmi2SetReal, fmi2DoStep and fmi2GetReal
reach the slave's Python methods without pythonfmu's binary, the inputs' sets held until the slave's next
call and the outputs of a step cached until the next call.  Every FMI call sequence must give what
pythonfmu's binary alone gives: each test drives one instance of our FMU and one of the same FMU whose
binary is pythonfmu's own (libpythonfmu-export.so in place of our loader) through the same calls, and
compares every value, status and log message."""
from __future__ import annotations

import gc
import math
import shutil
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any, Callable

import pytest

import fmu_support
from fmu_support import FMICallException, Fmu, H, INPUTS
from wmr_cosim.fmus.build import REAL_BINARY

MODELS = ["WmrPlant", "WmrSensor", "WmrController"]


def pythonfmus_own(path: Path, name: str, where: Path, monkeypatch: pytest.MonkeyPatch) -> Fmu:
    """An instance of the FMU at ``path`` whose binary is pythonfmu's (no loader, no direct path)."""
    real_extract = fmu_support.extract

    def extract_and_swap(fmu: str, unzipdir: str | None = None) -> str:
        d = Path(real_extract(fmu, unzipdir=unzipdir))
        binaries = d / "binaries" / "linux64"
        model = next(p for p in binaries.glob("*.so") if p.name != REAL_BINARY)
        shutil.copy(binaries / REAL_BINARY, model)
        return str(d)
    with monkeypatch.context() as m:
        m.setattr(fmu_support, "extract", extract_and_swap)
        f = Fmu(path, name, where)
    f.fmu.dll.finalizePythonInterpreter()   # its PyState owns nothing: none to free at exit (wmr_pyfinder.h)
    return f


def slave_of(name: str) -> Any:
    """The Python slave object of the instance named ``name`` (constructed in this process)."""
    found = [o for o in gc.get_objects() if any(c.__name__ == "WmrSlave" for c in type(o).__mro__)
             and o.instance_name == name]
    assert len(found) == 1, found
    return found[0]


def counting(slave: Any, names: tuple[str, ...]) -> dict[str, int]:
    """Count the calls of the slave's methods ``names`` (instance attributes over the class's)."""
    counts = dict.fromkeys(names, 0)
    for n in names:
        method = getattr(slave, n)

        def wrapped(*a: Any, _m: Callable = method, _n: str = n) -> Any:
            counts[_n] += 1
            return _m(*a)
        setattr(slave, n, wrapped)
    return counts


def inputs(model: str, t: float) -> list[float]:
    n = len(INPUTS[model])
    return [0.3 * (i + 1) * math.sin((i + 2) * t) + 0.5 * t for i in range(n)]


def drive(f: Fmu, model: str) -> list[Any]:
    """A long and varied sequence of FMI calls; every outcome (values or the status raised) in order."""
    out: list[Any] = []
    fmu = f.fmu

    def call(label: str, fn: Callable, *args: Any) -> Any:
        try:
            r = fn(*args)
        except FMICallException as exc:
            out.append((label, "status", int(exc.status)))
            return None
        out.append((label, r if not isinstance(r, list) else [float(x) for x in r]))
        return r

    md = f.md
    ins = f.vrs(INPUTS[model])
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    other = [(v.type, v.valueReference) for v in md.modelVariables if v.causality == "output" and v.type != "Real"]
    param = next(v for v in md.modelVariables if v.causality == "parameter" and v.type == "Real")
    tunable = next((v for v in md.modelVariables if v.causality == "parameter" and v.type == "Real"
                    and v.variability == "tunable"), None)
    call("setup", fmu.setupExperiment, None, 0.0)
    call("set param", fmu.setReal, [param.valueReference], [float(param.start)])
    call("get param", fmu.getReal, [param.valueReference])
    call("enter", fmu.enterInitializationMode)
    call("get in init", fmu.getReal, outs)
    call("set in init", fmu.setReal, ins, inputs(model, 0.0))
    call("get inputs in init", fmu.getReal, ins)
    call("get in init after set", fmu.getReal, outs)
    call("set one in init", fmu.setReal, ins[:1], [0.25])
    call("get some in init", fmu.getReal, outs[:3])
    call("exit", fmu.exitInitializationMode)
    state = None
    for k in range(60):
        t = k * H
        if k % 7 == 3:
            call("get before set", fmu.getReal, outs)
        if k % 6 == 5:   # the inputs in another order, or some of them only
            call("set reversed", fmu.setReal, ins[::-1], inputs(model, t)[::-1])
        elif k % 6 == 4:
            call("set every other", fmu.setReal, ins[::2], inputs(model, t)[::2])
        else:
            call("set", fmu.setReal, ins, inputs(model, t))
        if k % 5 == 1:
            call("set again", fmu.setReal, ins[:1] + ins[:1], [1.5, -0.5])
        if k % 11 == 2:
            call("get inputs", fmu.getReal, ins)
        if k % 13 == 6 and tunable is not None:
            call("set tunable", fmu.setReal, [tunable.valueReference], [float(tunable.start)])
        call("step", fmu.doStep, t, H)
        call("get", fmu.getReal, outs)
        if k % 3 == 0:
            call("get again", fmu.getReal, outs)
        if k % 4 == 1:
            call("get reversed", fmu.getReal, outs[::-1])
            call("get after another get", fmu.getReal, outs)
        if k % 9 == 4:
            for kind, vr in other:
                call(f"get {kind}", fmu.getInteger if kind == "Integer" else fmu.getBoolean, [vr])
        if k == 20:
            state = fmu.getFMUstate()
        if k == 40:
            call("set state", fmu.setFMUstate, state)
            call("get after set state", fmu.getReal, outs)
        call("last time", fmu.getRealStatus, 2)   # fmi2LastSuccessfulTime
    fmu.freeFMUstate(state)
    call("set before refused step", fmu.setReal, ins, inputs(model, 1.0))
    call("refused step", fmu.doStep, 60 * H, -1.0)
    call("get after refused step", fmu.getReal, outs)
    call("terminated", fmu.getBooleanStatus, 3)     # fmi2Terminated
    call("last time after refused step", fmu.getRealStatus, 2)
    call("step after refused step", fmu.doStep, 61 * H, H)
    call("reset", fmu.reset)
    call("setup again", fmu.setupExperiment, None, 0.0)
    call("enter again", fmu.enterInitializationMode)
    call("exit again", fmu.exitInitializationMode)
    for k in range(5):
        call("set after reset", fmu.setReal, ins, inputs(model, 2.0 * k * H))
        call("step after reset", fmu.doStep, k * H, H)
        call("get after reset", fmu.getReal, outs)
    call("terminate", fmu.terminate)
    return out


@pytest.mark.parametrize("model", MODELS)
def test_every_call_gives_what_pythonfmus_binary_gives(built_fmus, model, tmp_path, monkeypatch):
    """The same sequence of calls (gets before and after steps, sets between, repeated and partial sets,
    parameters, initialization mode, other types, FMU state, a refused step, reset) on our FMU and on it
    with pythonfmu's binary: the same values, statuses and log messages; and ours took the direct path."""
    loader = ("_loader_step", "_loader_get_real", "_loader_set_real")
    runs = {}
    for who in ("direct", "pythonfmu"):   # one after the other: FMPy's logger proxy serves one instance
        name = f"{who}-{model}"
        f = (Fmu(built_fmus[model], name, tmp_path / who) if who == "direct" else
             pythonfmus_own(built_fmus[model], name, tmp_path / who, monkeypatch))
        try:
            counts = counting(slave_of(name), loader)
            runs[who] = (drive(f, model), [(s, c, m.replace(name, "inst")) for s, c, m in f.log], counts)
        finally:
            f.free()
    (a, log_a, direct), (b, log_b, through_pythonfmu) = runs["direct"], runs["pythonfmu"]
    assert a == b
    assert log_a == log_b
    assert any("refused" in m or "failed" in m for _, _, m in log_a)
    # (62 steps before the reset, which constructs a new slave)
    assert direct["_loader_step"] == 62 and direct["_loader_get_real"] > 0 and direct["_loader_set_real"] > 0
    assert set(through_pythonfmu.values()) == {0}


def test_instances_stepped_on_threads_give_what_they_give_one_after_another(built_fmus, tmp_path):
    """Four instances of the controller stepped at once on four threads (sets, steps and gets
    interleaved by the GIL) give the outputs they give stepped one after another."""
    model = "WmrController"

    def run(name: str, scale: float, results: dict[str, list[Any]]) -> None:
        f = Fmu(built_fmus[model], name, tmp_path / name)
        try:
            f.init()
            outs = [v.valueReference for v in f.md.modelVariables if v.causality == "output" and v.type == "Real"]
            rows = []
            for k in range(300):
                f.step(k * H, H, tuple(scale * x for x in inputs(model, (k + 1) * H)))
                rows.append(f.fmu.getReal(outs))
            results[name] = rows
        finally:
            f.free()
    alone: dict[str, list[Any]] = {}
    together: dict[str, list[Any]] = {}
    for i in range(4):
        run(f"alone{i}", 1.0 + 0.1 * i, alone)
    threads = [threading.Thread(target=run, args=(f"together{i}", 1.0 + 0.1 * i, together)) for i in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert all(together[f"together{i}"] == alone[f"alone{i}"] for i in range(4))
    assert alone["alone0"] != alone["alone1"]


_EXCEPTION_IN_A_STEP = r"""
import gc, sys
sys.path.insert(0, sys.argv[3])
from fmu_support import Fmu, FMICallException
from test_loader_direct import pythonfmus_own, inputs, INPUTS
import pytest
mp = pytest.MonkeyPatch()
f = Fmu(sys.argv[1], "inst", sys.argv[2] + "/" + sys.argv[4]) if sys.argv[4] == "ours" else \
    pythonfmus_own(sys.argv[1], "inst", sys.argv[2] + "/" + sys.argv[4], mp)
slave = [o for o in gc.get_objects() if any(c.__name__ == "WmrSlave" for c in type(o).__mro__)][0]
def do_step(t, h):
    if sys.argv[5] == "log":
        slave.log("about to fail")
    raise KeyboardInterrupt("in the step")
f.init()
f.fmu.setReal(f.vrs(INPUTS["WmrPlant"]), inputs("WmrPlant", 0.0))
slave.do_step = do_step
try:
    f.fmu.doStep(0.0, 0.002)
    status = 0
except FMICallException as exc:
    status = int(exc.status)
print(repr((status, f.log)))
"""


@pytest.mark.parametrize("log_first", [False, True])
def test_an_exception_out_of_a_step_is_fatal_with_pythonfmus_messages(built_fmus, tmp_path, log_first):
    """An exception out of the slave's do_step (one that is not an Exception, which WmrSlave turns into a
    Discard), with or without a message of the slave before it: Fatal, the slave's message and then
    pythonfmu's line, as pythonfmu's binary gives them (each in a child process: the instance is leaked
    after Fatal).  (pythonfmu's binary loses the exception when messages were queued before it.)"""
    tests = Path(__file__).resolve().parent
    seen = []
    for which in ("ours", "theirs"):
        p = subprocess.run([sys.executable, "-c", _EXCEPTION_IN_A_STEP, str(built_fmus["WmrPlant"]), str(tmp_path),
                            str(tests), which, "log" if log_first else "-"], capture_output=True, text=True,
                           timeout=300, cwd=tmp_path)
        assert p.returncode == 0, p.stderr[-3000:]
        seen.append(p.stdout.strip().splitlines()[-1])
    print(seen)
    assert seen[0] == seen[1]
    assert seen[0].startswith("(4, ") and "Fatal py exception encountered: [doStep] PyObject_CallMethod\\n" in seen[0]
    assert ("about to fail" in seen[0]) == log_first
