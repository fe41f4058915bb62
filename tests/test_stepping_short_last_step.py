"""A step that does not divide the run ends it with a short last step to the stop time, as FMPy does, where
every co-simulation instance can take steps of varying length; refused at check, naming the instance,
where one cannot (our sampled-data FMUs, a third party's declaring canHandleVariableCommunicationStepSize
false)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from reference_fmus import REF
from wmr_cosim.cli import main
from wmr_cosim import cosim
from wmr_cosim.cosim.scenario.document import steps_of

BB, DQ, FT = (REF / "fmi2" / f"{m}.fmu" for m in ("BouncingBall", "Dahlquist", "Feedthrough"))
ROOT = Path(__file__).resolve().parents[1]


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_steps_of_a_run():
    assert steps_of(0.0, 1.0, 0.1) == (10, None)
    assert steps_of(0.0, 0.3, 0.1) == (3, None)           # 2.9999999999999996 steps: whole
    n, last = steps_of(0.0, 1.05, 0.1)
    assert n == 11 and last == pytest.approx(0.05, abs=1e-15) and 1.0 + last == 1.05
    n, last = steps_of(2.0, 2.25, 0.1)
    assert n == 3 and last == pytest.approx(0.05, abs=1e-15)


def _doc(stop: float, algorithm: str = "gauss-seidel", **bb: Any) -> dict[str, Any]:
    return {"experiment": {"stop": stop, "step": 0.1, "algorithm": algorithm},
            "instances": {"bb": {"fmu": str(BB), **bb}, "ft": {"fmu": str(FT)}},
            "connections": [{"from": "bb.h", "to": "ft.Float64_continuous_input"}],
            "record": {"variables": ["bb.h", "bb.v", "ft.Float64_continuous_output"]}}


def _run(doc: dict[str, Any], out: Path) -> tuple[cosim.RunResult, np.ndarray]:
    res = cosim.run(cosim.resolve(cosim.parse(doc, "short.toml")), out, progress=False)
    assert res.status == "ok", res.message
    return res, np.load(out / "signals.npy")


def test_the_last_step_reaches_the_stop_time_as_fmpys_run_does(tmp_path):
    from fmpy import simulate_fmu
    res, sig = _run(_doc(1.05), tmp_path / "o")
    ref = simulate_fmu(str(BB), stop_time=1.05, output_interval=0.1)
    assert res.steps == 11 and res.t_end == 1.05 and res.summary["last_step"] == pytest.approx(0.05)
    assert sig["time"].tolist() == ref["time"].tolist()
    assert sig["bb.h"].tolist() == ref["h"].tolist() and sig["bb.v"].tolist() == ref["v"].tolist()
    assert sig["ft.Float64_continuous_output"].tolist() == ref["h"].tolist()


@pytest.mark.parametrize("variant", ["jacobi", "isolated", "workers", "iterated", "model-exchange"])
def test_every_algorithm_and_host_takes_the_short_last_step(tmp_path, variant):
    """The compiled loop, the plain-Python stepper (iterated), an isolated child, children stepped at once,
    and a model exchange instance (the master's integrator) all end at 1.05 s; the one-pass ones with the
    rows of Gauss-Seidel's or Jacobi's compiled loop, bit for bit."""
    if variant == "model-exchange":   # against the same instance over whole steps of 0.05 s
        me = {"fmu": str(BB), "solver": "cvode", "tolerance": 1e-10}
        res, sig = _run({**_doc(1.05), "instances": {"bb": me, "ft": {"fmu": str(FT)}}}, tmp_path / "me")
        whole = {**_doc(1.05), "instances": {"bb": me, "ft": {"fmu": str(FT)}}}
        whole["experiment"] = {**whole["experiment"], "step": 0.05}
        _, ref = _run(whole, tmp_path / "me_whole")
        assert res.steps == 11 and sig["time"][-1] == ref["time"][-1] == 1.05
        assert abs(sig["bb.h"][-1] - ref["bb.h"][-1]) < 1e-7 and abs(sig["bb.v"][-1] - ref["bb.v"][-1]) < 1e-6
        return
    algorithm = {"jacobi": "jacobi", "isolated": "gauss-seidel", "workers": "jacobi", "iterated": "iterated"}[variant]
    doc = _doc(1.05, algorithm, isolate=variant in ("isolated", "workers"))
    if variant == "workers":
        doc["experiment"]["workers"] = 2
    _, sig = _run(doc, tmp_path / "v")
    _, ref = _run(_doc(1.05, "jacobi" if algorithm == "jacobi" else "gauss-seidel"), tmp_path / "r")
    assert sig["time"][-1] == 1.05
    assert sig.tobytes() == ref.tobytes()


def test_the_step_size_control_ends_at_the_stop_time(tmp_path):
    doc = {"experiment": {"stop": 1.05, "step": 0.1, "algorithm": "adaptive"}, "instances": {"dq": {"fmu": str(DQ)}},
           "record": {"variables": ["dq.x"]}}
    res, sig = _run(doc, tmp_path / "a")
    assert res.steps == 11 and sig["time"][-1] == 1.05 and len(sig) == 12


def test_g1_with_a_stop_off_the_grid_is_refused_naming_the_sensor(capsys):
    assert main(["check", str(ROOT / "scenarios" / "g1_learn.toml"), "--stop", "1.001"]) == 2
    err = _one_line(capsys)
    assert "experiment.stop" in err and "sensor" in err and "short step of 0.001 s" in err, err


def test_a_third_party_fmu_declaring_a_fixed_step_is_refused_a_short_last_step(tmp_path, capsys):
    from test_stepping_variable_step import _dahlquist_fixed_step
    fixed = _dahlquist_fixed_step(tmp_path)
    assert main(["check", str(fixed), "--stop", "1.05"]) == 2
    assert "canHandleVariableCommunicationStepSize = false" in _one_line(capsys)
    assert main(["check", str(fixed), "--stop", "1.1"]) == 0, capsys.readouterr().err


def test_check_says_the_last_step_is_short(capsys):
    assert main(["check", str(DQ), "--stop", "1.05"]) == 0
    assert "11 steps of 0.1 s (the last 0.05 s, to the stop time)" in capsys.readouterr().out


def test_an_event_inside_the_short_last_step_is_refused(capsys, tmp_path):
    doc = _doc(1.05)
    doc["events"] = [{"time": 1.02, "action": "stop"}]
    with pytest.raises(cosim.ScenarioError, match=r"events\[0\]\.time: 1.02 is inside the short last step"):
        cosim.resolve(cosim.parse(doc, "short.toml"))


def test_an_instance_at_its_own_rate_is_refused_a_short_last_step():
    doc = _doc(1.05)
    doc["instances"]["ft"]["step"] = 0.2
    with pytest.raises(cosim.ScenarioError, match="instances.ft.step"):
        cosim.resolve(cosim.parse(doc, "short.toml"))
