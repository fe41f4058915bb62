"""Bad input is rejected at construction with one line naming the parameter and the bad value."""
import math
import subprocess
import sys

import pytest

from wmr_cosim.components.controller import ControllerParams
from wmr_cosim.components.direct_loop import run_direct
from wmr_cosim.components.plant import Plant, PlantParams
from wmr_cosim.components.sensor import Sensor, SensorParams
from wmr_cosim.components.validation import ParameterError


@pytest.mark.parametrize("make, words", [
    (lambda: SensorParams(ppr=-500), ["ppr", "-500"]),
    (lambda: SensorParams(gear=0), ["gear", "0"]),
    (lambda: SensorParams(phase2=1.5), ["phase2", "1.5"]),
    (lambda: SensorParams(filter_form="butterworth"), ["filter_form", "butterworth"]),
    (lambda: PlantParams(a1=0.1, a2=0.0, a3=0.0), ["a1", "a2", "a3", "singular"]),
    (lambda: PlantParams(a1=0.1, a2=0.0, a3=-0.1), ["a1", "a3", "not positive definite"]),
    (lambda: ControllerParams(a1=0.02, a2=0.1, a3=-0.05), ["a1", "a2", "a3", "M"]),
    (lambda: PlantParams(cF=math.nan), ["cF", "nan"]),
    (lambda: PlantParams(a5=math.nan), ["a5", "nan"]),
    (lambda: PlantParams(substeps=0), ["substeps", "0"]),
    (lambda: PlantParams(foam_on_region=True, foam_x_min=1, foam_x_max=0, foam_y_min=0, foam_y_max=1), ["foam region"]),
    (lambda: PlantParams(foam_on_time="maybe"), ["foam_on_time", "maybe"]),
    (lambda: ControllerParams(goal_x=0.0, goal_y=0.0), ["goal", "start"]),
    (lambda: ControllerParams(gamma=math.nan), ["gamma", "nan"]),
    (lambda: ControllerParams(W_init=(0.05, math.nan, 0.05)), ["W_init[1]", "nan"]),
    (lambda: ControllerParams(P_init=(1, 0, 0, -1, 0, 1)), ["P_init", "positive definite"]),
    (lambda: ControllerParams(R=0), ["R", "0"]),
    (lambda: ControllerParams(p_norm="trace"), ["p_norm", "trace"]),
    (lambda: ControllerParams(adapt_t_start=10, adapt_t_end=5), ["adapt_t_end", "5"]),
    (lambda: ControllerParams(task="line", line_b2=2.0), ["line_b2", "2.0"]),
    (lambda: ControllerParams(h_state_cost_sign=0.5), ["h_state_cost_sign", "0.5"]),
    (lambda: run_direct(h=0.0), ["step", "0.0"]),
    (lambda: run_direct(h=math.nan), ["step", "nan"]),
    (lambda: run_direct(t_stop=-1.0), ["t_stop", "-1.0"]),
    (lambda: Sensor().step(0.0, 0.0, 0.0), ["step", "0.0"]),
])
def test_rejected_with_one_line_naming_parameter_and_value(make, words):
    with pytest.raises(ParameterError) as exc:
        make()
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_valid_unusual_inertia_parameters_are_accepted():
    # grouped parameters need not each be positive: M only has to be positive definite
    Plant(a1=0.05, a2=0.06, a3=-0.02)


def test_cli_reports_bad_parameter_in_one_line_with_exit_code_2():
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "direct", "G1", "--set", "sensor.ppr=-5"],
                       capture_output=True, text=True)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "ppr" in lines[0] and "-5" in lines[0]
    assert "Traceback" not in p.stderr
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "direct", "--set", "plant.nosuch=1"],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "nosuch" in p.stderr and "Traceback" not in p.stderr
