"""The compiled stepping loop (cosim/stepping/native.py, native_loop.c) against the Python loops it stands
in for: bit for bit the same recordings (Gauss-Seidel and Jacobi, FMI 2.0 and 3.0, instances at their own
rates, unit factors and offsets, discrete connections, recorded integers, tables, events, decimation, a short last step, Model
Exchange and isolated instances through callbacks, our pythonfmu FMUs in G1), the same failures with
the same rows on disk, and the Python loop, named, where there is no C compiler."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim import cosim
from wmr_cosim.cosim.stepping import native

from c_fmu_support import build_probe
from reference_fmus import REF

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(native.library()[0] is None, reason=f"no compiled loop: {native.library()[1]}")


def _both(doc: dict[str, Any], tmp_path: Path, monkeypatch, name: str = "s.toml") -> dict[str, Any]:
    """The document run through each loop: {loop: (RunResult, signals.npy bytes, signals)}."""
    out = {}
    for loop in ("python", "native"):
        monkeypatch.setenv("WMR_COSIM_LOOP", loop)
        res = cosim.run(cosim.resolve(cosim.parse(doc, name)), tmp_path / loop, progress=False)
        sig = np.load(tmp_path / loop / "signals.npy")
        out[loop] = (res, (tmp_path / loop / "signals.npy").read_bytes(), sig)
    monkeypatch.delenv("WMR_COSIM_LOOP")
    assert out["native"][0].summary["stepping"]["loop"] == native.NATIVE
    assert out["python"][0].summary["stepping"]["loop"] == f"{native.PYTHON} (WMR_COSIM_LOOP=python)"
    return out


def _same(out: dict[str, Any]) -> np.ndarray:
    (rp, bp, _), (rn, bn, sn) = out["python"], out["native"]
    assert (rn.status, rn.message, rn.steps) == (rp.status, rp.message, rp.steps)
    assert bn == bp, "signals.npy differs between the loops"
    return sn


def _chain(version: str, algorithm: str, stop: float = 1.0, step: float = 0.001) -> dict[str, Any]:
    """Dahlquist -> Feedthrough -> Feedthrough with a unit factor and an offset, an integer connection and
    recorded integers."""
    ft, dq = str(REF / version / "Feedthrough.fmu"), str(REF / version / "Dahlquist.fmu")
    return {"experiment": {"start": 0.0, "stop": stop, "step": step, "algorithm": algorithm},
            "instances": {"d": {"fmu": dq, "parameters": {"k": 0.7}}, "f1": {"fmu": ft}, "f2": {"fmu": ft}},
            "connections": [{"from": "d.x", "to": "f1.Float64_continuous_input", "factor": 2.5, "offset": -0.125},
                            {"from": "f1.Float64_continuous_output", "to": "f2.Float64_continuous_input"},
                            {"from": "f1.Int32_output", "to": "f2.Int32_input"},
                            {"from": "f2.Float64_continuous_output", "to": "f1.Float64_discrete_input"}],
            "events": [{"time": 0.3 * stop, "variable": "f1.Int32_input", "action": "override", "value": 4},
                       {"time": 0.35 * stop, "variable": "f1.Float64_tunable_parameter", "action": "set", "value": 1.5},
                       {"time": 0.5 * stop, "variable": "f2.Float64_continuous_input", "action": "bias",
                        "value": 0.25}],
            "record": {"variables": ["*.*"]}}


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_the_compiled_loop_records_what_the_python_loop_records(version, algorithm, tmp_path, monkeypatch):
    sig = _same(_both(_chain(version, algorithm), tmp_path, monkeypatch))
    assert len(sig) == 1001 and np.ptp(sig["f2.Float64_continuous_output"]) > 0


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_instances_at_their_own_rates(algorithm, tmp_path, monkeypatch):
    """f1 every 4 base steps, d every 2 (multi-rate): the same rows, steps counted alike."""
    doc = _chain("fmi2", algorithm)
    doc["instances"]["f1"]["step"] = 0.004
    doc["instances"]["d"]["step"] = 0.002
    out = _both(doc, tmp_path, monkeypatch)
    sig = _same(out)
    rates = [out[loop][0].summary["stepping"]["rates"] for loop in ("python", "native")]
    assert [{n: r["steps"] for n, r in x.items()} for x in rates] == [{"d": 500, "f1": 250, "f2": 1000}] * 2
    assert np.ptp(sig["f2.Float64_continuous_output"]) > 0


def test_decimation_and_a_short_last_step(tmp_path, monkeypatch):
    doc = _chain("fmi2", "gauss-seidel", stop=0.1005)
    doc["record"]["decimation"] = 7
    sig = _same(_both(doc, tmp_path, monkeypatch))
    assert sig["time"][-1] == 0.1005 and sig["time"][1] == 0.007


def test_tabulated_inputs(tmp_path, monkeypatch):
    table = tmp_path / "in.csv"
    table.write_text("time,f1.Float64_continuous_input,f1.Int32_input\n0,0,1\n0.05,2.5,3\n0.1,-1,7\n")
    ft = str(REF / "fmi2" / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.001}, "instances": {"f1": {"fmu": ft}},
           "inputs": {"file": str(table)}, "record": {"variables": ["*.*"]}}
    sig = _same(_both(doc, tmp_path, monkeypatch))
    assert np.ptp(sig["f1.Float64_continuous_output"]) > 0


def test_model_exchange_and_isolated_instances_step_through_callbacks(tmp_path, monkeypatch):
    doc = _chain("fmi2", "gauss-seidel", stop=0.2)
    doc["instances"]["d"]["interface"] = "model-exchange"
    doc["instances"]["f2"]["isolate"] = True
    sig = _same(_both(doc, tmp_path, monkeypatch))
    assert np.ptp(sig["d.x"]) > 0


@pytest.fixture(scope="module")
def probes(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("probes")
    return {"error": build_probe(out, "ErrorAt", ERROR_AT="0.0305"),
            "terminate": build_probe(out, "TerminateAt", TERMINATE_AT="0.0405")}


@pytest.mark.parametrize("kind,status,rate", [("error", "failed", None), ("terminate", "terminated", None),
                                              ("error", "failed", 0.002), ("terminate", "terminated", 0.002)])
def test_a_failure_ends_both_loops_alike_with_the_same_rows(kind, status, rate, probes, tmp_path, monkeypatch):
    """(``rate``: the probe at a rate of its own, the multi-rate passes)"""
    ft = str(REF / "fmi2" / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.001},
           "instances": {"f": {"fmu": ft}, "p": {"fmu": str(probes[kind]), **({"step": rate} if rate else {})}},
           "connections": [{"from": "p.y", "to": "f.Float64_continuous_input"},
                           {"from": "f.Float64_continuous_output", "to": "p.u"}],
           "record": {"variables": ["*.*"]}}
    out = _both(doc, tmp_path, monkeypatch)
    sig = _same(out)
    assert out["native"][0].status == status and 20 < len(sig) < 50


def test_a_non_finite_input_is_named_alike(tmp_path, monkeypatch):
    ft = str(REF / "fmi2" / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.001},
           "instances": {"a": {"fmu": ft}, "b": {"fmu": ft}},
           "connections": [{"from": "a.Float64_continuous_output", "to": "b.Float64_continuous_input",
                            "factor": 1e300}],
           "events": [{"time": 0.02, "variable": "a.Float64_continuous_input", "action": "override", "value": 1e10}],
           "record": {"variables": ["*.*"]}}
    out = _both(doc, tmp_path, monkeypatch)
    _same(out)
    assert out["native"][0].status == "failed" and "non-finite value inf" in out["native"][0].message


@pytest.mark.slow
def test_g1_through_our_pythonfmu_fmus_is_bit_for_bit(tmp_path, monkeypatch):
    from wmr_cosim.runner import load_plan

    out = {}
    for loop in ("python", "native"):
        monkeypatch.setenv("WMR_COSIM_LOOP", loop)
        res = cosim.run(load_plan(ROOT / "scenarios" / "g1_learn.toml", {"experiment.stop": 10.0}), tmp_path / loop,
                        progress=False)
        assert res.status == "ok", res.message
        out[loop] = (tmp_path / loop / "signals.npy").read_bytes()
    assert out["native"] == out["python"]


def test_without_a_c_compiler_the_run_takes_the_python_loop_and_says_so(tmp_path):
    """A process whose PATH has no cc: the run works, its summary names the Python loop and why."""
    ft = REF / "fmi2" / "Feedthrough.fmu"
    env = {k: v for k, v in os.environ.items() if k not in ("CC", "WMR_COSIM_LOOP")}
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    os.symlink(sys.executable, bin_dir / "python")
    env["PATH"] = str(bin_dir)
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "run", str(ft), "--out", str(tmp_path / "o"),
                        "--quiet"], capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    import json
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["stepping"]["loop"] == "Python (no C compiler (cc) on PATH)"


def test_a_unit_conversion_with_an_offset_on_a_connection(tmp_path, monkeypatch):
    """degF -> degC with the scenario's factor and offset folded in (0.5 (v - 32) 5/9 - 3), both ways round
    through the two loops."""
    from c_fmu_support import build_c_fmu
    from coupling_fmus import C_FMUS
    from test_plan_unit_offset_connections import THERMO, UNITS

    fmus = {u: build_c_fmu(C_FMUS / "affine.c", THERMO.format(name=f"Thermo_{u}", units=UNITS, unit=u), tmp_path,
                           f"Thermo_{u}") for u in ("degF", "degC")}
    doc = {"experiment": {"start": 0.0, "stop": 0.2, "step": 0.01},
           "instances": {"src": {"fmu": str(fmus["degF"]), "parameters": {"a": 0.0, "b0": 20.0, "b1": 10.0}},
                         "dst": {"fmu": str(fmus["degC"])}},
           "connections": [{"from": "src.y", "to": "dst.u", "factor": 0.5, "offset": -3.0}],
           "record": {"variables": ["src.y", "dst.u"]}}
    sig = _same(_both(doc, tmp_path, monkeypatch))
    np.testing.assert_allclose(sig["dst.u"][1:], 0.5 * (sig["src.y"][1:] - 32.0) * 5.0 / 9.0 - 3.0, rtol=1e-12)
