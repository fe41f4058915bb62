"""The master: equivalence with the direct loop, Jacobi, events, swapping the plant, results."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cosim_support import G1, build_test_fmu, g1_with_paths
from wmr_cosim.components.direct_loop import run_direct
from wmr_cosim.components.metrics import run_metrics
from wmr_cosim import cosim
from wmr_cosim.cosim.scenario import document as scenario


@pytest.fixture(scope="module")
def resolver(built_fmus):
    return lambda name: built_fmus.get(name)


def _run(path, resolver, out, **over):
    sc = scenario.load(path, resolver)
    for k, v in over.items():
        setattr(sc, k, v)
    return cosim.run(cosim.resolve(sc), out, progress=False)


@pytest.fixture(scope="module")
def gs_run(resolver, tmp_path_factory):
    out = tmp_path_factory.mktemp("gs")
    res = _run(G1, resolver, out)
    return res, np.load(out / "signals.npy")


def test_gauss_seidel_reproduces_the_direct_loop_bit_for_bit(gs_run):
    res, data = gs_run
    assert res.status == "ok", res.message
    assert len(data) == 25001
    ref = run_direct(t_stop=50.0)
    compared = 0
    for name in data.dtype.names:
        if name in ref.signals:
            assert np.array_equal(data[name], ref.signals[name]), name
            compared += 1
    assert compared == len(data.dtype.names)  # every recorded column is a direct-loop signal (and time)


def test_results_folder(gs_run):
    res, data = gs_run
    out = res.out_dir
    import json
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["steps"] == 25000 and summary["rows"] == 25001
    assert summary["final"]["plant.x_A"] == data["plant.x_A"][-1]
    head = (out / "signals.csv").read_text().splitlines()
    assert head[0].split(",") == list(data.dtype.names)
    assert len(head) == 25002
    assert float(head[-1].split(",")[data.dtype.names.index("controller.u1")]) == data["controller.u1"][-1]
    resolved = json.loads((out / "scenario.json").read_text())
    assert resolved["experiment"]["step"] == 0.002 and len(resolved["connections"]) == 11
    for inst in ("plant", "sensor", "controller"):
        assert (out / "logs" / f"{inst}.log").is_file()
    import pandas as pd  # the compact binary format loads in one call
    df = pd.DataFrame(np.load(out / "signals.npy"))
    assert df.shape == (25001, len(data.dtype.names))


def test_jacobi_runs_and_stays_close_to_gauss_seidel(resolver, tmp_path, gs_run):
    _, gs = gs_run
    res = _run(G1, resolver, tmp_path, algorithm="jacobi")
    assert res.status == "ok", res.message
    ja = np.load(tmp_path / "signals.npy")
    m_gs = run_metrics({k: gs[k] for k in gs.dtype.names}, (2, 5))
    m_ja = run_metrics({k: ja[k] for k in ja.dtype.names}, (2, 5))
    # Jacobi delays each link by one step (two along plant -> sensor -> controller): the learned weights
    # differ by a few per cent, and with them the tracking RMSE (measured: up to 6 %); the path hardly
    assert not np.array_equal(ja["controller.u1"], gs["controller.u1"])
    assert math.dist(m_ja["final_position"], m_gs["final_position"]) < 1e-3
    for a, b in zip(m_ja["rmse_e"] + m_ja["rmse_edot"], m_gs["rmse_e"] + m_gs["rmse_edot"]):
        assert a == pytest.approx(b, rel=0.10)
    assert m_ja["goal_distance"] < 0.03


def test_events_override_and_reset_an_input(resolver, tmp_path, built_fmus):
    path = g1_with_paths(tmp_path, built_fmus, """
[experiment]
stop = 2.0
[record]
variables = ["plant.dF1", "plant.dF2"]
[[events]]
time = 1.0
variable = "plant.tau_d1"
action = "override"
value = 0.25
[[events]]
time = 1.0
variable = "plant.tau_d1"
action = "bias"
value = 0.05
[[events]]
time = 1.5
variable = "plant.tau_d1"
action = "reset"
""")
    res = _run(path, None, tmp_path / "out")
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    t = d["time"]
    # the torque is held over the step that starts at the event time: visible from t = 1.002 s on
    assert np.all(d["plant.dF1"][t <= 1.0] == 0.0)
    assert np.allclose(d["plant.dF1"][(t > 1.001) & (t < 1.501)], 0.3)
    assert np.all(d["plant.dF1"][t > 1.501] == 0.0) and np.all(d["plant.dF2"] == 0.0)


def test_event_override_on_an_output_changes_what_the_connection_carries(resolver, tmp_path, built_fmus):
    path = g1_with_paths(tmp_path, built_fmus, """
