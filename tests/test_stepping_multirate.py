"""Instances at their own rates ([instances.X] step, a whole multiple of the experiment's step): the
exchange against libcosim's decimation factors on the same system, the semantics on a chain whose values
are known, the default unchanged, the checks."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim import cli
from wmr_cosim import cosim
from wmr_cosim.cosim.stepping.generated import GaussSeidel, Jacobi
from wmr_cosim.cosim.messages.errors import ScenarioError
from wmr_cosim.cosim.plan.ssp import OSP_NS, export_ssp, load_ssp

from cosim_support import write_document
from coupling_fmus import TwoMass, build_mass, two_mass_document
from reference_fmus import REF

OUT, IN = "Float64_continuous_output", "Float64_continuous_input"


@pytest.fixture(scope="module")
def mass_fmus(tmp_path_factory) -> tuple[Path, Path]:
    return build_mass(tmp_path_factory.mktemp("mass"))


def chain(algorithm: str, f_step: float | None, stop: float = 1.0) -> dict[str, Any]:
    """VanDerPol -> Feedthrough at 10 ms, the Feedthrough at its own ``f_step``."""
    f: dict[str, Any] = {"fmu": str(REF / "fmi2" / "Feedthrough.fmu")}
    if f_step is not None:
        f["step"] = f_step
    return {"experiment": {"start": 0.0, "stop": stop, "step": 0.01, "algorithm": algorithm},
            "instances": {"v": {"fmu": str(REF / "fmi2" / "VanDerPol.fmu")}, "f": f},
            "connections": [{"from": "v.x0", "to": f"f.{IN}"}],
            "record": {"variables": ["v.x0", f"f.{OUT}"]}}


def _run(doc: dict[str, Any], out: Path, alg: Any = None) -> tuple[cosim.RunResult, np.ndarray]:
    plan = cosim.resolve(cosim.parse(doc, "rates.toml"))
    res = cosim.run(plan, out, progress=False, algorithm=alg)
    assert res.status == "ok", res.message
    return res, np.load(out / "signals.npy")


@pytest.mark.parametrize("algorithm, lag", [("jacobi", 0), ("gauss-seidel", 4)])
def test_a_slow_instance_steps_at_its_points_and_its_outputs_hold(tmp_path, algorithm, lag):
    """Feedthrough every 4th step (40 ms): it takes one input per step of its own, its output (y = u, the
    input it stepped with) appears at t_4m+4 and holds until the next; under Jacobi the input is
    VanDerPol's output at t_4m (the start of its step), under Gauss-Seidel (VanDerPol first) at t_4m+4
    (the end of its step, as single-rate Gauss-Seidel gives a successor its predecessor's new outputs)."""
    res, sig = _run(chain(algorithm, 0.04), tmp_path / "r")
    x0, y = sig["v.x0"], sig[f"f.{OUT}"]
    for k in range(len(sig)):
        if k < 4:               # (the initial exchange's value until the first slow step completes)
            expected = x0[0]
        else:                   # the last slow step completed at t_4j, j = k // 4, started at t_4(j-1)
            expected = x0[4 * (k // 4 - 1) + lag]
        assert y[k] == expected, k
    rates = res.summary["stepping"]["rates"]
    assert {k: rates["f"][k] for k in ("step", "decimation", "steps")} == {"step": 0.04, "decimation": 4, "steps": 25}
    assert rates["v"]["steps"] == 100
    assert 0.0 < rates["f"]["step_time_s"] + rates["v"]["step_time_s"] < res.wall_s


@pytest.mark.parametrize("algorithm, fixed", [("gauss-seidel", GaussSeidel), ("jacobi", Jacobi)])
def test_every_instance_at_the_base_step_is_the_fixed_step_algorithm_bit_for_bit(tmp_path, algorithm, fixed):
    """An instance's step equal to the experiment's: the generated loop runs, rows as without it."""
    _, a = _run(chain(algorithm, None), tmp_path / "a")
    _, b = _run(chain(algorithm, 0.01), tmp_path / "b")
    assert a.tobytes() == b.tobytes()
    _, c = _run(chain(algorithm, None), tmp_path / "c", fixed())
    assert c.tobytes() == a.tobytes()


def test_multi_rate_jacobi_equals_libcosim_with_its_decimation_factor(mass_fmus, tmp_path):
    """The two masses (a loop both ways, the coupling force with direct feedthrough), the coupler every
    4th step of 1 ms, Jacobi; exported as SSP (the coupler's OSP StepSizeHint) and run by libcosim, whose
    fixed-step algorithm gives it decimation factor 4: the body's outputs at every step and the coupler's
    at its own steps agree to 1e-12."""
    pytest.importorskip("libcosimpy")
    import interop

    doc = two_mass_document(mass_fmus, TwoMass(), stop=1.0, step=0.001)
    doc["experiment"]["algorithm"] = "jacobi"
    doc["instances"]["coupler"]["step"] = 0.004
    plan = cosim.resolve(cosim.parse(doc, "two.toml"))
    ssp = export_ssp(plan, tmp_path / "two.ssp")
    hints = [float(e.get("value")) for e in
             __import__("lxml.etree").etree.fromstring(zipfile.ZipFile(ssp).read("SystemStructure.ssd"))
             .iter(f"{{{OSP_NS}}}StepSizeHint")]
    assert hints == [0.004]
    signals = ["body.x", "body.v", "coupler.F", "coupler.x"]
    ours = interop.run_here("ours", ssp, 1.0, 0.001, signals)["signals"]
    theirs = interop.run_here("libcosim", ssp, 1.0, 0.001, signals)["signals"]
    for s in ("body.x", "body.v"):           # (libcosim samples every step after the start)
        assert len(theirs[s]) == 1000 and np.max(np.abs(ours[s][1:] - theirs[s])) < 1e-12, s
    for s in ("coupler.F", "coupler.x"):     # (and a decimated simulator at its own steps)
        assert len(theirs[s]) == 250 and np.max(np.abs(ours[s][4::4] - theirs[s])) < 1e-12, s
    assert np.max(np.abs(np.diff(ours["body.x"]))) > 0.0


def test_the_ssp_archive_carries_each_rate_back(tmp_path):
    plan = cosim.resolve(cosim.parse(chain("jacobi", 0.04), "rates.toml"))
    arch = load_ssp(export_ssp(plan, tmp_path / "r.ssp"))
    try:
        assert arch.scenario.instances["f"].step == 0.04 and arch.scenario.instances["v"].step is None
        again = cosim.resolve(arch.scenario)
        assert again.instances["f"].decimation == 4
    finally:
        arch.cleanup()


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_check_shows_each_rate_and_summary_json_the_steps(tmp_path, capsys):
    path = write_document(tmp_path / "r.toml", chain("gauss-seidel", 0.04))
    code, out, _ = _cli(capsys, "check", str(path))
    assert code == 0 and "  f: co-simulation; steps of 0.04 s, every 4 base steps" in out
    assert "  v: co-simulation\n" in out
    code, _, err = _cli(capsys, "run", str(path), "--out", str(tmp_path / "o"), "--quiet")
    assert code == 0, err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["stepping"]["rates"]["f"]["steps"] == 25


@pytest.mark.parametrize("change, field, words", [
    ({"f_step": 0.025}, "instances.f.step", "is not a whole multiple of the experiment's step"),
    ({"f_step": 0.005}, "instances.f.step", "is not a whole multiple"),
    ({"f_step": -0.04}, "instances.f.step", "must be > 0"),
    ({"f_step": 0.03}, "instances.f.step", "does not divide the run"),
    ({"f_step": 0.04, "algorithm": "iterated"}, "instances.f.step", "steps every instance at every step"),
    ({"f_step": 0.04, "v_step": 0.06, "stop": 1.2}, "connections[0]", "must divide one another"),
])
def test_bad_rates_are_one_line_exit_2(tmp_path, capsys, change, field, words):
    doc = chain(change.get("algorithm", "jacobi"), change["f_step"], change.get("stop", 1.0))
    if "v_step" in change:
        doc["instances"]["v"]["step"] = change["v_step"]
    path = write_document(tmp_path / "bad.toml", doc)
    for command in ("check", "run"):
        code, _, err = _cli(capsys, command, str(path), *(["--out", str(tmp_path / "o"), "--quiet"]
                                                          if command == "run" else []))
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1, (command, err)
        assert f"bad.toml: {field}" in lines[0] and words in lines[0], lines


def test_an_algorithm_that_ignores_the_rates_is_refused(tmp_path):
    plan = cosim.resolve(cosim.parse(chain("gauss-seidel", 0.04), "rates.toml"))
    with pytest.raises(ScenarioError) as err:
        cosim.run(plan, tmp_path / "x", progress=False, algorithm=GaussSeidel())
    assert err.value.field == "instances.f.step" and "steps at its own rate" in str(err.value)


def test_g1_with_the_plant_at_half_a_millisecond(built_fmus, tmp_path):
    """G1 (50 s learning run, Gauss-Seidel) with the experiment's step 0.5 ms, the plant stepping at it and
    the sensor and controller every 4th step (2 ms): the tracking errors' RMSE over the 2 ms points equal
    the all-2 ms run's to 1e-9 relative (the plant's own integration does not depend on its communication
    step; the torques hold over the controller's step either way), and over every 0.5 ms row within 0.01 %
    (the held controller outputs sampled 4 times as often); the final position within 1e-9 m.  The all-2 ms
    run is the default, which the generated loop runs."""
    from cosim_support import g1_with_paths
    from wmr_cosim.components.metrics import run_metrics

    path = g1_with_paths(tmp_path, built_fmus, skip=("sensor", "controller"), extra=(
        f'[instances.sensor]\nfmu = "{built_fmus["WmrSensor"]}"\nstep = 0.002\n'
        f'[instances.controller]\nfmu = "{built_fmus["WmrController"]}"\nstep = 0.002\n'))
    slow = cosim.load(path, overrides={"experiment.step": 0.0005})
    base = cosim.load(g1_with_paths(tmp_path, built_fmus, name="g1_base.toml"))
    runs = {}
    for key, sc in (("base", base), ("fast_plant", slow)):
        plan = cosim.resolve(sc)
        res = cosim.run(plan, tmp_path / key, progress=False)
        assert res.status == "ok", res.message
        runs[key] = np.load(tmp_path / key / "signals.npy")
    assert len(runs["fast_plant"]) == 4 * (len(runs["base"]) - 1) + 1
    m0 = run_metrics(runs["base"], (2.0, 5.0))
    every = run_metrics(runs["fast_plant"], (2.0, 5.0))
    at_2ms = run_metrics(runs["fast_plant"][::4], (2.0, 5.0))
    for key in ("rmse_e", "rmse_edot"):
        for a, b, c in zip(m0[key], at_2ms[key], every[key]):
            assert abs(b - a) <= 1e-9 * a and abs(c - a) <= 1e-4 * a, (key, a, b, c)
    assert np.hypot(*np.subtract(m0["final_position"], at_2ms["final_position"])) < 1e-9


def test_the_python_api_sets_an_instance_rate(tmp_path):
    """Simulation.instance(fields={"step": ...}): the run steps it at its rate (its summary says so)."""
    from wmr_cosim import Simulation

    sim = Simulation()
    sim.experiment(start=0.0, stop=0.2, step=0.01, algorithm="jacobi")
    sim.instance("v", REF / "fmi2" / "VanDerPol.fmu")
    sim.instance("f", REF / "fmi2" / "Feedthrough.fmu", fields={"step": 0.05})
    sim.connect("v.x0", f"f.{IN}")
    sim.record("v.x0", f"f.{OUT}")
    result = sim.run(tmp_path / "api")
    assert result.status == "ok"
    f = result.summary["stepping"]["rates"]["f"]
    assert (f["step"], f["decimation"], f["steps"]) == (0.05, 5, 4)
    y = result.signals[f"f.{OUT}"]
    assert list(y[5:10]) == [result.signals["v.x0"][0]] * 5


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_an_isolated_slow_instance_gives_the_same_rows(tmp_path, algorithm):
    doc = chain(algorithm, 0.04)
    _, a = _run(doc, tmp_path / "a")
    doc["instances"]["f"]["isolate"] = True
    _, b = _run(doc, tmp_path / "b")
    assert a.tobytes() == b.tobytes()
