"""The FMI 3.0 sensor and controller declare their 2 ms as a periodic input clock ``sample`` and, instantiated
with eventModeUsed = true, sample only at its ticks: ticked every 2 ms and stepped every 0.5 ms (FMPy's
low-level FMU3Slave), their outputs are bit for bit those of the fixed-step 2 ms run of the same FMU, and
hold between ticks.  What an importer gets wrong (a step past a tick, a mistimed tick, a clock set without
event mode) is refused with its logged cause."""
from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave

from wmr_cosim.cosim.model.clocks import read_clocks

H = 0.002        # the clock's interval [s]
SUB = 4          # communication steps per tick in event mode (0.5 ms)
N = 400          # ticks (0.8 s)
#: The clock's value reference in each FMU (after every variable's).
CLOCK_VR = {"WmrSensor3": 19, "WmrController3": 90}


@pytest.fixture(scope="session")
def fmus3(tmp_path_factory):
    """The three FMI 3.0 FMUs built once per session: {model name: path}."""
    from wmr_cosim.fmus.build import SLAVES3, build_all

    from conftest import fmu_cache

    return build_all(fmu_cache(tmp_path_factory, "fmus3"), models=tuple(SLAVES3))


class _Run:
    """One instance of ``model`` and what the tests read and set: the Float64 inputs, the outputs by type,
    the clock's value reference, the log."""

    def __init__(self, path: Path, tmp: Path, event_mode: bool) -> None:
        self.md = md = read_model_description(str(path))
        d = extract(str(path), unzipdir=str(tmp / f"{md.modelName}_{event_mode}"))
        self.log: list[tuple[int, str]] = []
        self.fmu = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName="inst")
        self.fmu.instantiate(loggingOn=True, eventModeUsed=event_mode,
                             logMessage=lambda env, st, cat, msg: self.log.append((st, msg.decode())))
        self.ins = [v.valueReference for v in md.modelVariables if v.causality == "input" and v.type == "Float64"]
        outs = [v for v in md.modelVariables if v.causality == "output"]
        self.f64 = [v.valueReference for v in outs if v.type == "Float64"]
        self.n64 = sum(math.prod(int(x.start) for x in v.dimensions) if v.dimensions else 1
                       for v in outs if v.type == "Float64")
        self.i32 = [v.valueReference for v in outs if v.type == "Int32"]
        self.b = [v.valueReference for v in outs if v.type == "Boolean"]
        self.clock = [v.valueReference for v in md.modelVariables if v.type == "Clock"]

    def outputs(self) -> tuple[Any, ...]:
        f = self.fmu
        return (tuple(f.getFloat64(self.f64, nValues=self.n64)), tuple(f.getInt32(self.i32) if self.i32 else ()),
                tuple(f.getBoolean(self.b) if self.b else ()))

    def start(self, u: list[float]) -> None:
        self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.setFloat64(self.ins, u)
        self.fmu.exitInitializationMode()

    def tick(self, u: list[float]) -> tuple[Any, ...]:
        """In Event Mode: the clock set, the inputs, fmi3UpdateDiscreteStates, the outputs read."""
        f = self.fmu
        f.setClock(self.clock, [True])
        f.setFloat64(self.ins, u)
        assert f.updateDiscreteStates()[:2] == (False, False)   # no further update, no termination
        return self.outputs()

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


def _inputs(n: int, t: float) -> list[float]:
    """Inputs at time t [s] that move the outputs (angles a few radians, speeds of order 1)."""
    return [0.3 * math.sin(3.0 * t + j) + 0.4 * t + 0.1 * j for j in range(n)]


def _fixed(path: Path, tmp: Path) -> list[tuple[Any, ...]]:
    """The fixed-step run (eventModeUsed = false): the outputs after initialisation, then after every 2 ms step."""
    r = _Run(path, tmp, False)
    n = len(r.ins)
    r.start(_inputs(n, 0.0))
    rows = [r.outputs()]
    for k in range(N):
        r.fmu.setFloat64(r.ins, _inputs(n, (k + 1) * H))
        r.fmu.doStep(k * H, H)
        rows.append(r.outputs())
    r.close()
    return rows


