"""Each FMU driven under FMPy gives bit-identical outputs to its component; the closed loop of
the three FMUs reproduces the direct loop; state save/restore and serialisation; independent instances;
an FMU copied to a path with a space and run in a fresh process."""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmu_support import CONTROLLER_IN, Fmu, H, closed_loop
from wmr_cosim.components.controller import Controller, ControllerParams
from wmr_cosim.components.direct_loop import run_direct
from wmr_cosim.components.plant import Plant, PlantParams
from wmr_cosim.components.sensor import Sensor, SensorParams

TESTS = Path(__file__).resolve().parent


def same(a, b) -> bool:
    """Bit-identical sequences of numbers (bools and ints compared as floats; NaN equals NaN)."""
    a, b = [float(x) for x in a], [float(x) for x in b]
    return len(a) == len(b) and all(x == y or (x != x and y != y) for x, y in zip(a, b))


# ---------------------------------------------------------------- a component and its input sequence
PLANT_PARAMS = {"foam_on_time": True, "foam_t_on": 0.5, "foam_da1": 0.3, "foam_da2": 0.2, "foam_ramp": 0.1,
                "x0": 0.1, "beta0": 0.2}
SENSOR_PARAMS = {"phase1": 0.25, "angle_source": "filtered"}
CONTROLLER_PARAMS = {"goal_x": 1.0, "goal_y": 1.5, "gamma": 8.0, "adapt_t_end": 1.5}


def plant_inputs(t):
    return (2.0 * math.sin(3.0 * t), 1.5 * math.cos(2.0 * t), 0.1 * math.sin(t), 0.0)


def sensor_inputs(t):
    return (0.8 * t + 0.3 * math.sin(5.0 * t), 0.7 * t)


def controller_inputs(t):
    a1, a2 = 3.0 * t + 0.2 * math.sin(4.0 * t), 2.8 * t
    return (a1, a2, 3.0 + 0.8 * math.cos(4.0 * t), 2.8, 0.0, 0.0, 0.0)


class Reference:
    """The component stepped exactly as the FMU's documented semantics say."""

    def __init__(self, model: str, params: dict, t0: float = 0.0, at_rest: bool = False):
        self.model = model
        if model == "WmrPlant":
            self.c = Plant(PlantParams(**params))
            self.out = self.c.outputs()
        elif model == "WmrSensor":
            self.c = Sensor(SensorParams(**params))
            self.c.reset(*((0.0, 0.0) if at_rest else sensor_inputs(t0)))
            self.out = self.c.outputs()
        else:
            self.c = Controller(ControllerParams(**params))
            self.out = self.c.reset(t0, *((0.0,) * 7 if at_rest else controller_inputs(t0)))

    def step(self, t, h, x):
        """The step from t = k h; like the direct loop, the controller's sample time is (k + 1) h."""
        if self.model == "WmrPlant":
            self.out = self.c.step(t, h, *x)
        elif self.model == "WmrSensor":
            self.out = self.c.step(h, *x)
        else:
            self.out = self.c.step((round(t / h) + 1) * h, h, *x)
        return self.out


def inputs_for(model):
    """Inputs applied over the step from t: the plant's held torques at t; the sensor's and the
    controller's samples at the end of the step, t + h."""
    if model == "WmrPlant":
        return lambda t, h: plant_inputs(t)
    if model == "WmrSensor":
        return lambda t, h: sensor_inputs(t + h)
    return lambda t, h: controller_inputs(t + h)


PARAMS = {"WmrPlant": PLANT_PARAMS, "WmrSensor": SENSOR_PARAMS, "WmrController": CONTROLLER_PARAMS}
INIT_INPUTS = {"WmrPlant": None, "WmrSensor": dict(zip(("alpha1", "alpha2"), sensor_inputs(0.0))),
               "WmrController": dict(zip(CONTROLLER_IN, controller_inputs(0.0)))}


def start(fmu: Fmu, model: str, params: dict | None = None) -> None:
    fmu.init(params=PARAMS[model] if params is None else params, inputs=INIT_INPUTS[model])


