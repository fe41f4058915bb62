"""``wmr-cosim export-fmu`` of a scenario with timed events and input tables: the container does before each
step what the master's actuator and table feeder do (overrides, biases and resets of Real inputs and
outputs, values set on tunable parameters and on inputs of other types, a stop; the table's Real, Integer,
Boolean and String columns), and its outputs in FMPy equal ``wmr-cosim run`` bit for bit, Gauss-Seidel and
Jacobi; a stop ends the host's run at its time."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim.cli import main

from reference_fmus import REF

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
G1_EVENTS = [
    {"time": 1.0, "variable": "plant.tau_d1", "action": "override", "value": 0.3},   # an open input: held
    {"time": 1.5, "variable": "plant.tau_d1", "action": "bias", "value": 0.1},       # on the override in force
    {"time": 2.0, "variable": "plant.tau_d1", "action": "reset"},
    {"time": 2.2, "variable": "sensor.alpha_m1", "action": "bias", "value": 0.01},   # an output on connections
    {"time": 2.5, "variable": "controller.u1", "action": "override", "value": 0.2},
    {"time": 2.8, "variable": "controller.u1", "action": "override", "value": 0.1},  # a new value in place
    {"time": 3.0, "variable": "controller.u1", "action": "reset"},
    {"time": 3.1, "variable": "controller.adapt", "action": "set", "value": False},  # a tunable Boolean
    {"time": 3.2, "variable": "controller.goal_x", "action": "set", "value": 1.5},   # a tunable Real
    {"time": 3.5, "action": "stop"},
]


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, (int, float)) else f'"{value}"'


def events_toml(events: list[dict[str, Any]]) -> str:
    return "".join("[[events]]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in ev.items()) for ev in events)


def export_and_run(sc: Path, d: Path, stop: float, step: float, fmi: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The scenario's run and its container's run in FMPy (FMI 3.0: early return allowed)."""
    import fmpy

    assert main(["run", str(sc), "--out", str(d / "run"), "--quiet"]) == 0
    assert main(["export-fmu", str(sc), "--out", str(d / "S.fmu"), "--fmi", str(fmi)]) == 0
    kw = {"early_return_allowed": True} if fmi == 3 else {}
    return np.load(d / "run" / "signals.npy"), fmpy.simulate_fmu(str(d / "S.fmu"), stop_time=stop,
                                                                  output_interval=step, **kw)


@pytest.mark.parametrize("algorithm,fmi", [("gauss-seidel", 2), ("jacobi", 2), ("gauss-seidel", 3)])
def test_g1_with_timed_events_in_fmpy_equals_the_run_to_its_stop(algorithm: str, fmi: int, tmp_path: Path) -> None:
    """G1 (our three pythonfmu FMUs) with an override, a bias on it, resets, a bias on an output feeding
    connections, overrides of an output, tunable parameters set and a stop at 3.5 s (FMI 2.0: fmi2Discard
    and terminated; FMI 3.0: terminateSimulation and an early return)."""
    from fmpy import read_model_description

    sc = tmp_path / "g1.toml"
    sc.write_text(f"base = {str(SCENARIOS / 'g1_learn.toml')!r}\n[experiment]\nstop = 4.0\nalgorithm = {algorithm!r}\n"
                  + events_toml(G1_EVENTS))
    ref, got = export_and_run(sc, tmp_path, 4.0, 0.002, fmi)
    assert ref["time"][-1] == 3.5 and len(ref) == 1751
    # FMPy takes the stop (fmi2Discard, terminated, its last successful time) and samples that time again
    assert got["time"][-1] == 3.5 and len(got) == len(ref) + 1
    for name in ref.dtype.names:
        assert np.array_equal(got[name][:len(ref)], ref[name]), name
        assert np.array_equal(got[name][-1], ref[name][-1]), name
    # (the events changed the run: without them it goes on, and differs from 1 s)
    plain = tmp_path / "plain"
    sc2 = tmp_path / "plain.toml"
    sc2.write_text(f"base = {str(SCENARIOS / 'g1_learn.toml')!r}\n[experiment]\nstop = 4.0\nalgorithm = {algorithm!r}\n")
    assert main(["run", str(sc2), "--out", str(plain), "--quiet"]) == 0
    base = np.load(plain / "signals.npy")
    k = 501
    assert np.array_equal(base["plant.x_A"][:k], ref["plant.x_A"][:k])
    assert not np.array_equal(base["plant.x_A"][:len(ref)], ref["plant.x_A"])
    # an input an event drives is not the host's
    names = {v.name for v in read_model_description(str(tmp_path / "S.fmu")).modelVariables}
    assert "plant.tau_d1" not in names and "plant.tau_d2" in names


TABLE = """time,a.Float64_continuous_input,a.Float64_discrete_input,a.Int32_input,a.Boolean_input,a.String_input
0.0,0.0,1.0,1,0,x
0.3,3.0,2.0,2,1,y
0.55,-1.0,3.0,7,0,z
1.0,2.0,4.0,3,1,w
"""


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_input_tables_and_events_on_inputs_of_every_type_equal_the_run(algorithm: str, tmp_path: Path) -> None:
    """Two Reference Feedthrough FMUs: the first one's inputs from a table (a Real column linear, the others
    held; Real, Integer, Boolean and String), the second one's through a connection with a factor, a bias
    on it, an override and reset of its Boolean input, a bias on its Integer input, a tunable parameter set."""
    (tmp_path / "in.csv").write_text(TABLE)
    ft = REF / "fmi2" / "Feedthrough.fmu"
    sc = tmp_path / "t.toml"
    sc.write_text(f"""[experiment]
start = 0.0
stop = 1.0
step = 0.01
algorithm = {algorithm!r}
[instances.a]
fmu = {str(ft)!r}
[instances.b]
fmu = {str(ft)!r}
[[connections]]
from = "a.Float64_continuous_output"
to = "b.Float64_continuous_input"
factor = 2.0
[inputs]
file = "in.csv"
interpolation = {{ "a.Float64_continuous_input" = "linear" }}
[record]
variables = ["a.Float64_continuous_output", "a.Float64_discrete_output", "a.Int32_output", "a.Boolean_output",
             "b.Float64_continuous_output", "b.Int32_output", "b.Boolean_output"]
""" + events_toml([
        {"time": 0.4, "variable": "b.Float64_continuous_input", "action": "bias", "value": 0.5},
        {"time": 0.5, "variable": "b.Boolean_input", "action": "override", "value": True},
        {"time": 0.6, "variable": "b.Int32_input", "action": "bias", "value": 3},
        {"time": 0.7, "variable": "b.Float64_tunable_parameter", "action": "set", "value": 2.5},
        {"time": 0.8, "variable": "b.Boolean_input", "action": "reset"}]))
    ref, got = export_and_run(sc, tmp_path, 1.0, 0.01)
    assert sorted(got.dtype.names) == sorted(ref.dtype.names)   # (FMPy orders them by type)
    for name in ref.dtype.names:
        assert np.array_equal(got[name], ref[name]), name
    # (the table and the events are in the results: what the equality above covers)
    assert ref["a.Int32_output"][[0, 40, 70]].tolist() == [1, 2, 7]
    assert ref["b.Int32_output"][[0, 59, 61, 99]].tolist() == [0, 0, 3, 3]
    assert ref["b.Boolean_output"][[45, 55, 85]].tolist() == [False, True, False]
    assert ref["a.Float64_continuous_output"][10] == pytest.approx(0.9)   # linear: the step from 0.09 s
