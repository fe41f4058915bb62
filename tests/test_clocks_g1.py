"""G1 through our clocked FMI 3.0 sensor and controller (a periodic input clock ``sample`` of 2 ms, run with
event mode): their clocked outputs of every type and shape (Int32 counts, the controller's W Float64[3]) are
read at the ticks and held by the master; a clocked output that is not Float64 is read only where its clock
ticks at every recorded communication point, else refused at check in one line.  G1 through the clocked
FMI 3.0 FMUs (the events of t_(k+1) at the end of the step that ends there) is bit for bit the fixed-step
run through the FMI 2.0 FMUs."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cosim_support import G1, toml_value, write_scenario
from wmr_cosim import cosim
from wmr_cosim.cosim.messages.errors import ScenarioError


@pytest.fixture(scope="session")
def fmus3(tmp_path_factory):
    from wmr_cosim.fmus.build import SLAVES3, build_all

    from conftest import fmu_cache

    return build_all(fmu_cache(tmp_path_factory, "fmus3"), models=tuple(SLAVES3))


def _scenario(tmp: Path, models: dict[str, Path], name: str, extra: str = "", stop: float = 0.1) -> Path:
    text = f"base = {toml_value(str(G1))}\n[experiment]\nstop = {stop}\n{extra}"
    text += "".join(f"[instances.{inst}]\nfmu = {toml_value(str(models[inst]))}\n"
                    for inst in ("plant", "sensor", "controller"))
    return write_scenario(tmp / f"{name}.toml", text)


def _run(path: Path, out: Path) -> np.ndarray:
    res = cosim.run(cosim.resolve(cosim.load(path)), out, progress=False)
    assert res.status == "ok", res.message
    return np.load(out / "signals.npy")


def test_clocked_int32_and_array_outputs_are_read_at_the_ticks(built_fmus, fmus3, tmp_path):
    """At the 2 ms step (a tick at every communication point) the clocked sensor's outputs, its Int32
    counts included, equal the FMI 2.0 sensor's bit for bit; the controller's clocked W Float64[3] is read
    as its three elements."""
    two = _run(_scenario(tmp_path, {"plant": built_fmus["WmrPlant"], "sensor": built_fmus["WmrSensor"],
                                    "controller": built_fmus["WmrController"]}, "two"), tmp_path / "two")
    three = _run(_scenario(tmp_path, {"plant": fmus3["WmrPlant3"], "sensor": fmus3["WmrSensor3"],
                                      "controller": fmus3["WmrController3"]}, "three",
                                     "[instances.controller.parameters]\nW_init = [0.02, 0.04, 0.06]\n"), tmp_path / "three")
    sensor = [c for c in two.dtype.names if c.startswith("sensor.")]
    assert "sensor.count1" in sensor and "sensor.count2" in sensor
    assert three["sensor.count1"].dtype.kind == "i"
    for c in sensor:
        assert np.array_equal(two[c], three[c]), c
    for k in (0, 1, len(three) - 1):   # (the weights move from 3.7 s on)
        assert [three[f"controller.W[{i}]"][k] for i in (1, 2, 3)] == [0.02, 0.04, 0.06]
    # the controller's columns that stay constant over these 0.1 s in the FMI 2.0 run (its P, t_goal ...):
    # the same values, each in its own column (an array read at the tick with the wrong count shifts them)
    steady = [c for c in two.dtype.names if c.startswith("controller.") and c[11] != "W" and (two[c] == two[c][0]).all()]
    assert len(steady) >= 8, steady
    for c in steady:
        name3 = re.sub(r"^controller\.P(\d)(\d)$", r"controller.P[\1,\2]", c)
        assert (three[name3] == two[c][0]).all(), c


def test_a_clocked_int32_output_between_ticks_is_refused_in_one_line(fmus3, tmp_path):
    """At 0.5 ms steps the 2 ms clock ticks at every 4th point: recording sensor.count1 at every point is
    refused; with decimation 4 every recorded point is a tick and it is accepted."""
    models = {"plant": fmus3["WmrPlant3"], "sensor": fmus3["WmrSensor3"], "controller": fmus3["WmrController3"]}
    path = _scenario(tmp_path, models, "fast", "step = 0.0005\n")
    with pytest.raises(ScenarioError) as exc:
        cosim.resolve(cosim.load(path))
    msg = str(exc.value)
    assert "\n" not in msg and re.search(r"sensor\.count\d: a clocked Int32 output .* sample does not tick at "
                                         r"every recorded communication point", msg), msg
    path = _scenario(tmp_path, models, "dec", "step = 0.0005\n[record]\ndecimation = 4\n")
    cosim.resolve(cosim.load(path))


def _fmi3(fmus3: dict[str, Path]) -> dict[str, Path]:
    return {"plant": fmus3["WmrPlant3"], "sensor": fmus3["WmrSensor3"], "controller": fmus3["WmrController3"]}


def _column3(column: str) -> str:
    """The FMI 3.0 column of an FMI 2.0 column: controller.W1 -> controller.W[1], P12 -> P[1,2]."""
    column = re.sub(r"^controller\.W(\d)$", r"controller.W[\1]", column)
    return re.sub(r"^controller\.P(\d)(\d)$", r"controller.P[\1,\2]", column)


def test_g1_through_the_clocked_fmi3_fmus_is_bit_identical_to_the_fixed_step_run(built_fmus, fmus3, tmp_path):
    """G1 (plant -> sensor -> controller, Gauss-Seidel, 2 ms) with the sensor and the controller run with
    event mode, their clock sample ticking at the end of every step: every recorded column equals the
    fixed-step FMI 2.0 run's bit for bit over 5 s (the weights move from 3.7 s on).  Ticks handled at the
    start of the step from their time would make the controller's outputs a step late and the plant
    use the torque of the tick before."""
    two = _run(_scenario(tmp_path, {"plant": built_fmus["WmrPlant"], "sensor": built_fmus["WmrSensor"],
                                    "controller": built_fmus["WmrController"]}, "two", stop=5.0), tmp_path / "two")
    three = _run(_scenario(tmp_path, _fmi3(fmus3), "three", stop=5.0), tmp_path / "three")
    assert len(two) == len(three) == 2501
    for c in two.dtype.names:
        assert np.array_equal(two[c], three[_column3(c)]), c
    assert len(two.dtype.names) > 50
    assert three["controller.W[1]"][0] != three["controller.W[1]"][-1]   # (it learned)


def test_check_lists_each_instance_clock_of_g1(fmus3, tmp_path):
    """``check`` of G1 through the clocked FMUs: the sensor and the controller run with event mode, one
    line for each one's clock (the plant has none)."""
    path = _scenario(tmp_path, _fmi3(fmus3), "check", stop=5.0)
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "check", str(path)], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    assert "  plant: co-simulation" in lines
    clocks = [(lines[i - 1].strip(), line.split(";")[:2]) for i, line in enumerate(lines)
              if line.startswith("    clock ")]
    assert clocks == [(inst + ": co-simulation with event mode",
                       ["    clock sample: periodic input clock (constant)", " interval 0.002 s"])
                      for inst in ("sensor", "controller")]


