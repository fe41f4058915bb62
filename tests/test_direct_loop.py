"""The direct loop is the exchange order its documentation states, with every component's own parameters
and the plant's start pose carried through; its step count and time span are checked in one line."""
from __future__ import annotations

import pytest

from wmr_cosim.components.controller import CONTROLLER_OUTPUTS, Controller, ControllerParams
from wmr_cosim.components.direct_loop import run_direct
from wmr_cosim.components.plant import PLANT_OUTPUTS, Plant, PlantParams
from wmr_cosim.components.sensor import SENSOR_OUTPUTS, Sensor, SensorParams
from wmr_cosim.components.validation import ParameterError

H = 0.002


def _by_hand(plant: PlantParams, sensor: SensorParams, controller: ControllerParams, n: int, disturbance=None):
    """Plant -> sensor -> controller, each step: the plant integrates over [t_k, t_k+1] with the torques of
    t_k, the sensor samples at t_k+1, the controller answers at t_k+1 (and starts from the first samples)."""
    pl, se, co_ = Plant(plant), Sensor(sensor), Controller(controller)
    po = pl.outputs()
    se.reset(po[0], po[1])
    so = se.outputs()
    co = co_.reset(0.0, so[0], so[1], so[2], so[3], po[4], po[5], po[6])
    rows = [(po, so, co)]
    for k in range(n):
        tau = disturbance(k * H) if disturbance else (0.0, 0.0)
        po = pl.step(k * H, H, co[0], co[1], *tau)
        so = se.step(H, po[0], po[1])
        co = co_.step((k + 1) * H, H, so[0], so[1], so[2], so[3], po[4], po[5], po[6])
        rows.append((po, so, co))
    return rows


def test_the_loop_is_the_documented_exchange_order_with_each_components_parameters():
    """A start away from the origin, turned, with a coarse encoder and the controller on the true pose:
    every recorded sample equals the order stepped by hand, and differs from the defaults' run."""
    plant = PlantParams(x0=1.0, y0=-0.5, beta0=0.4)
    sensor = SensorParams(ppr=100.0, phase1=0.3)
    controller = ControllerParams(task="goal", goal_x=3.0, goal_y=1.0, pose_source="true", b1=0.05)
    n = 400

    def disturbance(t: float) -> tuple[float, float]:   # on the left wheel only, from 0.3 s
        return (0.0, 0.2) if t >= 0.3 else (0.0, 0.0)
    r = run_direct(plant, sensor, controller, t_stop=n * H, h=H, disturbance=disturbance)
    assert r.status == "ok" and r.message == "" and r.steps == n and len(r["time"]) == n + 1
    rows = _by_hand(plant, sensor, controller, n, disturbance)
    for part, (names, j) in {"plant": (PLANT_OUTPUTS, 0), "sensor": (SENSOR_OUTPUTS, 1),
                             "controller": (CONTROLLER_OUTPUTS, 2)}.items():
        for i, name in enumerate(names):
            assert r[f"{part}.{name}"].tolist() == [row[j][i] for row in rows], f"{part}.{name}"
    assert r["time"].tolist() == [k * H for k in range(n + 1)]
    default = run_direct(t_stop=n * H, h=H)
    for name in ("plant.x_A", "sensor.alpha_m1", "controller.u1"):
        assert r[name].tolist() != default[name].tolist(), name


def test_the_controller_starts_from_the_plant_pose_when_it_reads_the_true_pose():
    """The first sample's control from the true pose equals the one from odometry started at the same
    pose: the start pose reaches the controller."""
    plant = PlantParams(x0=1.0, y0=-0.5, beta0=0.4)
    goal = dict(task="goal", goal_x=3.0, goal_y=1.0)
    true = run_direct(plant, controller=ControllerParams(pose_source="true", **goal), t_stop=H)
    odo = run_direct(plant, controller=ControllerParams(x0=1.0, y0=-0.5, beta0=0.4, **goal), t_stop=H)
    for name in CONTROLLER_OUTPUTS:
        assert true[f"controller.{name}"][0] == odo[f"controller.{name}"][0], name


@pytest.mark.parametrize("t_stop, message", [
    (0.0, "direct loop parameter t_stop = 0.0: must be > 0"),
    (0.003, "direct loop parameter t_stop = 0.003: not a whole number of steps h = 0.002"),
    (10.0 + 2e-8, f"direct loop parameter t_stop = {10.0 + 2e-8!r}: not a whole number of steps h = 0.002")])
def test_a_time_span_that_is_not_whole_steps_is_refused_in_one_line(t_stop, message):
    with pytest.raises(ParameterError) as err:
        run_direct(t_stop=t_stop, h=H)
    assert str(err.value) == message


def test_a_time_span_within_rounding_of_whole_steps_is_run():
    """A relative mismatch up to 1e-9 of t_stop is rounding: 10 s + 5 ns is 5000 steps."""
    r = run_direct(t_stop=10.0 + 5e-9, h=H, record=False)
    assert r.steps == 5000 and r["time"].tolist() == [5000 * H]


def test_a_state_that_is_no_longer_finite_ends_the_run_after_the_last_finite_step():
    """A NaN disturbance from t = 0.1 s: the step into 0.102 s fails in a component, so 50 steps were
    done and the run is diverged, saying when."""
    r = run_direct(t_stop=0.2, h=H, disturbance=lambda t: (float("nan"), 0.0) if t >= 0.1 else (0.0, 0.0))
    assert r.status == "diverged" and r.steps == 50
    assert r.message.startswith("the state is no longer finite at t = 0.102 s (")
    assert len(r["time"]) == 51 and r["time"][-1] == pytest.approx(0.1)