@pytest.mark.parametrize("model", ["WmrSensor3", "WmrController3"])
def test_ticked_every_2ms_and_stepped_every_half_ms_equals_the_fixed_step_run(model, fmus3, tmp_path):
    """Event mode: the tick at the start time (its inputs those the fixed-step run was initialised with),
    then every 2 ms a tick in Event Mode and four 0.5 ms steps between ticks: the outputs at every tick
    equal the fixed-step run's bit for bit, and between ticks they hold (read after every 0.5 ms step)."""
    fixed = _fixed(fmus3[model], tmp_path)
    r = _Run(fmus3[model], tmp_path, True)
    n = len(r.ins)
    f = r.fmu
    r.start([0.0] * n)                  # initialised from other inputs: the tick at the start time samples
    rows = [r.tick(_inputs(n, 0.0))]    # (after fmi3ExitInitializationMode the instance is in Event Mode)
    f.enterStepMode()
    i = 0
    dt = H / SUB
    for k in range(N):
        for _ in range(SUB):
            f.doStep(i * dt, dt)
            i += 1
            assert r.outputs() == rows[-1]      # between ticks the outputs hold (the last step ends at the tick)
        f.enterEventMode()
        rows.append(r.tick(_inputs(n, (k + 1) * H)))
        f.enterStepMode()
    r.close()
    assert len(rows) == len(fixed) == N + 1
    assert rows == fixed
    assert fixed[1] != fixed[-1] and fixed[-2] != fixed[-1]   # the outputs moved, to the end


def test_a_read_of_an_output_takes_the_sample_before_update_discrete_states(fmus3, tmp_path):
    """The sample due at a tick is taken by the first read of an output when it comes before
    fmi3UpdateDiscreteStates (which then takes none); ticks in any order give the same outputs."""
    path = fmus3["WmrSensor3"]
    fixed = _fixed(path, tmp_path)
    r = _Run(path, tmp_path, True)
    f = r.fmu
    n = len(r.ins)
    r.start(_inputs(n, 0.0))
    f.enterStepMode()                   # (no tick at the start time: it is optional)
    rows = [r.outputs()]
    for k in range(N):
        f.doStep(k * H, H)              # a step of the clock's interval, ending at the tick
        f.enterEventMode()
        f.setFloat64(r.ins, _inputs(n, (k + 1) * H))
        f.setClock(r.clock, [True])
        if k == 0:
            assert list(f.getClock(r.clock)) == [True]   # (fmi3GetClock: the clock is active)
        rows.append(r.outputs())
        f.updateDiscreteStates()
        assert r.outputs() == rows[-1]
        f.enterStepMode()
    r.close()
    assert rows == fixed


def test_a_step_past_the_tick_then_a_mistimed_tick_are_refused(fmus3, tmp_path):
    """A step past the next tick: fmi3Discard; a tick that is not 2 ms after the last sample: fmi3Error
    from fmi3UpdateDiscreteStates, both with their logged cause; after the tick every step is refused."""
    r = _Run(fmus3["WmrController3"], tmp_path / "a", True)
    f = r.fmu
    n = len(r.ins)
    r.start(_inputs(n, 0.0))
    f.enterStepMode()
    f.doStep(0.0, 0.0015)
    with pytest.raises(FMICallException) as exc:
        f.doStep(0.0015, 0.001)         # would pass the tick at 2 ms
    assert exc.value.status == 2
    assert r.log[-1][0] == 2 and "passes the tick of clock sample at t = 0.002 s" in r.log[-1][1]
    f.enterEventMode()                  # a tick at 1.5 ms
    f.setClock(r.clock, [True])
    with pytest.raises(FMICallException) as exc:
        f.updateDiscreteStates()
    assert exc.value.status == 3
    assert r.log[-1][0] == 3 and "clock ticks every 0.002 s" in r.log[-1][1] and "t = 0.0015 s" in r.log[-1][1]
    f.enterStepMode()
    with pytest.raises(FMICallException) as exc:
        f.doStep(0.0015, 0.0005)        # every later step is refused
    assert exc.value.status == 2 and "an earlier step failed" in r.log[-1][1]


def test_a_clock_set_without_event_mode_is_fatal(fmus3, tmp_path):
    r = _Run(fmus3["WmrSensor3"], tmp_path / "b", False)
    r.start(_inputs(len(r.ins), 0.0))
    with pytest.raises(FMICallException) as exc:
        r.fmu.setClock(r.clock, [True])
    assert exc.value.status == 4
    assert any(st == 4 and "eventModeUsed = false" in m for st, m in r.log)
    # after fmi3Fatal the instance is left alone (not freed), as the failure rules say


