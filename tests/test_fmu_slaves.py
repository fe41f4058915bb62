"""The slave classes as plain Python objects (no FMI binary): declared dependencies checked
against the components, initialization-mode outputs, tunable and fixed parameters, refused calls, and
the tolerance to other masters' time and step rounding."""
from __future__ import annotations

import math

import pytest

from wmr_cosim.components.controller import Controller, ControllerParams
from wmr_cosim.components.plant import Plant, PlantParams
from wmr_cosim.components.sensor import Sensor
from wmr_cosim.fmus.slave_controller import WmrController
from wmr_cosim.fmus.slave_plant import WmrPlant
from wmr_cosim.fmus.slave_sensor import WmrSensor

H = 0.002


def started(cls, params=None, inputs=None, t0=0.0):
    s = cls(instance_name="t")
    s.setup_experiment(t0)
    for name, value in (params or {}).items():
        _set(s, name, value)
    s.enter_initialization_mode()
    for name, value in (inputs or {}).items():
        _set(s, name, value)
    s.exit_initialization_mode()
    return s


def _set(s, name, value):
    v = s._by_name[name]
    {"Real": s.set_real, "Integer": s.set_integer, "Boolean": s.set_boolean, "String": s.set_string}[v.kind](
        [v.vr], [value])


def outputs(s):
    return {v.name: s._vals[v.vr] for v in s._outputs}


def log_text(s):
    return [m.msg for m in s.log_queue]


# ---------------------------------------------------------------- dependencies tell the truth
def _probe(s, inputs, k0, deps_of):
    """From the state after k0 steps, perturb each input in turn before one step; every output that
    changes must list that input among its declared dependencies."""
    state = s._get_fmu_state()
    names = [v.name for v in s._inputs]
    t = k0 * H
    s.set_real([s.vr(n) for n in names], list(inputs))
    assert s.do_step(t, H)
    base = outputs(s)
    seen = set()
    for j, name in enumerate(names):
        s._set_fmu_state(state)
        x = list(inputs)
        x[j] += 0.05 + 0.1 * abs(x[j])
        s.set_real([s.vr(n) for n in names], x)
        assert s.do_step(t, H)
        for out, val in outputs(s).items():
            if val != base[out]:
                assert name in deps_of[out], f"{out} changed with {name}, not declared"
                seen.add((out, name))
    s._set_fmu_state(state)
    return seen


@pytest.mark.parametrize("params", [{}, {"pose_source": "true"}, {"task": "line"},
                                    {"goal_x": 0.3, "goal_y": 0.1}])
def test_controller_dependencies_are_true(params):
    s = started(WmrController, params)
    deps = {v.name: set(v.deps) for v in s._outputs}
    seen = set()
    names = [v.name for v in s._inputs]
    for k in range(1500):
        t = (k + 1) * H
        x = [3.0 * t, 2.9 * t, 3.0, 2.9, 0.2 * t, 0.5 * t, 0.1]
        if k in (0, 10, 700, 1400):
            seen |= _probe(s, x, k, deps)
        s.set_real([s.vr(n) for n in names], x)
        assert s.do_step(k * H, H)
    # and the declarations are not wildly conservative: the main couplings are seen
    assert ("u1", "alpha_m1") in seen and ("s1", "alpha_dot_m1") in seen
    if params.get("pose_source") == "true":
        assert ("x_hat", "x_true") in seen


def test_sensor_and_plant_dependencies_are_true():
    s = started(WmrSensor)
    deps = {v.name: set(v.deps) for v in s._outputs}
    for k in range(300):
        x = (0.9 * (k + 1) * H + 0.01, 0.7 * (k + 1) * H)
        if k in (0, 150):
            seen = _probe(s, x, k, deps)
            assert ("count1", "alpha1") in seen and ("alpha_dot_inc2", "alpha2") in seen
        s.set_real([s.vr("alpha1"), s.vr("alpha2")], list(x))
        assert s.do_step(k * H, H)
    # the plant: setting inputs never changes the outputs without a step (no direct feedthrough)
    p = started(WmrPlant)
    p.set_real([p.vr("u1")], [1.0])
    assert p.do_step(0.0, H)
    before = outputs(p)
    p.set_real([p.vr(n) for n in ("u1", "u2", "tau_d1", "tau_d2")], [5.0, -3.0, 1.0, 2.0])
    assert outputs(p) == before


# ---------------------------------------------------------------- initialization mode
def test_outputs_follow_parameters_and_inputs_in_initialization_mode():
    p = WmrPlant(instance_name="t")
    assert outputs(p)["x_A"] == 0.0  # before initialisation: the default initial state
    p.setup_experiment(0.0)
    _set(p, "x0", 1.5)
    p.enter_initialization_mode()
    assert p.get_real([p.vr("x_A")]) == [1.5]
    _set(p, "beta0", 0.25)
    assert p.get_real([p.vr("beta")]) == [0.25]
    p.exit_initialization_mode()
    assert p.get_real([p.vr("x_A"), p.vr("beta")]) == [1.5, 0.25]
    s = WmrSensor(instance_name="t")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    _set(s, "alpha1", 1.0)
    q = 2.0 * math.pi / (500 * 19.7)
    assert s.get_integer([s.vr("count1")]) == [math.floor(1.0 / q)]
    s.exit_initialization_mode()
    assert s.get_integer([s.vr("count1")]) == [math.floor(1.0 / q)]


