"""An isolated instance (isolate = true: a child process) whose FMU ends the simulation ends the run exactly
as the same FMU in process does: the same status, message, end time, steps and rows, bit for bit; the last
row holds the FMU's outputs after the step that ended it (not the step before's), also where they reach
another instance.  The FMU is the Ramp test model (tests/c_fmus/ramp/, x = 1 + 2 t here) ending the
simulation at a time event at T_stop = 0.255 s, inside the step from 0.25 s: FMI 3.0 co-simulation
(terminateSimulation from fmi3DoStep), FMI 2.0 and 3.0 model exchange (terminateSimulation from the event
update) and FMI 2.0 co-simulation (Discard, fmi2Terminated).  The outputs cross the control channel only
before stepping and after such a step: never after an OK step (docs/isolation.md)."""
from __future__ import annotations

import collections
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from c_fmu_support import build_ramp
from reference_fmus import REF
from wmr_cosim import cosim
from wmr_cosim.cosim.instances import isolation

T_STOP = 0.255
SLOPE = 2.0
X0 = 1.0


@pytest.fixture(scope="module")
def ramps(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    out = tmp_path_factory.mktemp("ramps")
    return {v: build_ramp(out, v) for v in (2, 3)}


def _document(fmu: Path, interface: str, isolate: bool, algorithm: str = "gauss-seidel",
              workers: int = 1) -> dict[str, Any]:
    """The ramp feeding a Feedthrough, both isolated or neither, 0.5 s of 10 ms steps."""
    ramp: dict[str, Any] = {"fmu": str(fmu), "interface": interface, "isolate": isolate,
                            "parameters": {"s": SLOPE, "T_stop": T_STOP, "x": X0}}
    return {"experiment": {"start": 0.0, "stop": 0.5, "step": 0.01, "algorithm": algorithm, "workers": workers},
            "instances": {"r": ramp, "ft": {"fmu": str(REF / "fmi2" / "Feedthrough.fmu"), "isolate": isolate}},
            "connections": [{"from": "r.x", "to": "ft.Float64_continuous_input"}],
            "record": {"variables": ["r.x", "r.crossings", "ft.Float64_continuous_output"]}}


def _run(doc: dict[str, Any], out: Path) -> tuple[cosim.RunResult, np.ndarray, dict[str, Any]]:
    res = cosim.run(cosim.resolve(cosim.parse(doc, "ramp.toml")), out, progress=False)
    return res, np.load(out / "signals.npy"), json.loads((out / "summary.json").read_text())


# (FMI version, interface, the time the run ends at, steps done): co-simulation in FMI 2.0 ends at the
# FMU's last successful time with a row of its own; the others after the step's row at 0.26 s
CASES = [(3, "co-simulation", 0.26, 26), (3, "model-exchange", 0.26, 26), (2, "model-exchange", 0.26, 26),
         (2, "co-simulation", T_STOP, 25)]


@pytest.mark.parametrize("version, interface, t_end, steps", CASES)
def test_an_isolated_fmu_ending_the_simulation_ends_the_run_as_in_process(ramps, tmp_path, version, interface,
                                                                          t_end, steps):
    res0, rows0, sum0 = _run(_document(ramps[version], interface, False), tmp_path / "in_process")
    res1, rows1, sum1 = _run(_document(ramps[version], interface, True), tmp_path / "isolated")
    message = f"terminated by FMU r at t = {t_end:g} s"
    for res, summary in ((res0, sum0), (res1, sum1)):
        assert (res.status, res.message, res.t_end, res.steps) == ("terminated", message, t_end, steps)
        assert (summary["status"], summary["message"], summary["t_end"], summary["steps"], summary["rows"]) == \
            ("terminated", message, t_end, steps, steps + 2 if interface == "co-simulation" and version == 2
             else steps + 1)
    assert rows1.dtype == rows0.dtype and rows1.tobytes() == rows0.tobytes()
    assert sum1["final"] == sum0["final"]
    # the first row: the initialised system (the Feedthrough's input from the ramp's start); the last: the
    # ramp's output after the step that ended the simulation, and the Feedthrough's input from it (x = 1 + 2 t
    # at T_STOP: 1.51, not the 1.5 of the step before)
    assert rows1[0]["r.x"] == rows1[0]["ft.Float64_continuous_output"] == X0
    last = rows1[-1]
    assert last["time"] == t_end
    assert last["r.x"] == pytest.approx(X0 + SLOPE * T_STOP, abs=1e-12)
    assert rows1["r.x"][-2] == pytest.approx(X0 + 0.5, abs=1e-12)
    if not (interface == "co-simulation" and version == 2):   # (there the Feedthrough did not step to T_STOP)
        assert last["ft.Float64_continuous_output"] == last["r.x"]


@pytest.mark.parametrize("version, interface, t_end, steps", CASES)
def test_outputs_cross_the_control_channel_only_before_stepping_and_after_the_end(ramps, tmp_path, monkeypatch,
                                                                                  version, interface, t_end, steps):
    """Each isolated instance's outputs are asked for on the control channel while initialising, then
    never while its steps are OK (the child writes them into the step slot), and once after the step in
    which the ramp ended the simulation (it did not write them then).  (The Python child: the C child asks
    for them on the slot, next test.)"""
    monkeypatch.setenv("WMR_COSIM_CHILD", "python")
    asked: collections.Counter[str] = collections.Counter()
    call = isolation.Child.call

    def counted(self: isolation.Child, op: str, *args: Any) -> Any:
        if op == "get_outputs":
            asked[self.name] += 1
        return call(self, op, *args)
    monkeypatch.setattr(isolation.Child, "call", counted)
    plan = cosim.resolve(cosim.parse(_document(ramps[version], interface, True), "ramp.toml"))
    ex = cosim.Execution(plan, tmp_path / "out")
    ex.initialize()
    try:
        initial = dict(asked)
        assert initial["r"] >= 1 and initial["ft"] >= 1
        assert ex.simulate_until(0.2) == "ok" and asked == initial      # 20 OK steps: nothing asked
        assert ex.simulate_until(0.5) == "terminated"
        assert (ex.message, ex.k_done) == (f"terminated by FMU r at t = {t_end:g} s", steps)
        assert asked == {"r": initial["r"] + 1, "ft": initial["ft"]}
    finally:
        ex.close()


@pytest.mark.parametrize("version, t_end, steps", [(3, 0.26, 26), (2, T_STOP, 25)])
def test_the_c_child_asks_for_outputs_only_before_stepping_and_after_the_end(ramps, tmp_path, version, t_end, steps):
    """The C child (co-simulation): after the first step, the master's requests on the slot are the steps
    alone while they are OK (the outputs come with each), one more after the step in which the ramp ended
    the simulation."""
    plan = cosim.resolve(cosim.parse(_document(ramps[version], "co-simulation", True), "ramp.toml"))
    ex = cosim.Execution(plan, tmp_path / "out")
    ex.initialize()
    try:
        sides = {n: i.child.c_side for n, i in ex.instances.items()}
        assert all(s is not None for s in sides.values()), "no C child here"
        assert ex.simulate_until(0.01) == "ok"
        initial = {n: s.p.seq for n, s in sides.items()}
        assert ex.simulate_until(0.2) == "ok"
        assert {n: s.p.seq - initial[n] for n, s in sides.items()} == {"r": 19, "ft": 19}   # the steps alone
        assert ex.simulate_until(0.5) == "terminated"
        assert (ex.message, ex.k_done) == (f"terminated by FMU r at t = {t_end:g} s", steps)
        # r's 26th step ended it and its outputs were asked for then: FMI 3.0 after ft's 26th step, FMI 2.0
        # after a Discard (no step of ft after it)
        expected = {"r": 25 + 1, "ft": 25 if version == 3 else 24}
        assert {n: s.p.seq - initial[n] for n, s in sides.items()} == expected
    finally:
        ex.close()


def test_an_isolated_fmu_ending_the_simulation_while_others_step_at_once(ramps, tmp_path):
    """Jacobi with two isolated ramps stepped at once (workers = 2): the rows of the serial Jacobi run in
    process, ended by the FMI 3.0 ramp's terminateSimulation."""
    doc = _document(ramps[3], "co-simulation", True, "jacobi", 2)
    doc["instances"]["r2"] = {**doc["instances"]["r"], "parameters": {"s": -1.0}}
    doc["record"]["variables"].append("r2.x")
    res1, rows1, sum1 = _run(doc, tmp_path / "parallel")
    assert sum1["stepping"]["stepped_at_once"] == ["r", "ft", "r2"]
    serial = _document(ramps[3], "co-simulation", False, "jacobi", 1)
    serial["instances"]["r2"] = {**serial["instances"]["r"], "parameters": {"s": -1.0}}
    serial["record"]["variables"].append("r2.x")
    res0, rows0, sum0 = _run(serial, tmp_path / "serial")
    assert (res1.status, res1.message, res1.t_end) == (res0.status, res0.message, res0.t_end) == \
        ("terminated", "terminated by FMU r at t = 0.26 s", 0.26)
    assert rows1.tobytes() == rows0.tobytes()
    assert rows1["r.x"][-1] == pytest.approx(X0 + SLOPE * T_STOP, abs=1e-12)


@pytest.mark.parametrize("interface", ["co-simulation", "model-exchange"])
def test_the_isolated_fast_path_gives_the_fmus_last_successful_time(ramps, tmp_path, interface):
    """FMI 3.0: after the step that ended the simulation the isolated fast path says so with the FMU's own
    last successful time, as in process (co-simulation: the FMU's internal time, T_STOP; model exchange:
    the time event's)."""
    seen = {}
    for isolate in (False, True):
        plan = cosim.resolve(cosim.parse(_document(ramps[3], interface, isolate), "ramp.toml"))
        ex = cosim.Execution(plan, tmp_path / f"iso_{isolate}")
        ex.initialize()
        try:
            assert ex.simulate_until(0.5) == "terminated"
            fast = ex.ios[plan.order.index("r")].fast
            assert fast.terminated is not None and fast.terminated.value
            assert fast.last_time is not None
            seen[isolate] = fast.last_time.value
        finally:
            ex.close()
    assert seen[True] == seen[False] == pytest.approx(T_STOP, abs=1e-9)