def test_the_model_descriptions_declare_the_clock(fmus3):
    """Our reader of clocks: one periodic input clock ``sample`` of 2 ms in the sensor and the controller,
    clocking every input and output; the plant has none.  hasEventMode on their CoSimulation."""
    for model, vr in CLOCK_VR.items():
        md = read_model_description(str(fmus3[model]))
        clocks = read_clocks(fmus3[model])
        assert [(c.name, c.vr, c.causality, c.variability, c.interval) for c in clocks] == [
            ("sample", vr, "input", "constant", "0.002")]
        assert clocks[0].periodic and clocks[0].shift is None
        sampled = {v.name for v in md.modelVariables if v.causality in ("input", "output") and v.type != "Clock"}
        assert set(clocks[0].clocked) == sampled and len(sampled) == (10 if model == "WmrSensor3" else 38)
        assert md.coSimulation.hasEventMode and not md.coSimulation.canHandleVariableCommunicationStepSize
    assert read_clocks(fmus3["WmrPlant3"]) == []
    assert not read_model_description(str(fmus3["WmrPlant3"])).coSimulation.hasEventMode


def test_event_mode_survives_reset_and_the_fmu_state_holds_the_clock(fmus3, tmp_path):
    """After fmi3Reset the instance still samples only at ticks (our loader tells the new slave
    eventModeUsed again); a state saved in Event Mode with the clock set and restored takes the same sample."""
    path = fmus3["WmrController3"]
    fixed = _fixed(path, tmp_path)
    r = _Run(path, tmp_path / "r", True)
    f = r.fmu
    n = len(r.ins)
    r.start(_inputs(n, 0.0))
    f.enterStepMode()
    f.doStep(0.0, H / 2)
    f.reset()
    r.start(_inputs(n, 0.0))
    f.enterStepMode()
    rows = [r.outputs()]
    for k in range(N // 4):
        f.doStep(k * H, H / 2)
        f.doStep(k * H + H / 2, H / 2)
        f.enterEventMode()
        f.setClock(r.clock, [True])
        f.setFloat64(r.ins, _inputs(n, (k + 1) * H))
        if k == 20:
            state = f.getFMUState()
            f.updateDiscreteStates()
            first = r.outputs()
            f.setFMUState(state)        # the clock active again, the sample not yet taken
            f.freeFMUState(state)
        f.updateDiscreteStates()
        rows.append(r.outputs())
        if k == 20:
            assert rows[-1] == first
        f.enterStepMode()
    r.close()
    assert rows == fixed[:len(rows)]


#: A process that runs the clock's calls through our loader on each FMU: instantiation with eventModeUsed,
#: the tick at the start time, five ticks, fmi3Reset, a step, free.
_EVENT_MODE_CALLS = """
import sys, shutil
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave
for path in sys.argv[1:]:
    md = read_model_description(path)
    d = extract(path)
    s = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
    s.instantiate(eventModeUsed=True)
    clk = [v.valueReference for v in md.modelVariables if v.type == "Clock"]
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    s.setClock(clk, [True])
    assert list(s.getClock(clk)) == [True]
    s.updateDiscreteStates()
    s.enterStepMode()
    for k in range(5):
        s.doStep(k * 0.002, 0.002)
        s.enterEventMode()
        s.setClock(clk, [True])
        s.updateDiscreteStates()
        s.enterStepMode()
    s.reset()
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    s.doStep(0.0, 0.001)
    s.terminate()
    s.freeInstance()
    shutil.rmtree(d)
print("done")
"""


@pytest.mark.slow
def test_the_clock_calls_through_our_loader_have_no_invalid_access_under_valgrind(fmus3, tmp_path):
    """fmi3SetClock, fmi3GetClock, fmi3UpdateDiscreteStates and fmi3Reset of an instance with eventModeUsed
    (the loader's own paths) under ``PYTHONMALLOC=malloc valgrind``: no invalid access, exit 0."""
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        pytest.skip("valgrind not installed")
    supp = tmp_path / "ldso.supp"   # (the dynamic loader's false positive, as in test_pythonfmu_defects)
    supp.write_text("{\n   ld.so is_dst strncmp word over-read\n   Memcheck:Addr8\n   fun:strncmp\n   fun:is_dst\n}\n")
    log = tmp_path / "valgrind.log"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(TMPDIR=str(tmp_path), PYTHONMALLOC="malloc")
    p = subprocess.run([valgrind, "--quiet", f"--suppressions={supp}", f"--log-file={log}", sys.executable, "-c",
                        _EVENT_MODE_CALLS, str(fmus3["WmrSensor3"]), str(fmus3["WmrController3"])],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=1200)
    text = log.read_text()
    assert p.returncode == 0 and p.stdout.strip() == "done", p.stderr[-3000:]
    invalid = [m.start() for m in re.finditer(r"Invalid (read|write|free)", text)]
    assert not invalid, "\n".join(text[i:i + 900] for i in invalid[:3])