# ---------------------------------------------------------------- parameters after initialisation
def test_tunable_parameter_takes_effect_at_the_next_step():
    params = {"foam_on_time": True, "foam_t_on": 0.0, "foam_ramp": 0.0}
    s = started(WmrPlant, params)
    ref = Plant(PlantParams(**params))
    _set(s, "u1", 2.0)
    for k in range(200):
        if k == 100:
            _set(s, "foam_da1", 0.5)  # tunable
            ref.p = PlantParams(**{**params, "foam_da1": 0.5})
        assert s.do_step(k * H, H)
        assert tuple(outputs(s).values()) == ref.step(k * H, H, 2.0, 0.0, 0.0, 0.0)
    assert outputs(s)["dF1"] != 0.0
    c = started(WmrController)
    _set(c, "adapt", False)
    assert c.do_step(0.0, H) and outputs(c)["adapting"] == 0.0


def test_refused_calls_are_logged():
    s = started(WmrPlant)
    with pytest.raises(ValueError, match="fixed parameter a5 after initialisation"):
        _set(s, "a5", 1.0)
    with pytest.raises(ValueError, match="output x_A"):
        s.set_real([s.vr("x_A")], [1.0])
    with pytest.raises(TypeError, match="not Integer: u1"):
        s.get_integer([s.vr("u1")])
    assert any("refused" in m for m in log_text(s))
    c = started(WmrController)
    _set(c, "goal_x", 0.0)
    _set(c, "goal_y", 0.0)  # now the goal is the start: refused at the next step, as a Discard
    assert not c.do_step(0.0, H)
    assert any("goal" in m and "ParameterError" in m for m in log_text(c))
    bad = WmrSensor(instance_name="bad")
    _set(bad, "filter_form", "bessel")
    bad.enter_initialization_mode()
    with pytest.raises(ValueError):
        bad.exit_initialization_mode()
    assert log_text(bad)[-1] == ("WmrSensor instance bad: initialisation failed: ParameterError: sensor parameter "
                                 "filter_form = 'bessel': must be one of normalised, printed")


# ---------------------------------------------------------------- other masters' rounding
def test_accumulated_time_and_jittered_steps_reproduce_exact_steps():
    """A master that accumulates time (t += h) and jitters the step by 2e-16 s after an exact first step
    (as libcosim does) sees the results of exact k h times and a constant h (no rediscretisation, same
    floats)."""
    c = started(WmrController)
    s = started(WmrSensor)
    ref_c = Controller(ControllerParams())
    ref_c.reset(0.0, 0.0, 0.0, 0.0, 0.0)
    ref_s = Sensor()
    t = 0.0
    for k in range(3000):
        h = H * (1.0 + (1e-13 if k % 3 == 1 else -1e-13 if k % 3 == 2 else 0.0))  # the first step exact
        tn = (k + 1) * H
        x = (3.0 * tn, 2.9 * tn, 3.0, 2.9, 0.0, 0.0, 0.0)
        c.set_real([v.vr for v in c._inputs], list(x))
        s.set_real([v.vr for v in s._inputs], [x[0], x[1]])
        assert c.do_step(t, h) and s.do_step(t, h)
        assert tuple(outputs(c).values()) == ref_c.step(tn, H, *x)
        assert tuple(outputs(s).values()) == ref_s.step(H, x[0], x[1])
        t += h
    assert abs(t - 3000 * H) > 0.0  # the accumulated time did drift from k h


def test_the_plant_accepts_any_step_size():
    p = started(WmrPlant)
    for k in range(100):
        h = 0.001 if k < 50 else 0.004
        assert p.do_step(k * h, h)
    assert all(math.isfinite(v) for v in outputs(p).values())
    assert not p.do_step(0.3, 0.0)
    assert any("step size h = 0.0 s" in m for m in log_text(p))


@pytest.mark.parametrize("cls", [WmrSensor, WmrController])
def test_a_sampled_data_slave_takes_steps_of_its_first_length_only(cls):
    """Its sample period is its first step: a step of another length is refused (Discard, the reason in the
    log); one within a millionth of it, as the last step of a host that accumulates time in floating point
    (OMSimulator's: 1.5e-11 s short of 2 ms), is a step of that period."""
    s = started(cls)
    for k in range(10):
        assert s.do_step(k * 0.002, 0.002)
    before = dict(outputs(s))
    assert not s.do_step(0.02, 0.001)
    assert any("step of h = 0.001 s at t = 0.02 s refused: it samples every 0.002 s" in m for m in log_text(s))
    assert outputs(s) == before


@pytest.mark.parametrize("short", [1.5e-11, 1.9e-9])
def test_a_step_a_floating_point_hair_short_is_the_sample_period(short):
    s, ref = started(WmrSensor), started(WmrSensor)
    for k in range(10):
        s.set_real([s.vr("alpha1")], [0.01 * k])
        ref.set_real([ref.vr("alpha1")], [0.01 * k])
        assert s.do_step(k * 0.002, 0.002 - (short if k == 9 else 0.0)) and ref.do_step(k * 0.002, 0.002)
    assert outputs(s) == outputs(ref)
    assert not s.do_step(0.02, 0.002 * (1 - 2e-6))