@pytest.mark.parametrize("h", [0.002, 0.001])
@pytest.mark.parametrize("model", ["WmrPlant", "WmrSensor", "WmrController"])
def test_fmu_alone_is_bit_identical_to_its_component(built_fmus, model, h):
    f = Fmu(built_fmus[model], "alone")
    try:
        ref0 = Reference(model, {}, at_rest=True)  # default parameters, inputs at their start values
        assert same(f.outputs(), ref0.out)  # before initialisation: the default initial state
        start(f, model)
        ref = Reference(model, PARAMS[model])
        assert same(f.outputs(), ref.out)
        u = inputs_for(model)
        n = round(1.0 / h) if model != "WmrController" else round(2.0 / h)
        for k in range(n):
            t = k * h
            x = u(t, h)
            f.step(t, h, x)
            expect = ref.step(t, h, x)
            assert same(f.outputs(), expect), (model, k)
        assert any(v != 0.0 for v in ref.out)
    finally:
        f.free()


def test_closed_loop_of_fmus_reproduces_the_direct_loop(built_fmus):
    n = 1500
    rec = closed_loop(built_fmus["WmrPlant"].parent, n)
    res = run_direct(t_stop=n * H, h=H)
    keys = [k for k in res.signals if k != "time"]
    assert set(keys) == set(rec)
    for k in keys:
        assert np.array_equal(np.asarray(rec[k]), res.signals[k]), k
    assert res.signals["plant.x_A"][-1] != 0.0


@pytest.mark.parametrize("model", ["WmrPlant", "WmrSensor", "WmrController"])
def test_state_restore_and_serialisation_are_exact(built_fmus, model):
    a = Fmu(built_fmus[model], "a")
    b = Fmu(built_fmus[model], "b")
    try:
        start(a, model)
        u = inputs_for(model)
        for k in range(300):
            a.step(k * H, H, u(k * H, H))
        state = a.fmu.getFMUstate()

        def run(f, k0):
            rows = []
            for k in range(k0, k0 + 1000):
                f.step(k * H, H, u(k * H, H))
                rows.append(f.outputs())
            return rows

        first = run(a, 300)
        a.fmu.setFMUstate(state)
        second = run(a, 300)
        assert all(same(x, y) for x, y in zip(first, second))
        # serialised, then restored into another instance that has other parameters and another state
        blob = a.fmu.serializeFMUstate(state)
        a.fmu.freeFMUstate(state)
        start(b, model, params={})
        for k in range(50):
            b.step(k * H, H, u(k * H + 0.1, H))
        s2 = b.fmu.deSerializeFMUstate(blob)
        b.fmu.setFMUstate(s2)
        b.fmu.freeFMUstate(s2)
        third = run(b, 300)
        assert all(same(x, y) for x, y in zip(first, third))
        assert not all(same(first[0], r) for r in first[1:])  # the outputs do change over the run
    finally:
        a.free()
        b.free()


@pytest.mark.parametrize("model", ["WmrPlant", "WmrSensor", "WmrController"])
def test_two_instances_in_one_process_are_independent(built_fmus, model, tmp_path):
    """Two instances, one of them from a second extraction of the same FMU, stepped interleaved with
    different parameters and inputs, each match their own component."""
    f1 = Fmu(built_fmus[model], "one")
    f2 = Fmu(built_fmus[model], "two", unzip_dir=tmp_path / "second copy")
    try:
        other = {"WmrPlant": {"x0": -1.0, "substeps": 3}, "WmrSensor": {"phase2": 0.0, "angle_source": "counts"},
                 "WmrController": {"task": "line", "gamma": 5.0}}[model]
        start(f1, model)
        start(f2, model, params=other)
        r1, r2 = Reference(model, PARAMS[model]), Reference(model, other)
        u = inputs_for(model)
        for k in range(400):
            t = k * H
            x1 = u(t, H)
            x2 = tuple(0.5 * v for v in x1)
            f1.step(t, H, x1)
            f2.step(t, H, x2)
            assert same(f1.outputs(), r1.step(t, H, x1))
            assert same(f2.outputs(), r2.step(t, H, x2))
    finally:
        f1.free()
        f2.free()


def test_copied_fmus_run_in_a_fresh_process_from_a_path_with_spaces(built_fmus, tmp_path):
    where = tmp_path / "a folder with spaces" / "and more"
    where.mkdir(parents=True)
    for p in built_fmus.values():
        shutil.copy(p, where / p.name)
    n = 500
    r = subprocess.run([sys.executable, str(TESTS / "fmu_support.py"), str(where), str(n)],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    rec = json.loads(r.stdout.strip().splitlines()[-1])
    res = run_direct(t_stop=n * H, h=H)
    for k, v in res.signals.items():
        if k != "time":
            assert np.array_equal(np.asarray(rec[k], dtype=float), v), k