def test_the_plant_at_half_a_millisecond_beside_the_clocked_blocks_equals_the_multirate_run(built_fmus, fmus3,
                                                                                             tmp_path):
    """The plant stepped every 0.5 ms, the sensor and the controller ticked by their 2 ms clock (every 4th
    point, event mode): every recorded column (every 4th point, where the clock ticks) equals the multi-rate
    run of the FMI 2.0 FMUs with the sensor and the controller at their own step of 2 ms, bit for bit.  The
    two are the same schedule: a multi-rate block steps from t_(k+1-4) in the base step that ends at t_(k+1),
    taking its inputs as they are then (the plant's at t_(k+1)), and its outputs appear at t_(k+1); a clocked
    block's tick at t_(k+1) takes the inputs set for the step that ends there (the plant's at t_(k+1)), and
    its outputs are read right after."""
    head = "step = 0.0005\n[record]\ndecimation = 4\n"
    path = _scenario(tmp_path, {"plant": built_fmus["WmrPlant"], "sensor": built_fmus["WmrSensor"],
                                "controller": built_fmus["WmrController"]}, "multirate", head, stop=1.0)
    text = path.read_text()
    for inst in ("sensor", "controller"):   # (their own step of 2 ms: the master's multi-rate setting)
        text = text.replace(f"[instances.{inst}]\n", f"[instances.{inst}]\nstep = 0.002\n", 1)
    path.write_text(text)
    two = _run(path, tmp_path / "two")
    three = _run(_scenario(tmp_path, _fmi3(fmus3), "clocked", head, stop=1.0), tmp_path / "three")
    assert len(two) == len(three) == 501
    for c in two.dtype.names:
        assert np.array_equal(two[c], three[_column3(c)]), c
    assert not (two["controller.u1"] == two["controller.u1"][0]).all()