[experiment]
stop = 1.0
[record]
variables = ["controller.u1", "plant.alpha_dot1"]
[[events]]
time = 0.1
variable = "controller.u1"
action = "override"
value = 2.0
""")
    assert _run(path, None, tmp_path / "out").status == "ok"
    d = np.load(tmp_path / "out" / "signals.npy")
    # the controller still outputs its own u1 (recorded: it brakes, since the wheel runs ahead of the
    # desired motion), but the plant receives 2 N.m and moves
    assert d["controller.u1"][-1] < 0.0
    assert d["plant.alpha_dot1"][-1] > 0.1
    base = run_direct(t_stop=1.0)
    assert base.signals["plant.alpha_dot1"][-1] < 1e-3


@pytest.fixture(scope="module")
def swap_fmu(tmp_path_factory):
    return build_test_fmu("swap_plant.py", tmp_path_factory.mktemp("swap"))


SWAP_NAMES = """
[instances.plant.names]
torque_right = "u1"
torque_left = "u2"
phi_right_deg = "alpha1"
phi_left_deg = "alpha2"
pos_x = "x_A"
pos_y = "y_A"
heading = "beta"
"""


def _swap_scenario(path, swap_fmu, units: str):
    path.write_text(f'base = "{G1}"\n[instances.plant]\nfmu = "{swap_fmu}"\n{SWAP_NAMES}[instances.plant.units]\n{units}')
    return path


def test_swapped_plant_with_other_names_and_degrees(resolver, tmp_path, swap_fmu, gs_run):
    _, gs = gs_run
    path = _swap_scenario(tmp_path / "swap.toml", swap_fmu,
                          'alpha1 = "deg"\nalpha2 = "deg"\nx_A = "m"\ny_A = "m"\nbeta = "rad"\nu1 = "N.m"\nu2 = "N.m"\n')
    plan = cosim.resolve(scenario.load(path, resolver))
    conv = {c.spec.src: (c.factor, c.offset) for c in plan.connections}
    assert conv["plant.alpha1"] == (pytest.approx(math.pi / 180, rel=1e-15), 0.0)   # deg -> rad
    res = cosim.run(plan, tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    assert "plant.alpha1" in d.dtype.names           # recorded under our names
    import json
    for f in ("summary.json", "scenario.json"):     # ... with the unit and the FMU's own name beside them
        cols = json.loads((tmp_path / "out" / f).read_text())["columns"]
        assert cols["plant.alpha1"] == {"unit": "deg", "instance": "plant", "fmu": swap_fmu.name,
                                        "variable": "phi_right_deg"}
        assert cols["time"]["unit"] == "s" and cols["controller.u1"]["unit"] == "N.m"
        assert list(cols) == list(d.dtype.names)
    m = run_metrics({k: d[k] for k in d.dtype.names}, (2, 5))
    m0 = run_metrics({k: gs[k] for k in gs.dtype.names}, (2, 5))
    for a, b in zip(m["rmse_e"] + m["rmse_edot"], m0["rmse_e"] + m0["rmse_edot"]):
        assert a == pytest.approx(b, rel=1e-3)
    assert math.dist(m["final_position"], m0["final_position"]) < 1e-3


def test_swapped_plant_is_checked(resolver, tmp_path, swap_fmu):
    path = _swap_scenario(tmp_path / "swap.toml", swap_fmu, 'alpha1 = "N.m"\n')
    from wmr_cosim.cosim.messages.errors import ScenarioError
    with pytest.raises(ScenarioError, match=r"connections\[0\]: unit mismatch: plant.alpha1 -> sensor.alpha1"):
        cosim.resolve(scenario.load(path, resolver))


def test_cli_runs_every_run_of_a_protocol(built_fmus, tmp_path):
    import json
    import subprocess
    import sys

    path = g1_with_paths(tmp_path, built_fmus, """
[experiment]
stop = 6.0
[[runs]]
name = "a"
[[runs]]
name = "b"
parameters = { "controller.adapt" = false }
carry = { "controller.W1_init" = "a.controller.W1", "controller.W2_init" = "a.controller.W2", "controller.W3_init" = "a.controller.W3" }
""")
    # b carries all of W: with W2 alone its |e1| ends at 1.1 rad, which `run` reports as diverged (exit 1)
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "run", str(path), "--out", str(out), "--quiet"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    a = np.load(out / "a" / "signals.npy")
    b = np.load(out / "b" / "signals.npy")
    assert a["controller.W2"][-1] != 0.05                      # a adapted
    assert np.all(b["controller.W2"] == a["controller.W2"][-1])  # b started from a's final W2, frozen
    assert json.loads((out / "b" / "scenario.json").read_text())["instances"]["controller"]["parameters"]["W2_init"] \
        == a["controller.W2"][-1]
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "run", str(path), "--variant", "x"],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "--variant x: not declared" in p.stderr


def test_check_of_a_protocol_with_a_swapped_plant_names_what_a_later_run_lacks(built_fmus, tmp_path, swap_fmu,
                                                                                capsys):
    """A protocol based on the paper's G1 with the plant swapped: check resolves every run, so what the
    foam run sets on a plant that has no such parameter is found before anything is simulated."""
    from cosim_support import ROOT, toml_value
    from wmr_cosim.cli import main

    g1 = ROOT / "scenarios" / "paper" / "g1.toml"
    record = ('[record]\nvariables = ["plant.x_A", "plant.y_A", "plant.alpha*", "controller.u*", '
              '"controller.e*", "controller.W*", "controller.P*"]\n')
    text = (f"base = {toml_value(str(g1))}\n{record}"
            + "".join(f"[instances.{i}]\nfmu = {toml_value(str(built_fmus[m]))}\n"
                      for i, m in (("sensor", "WmrSensor"), ("controller", "WmrController")))
            + f"[instances.plant]\nfmu = {toml_value(str(swap_fmu))}\n{SWAP_NAMES}[instances.plant.units]\n"
              'alpha1 = "deg"\nalpha2 = "deg"\n')
    path = tmp_path / "swap_protocol.toml"
    path.write_text(text)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"{path}: 5 variables missing from their FMUs: plant.foam_on_time (runs.foam.parameters), "
                        "plant.foam_t_on (runs.foam.parameters), plant.foam_da1 (runs.foam.parameters), "
                        "plant.foam_da2 (runs.foam.parameters), plant.foam_ramp (runs.foam.parameters)"), err
    assert len(err.splitlines()) == 1
    # without P* in the record, the carry of the frozen run is what check names first
    path.write_text(text.replace(', "controller.P*"', ""))
    assert main(["check", str(path)]) == 2
    assert "runs.frozen.carry.controller.P11_init: 'learn.controller.P11' was not recorded by run 'learn'" \
        in capsys.readouterr().err
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    assert not out.exists()          # nothing was simulated
