"""A ``units`` entry never silently contradicts a model description: a unit for a variable that declares a
different one is refused at check, unless the instance says override_declared_units (then check prints it)."""
from __future__ import annotations

import math

import pytest

from cosim_support import g1_with_paths
from wmr_cosim.cli import main
from wmr_cosim import cosim
from wmr_cosim.cosim.messages.errors import ScenarioError


def _plant(fmus, extra: str) -> str:
    return f'[instances.plant]\nfmu = "{fmus["WmrPlant"]}"\n{extra}'


def _plan(path):
    return cosim.resolve(cosim.load(path))


@pytest.mark.parametrize("var, unit, declared", [("alpha1", "deg", "rad"), ("x_A", "mm", "m")])
def test_a_unit_that_contradicts_the_declared_one_is_refused(built_fmus, tmp_path, var, unit, declared):
    path = g1_with_paths(tmp_path, built_fmus, f'[instances.plant.units]\n{var} = "{unit}"\n')
    with pytest.raises(ScenarioError) as err:
        _plan(path)
    msg = str(err.value)
    assert f"instances.plant.units.{var}" in msg
    assert f"'{unit}' contradicts the unit '{declared}' that WmrPlant.fmu declares for {var}" in msg
    assert "override_declared_units = true" in msg and "\n" not in msg


def test_check_refuses_it_in_one_line_with_exit_2(built_fmus, tmp_path, capsys):
    path = g1_with_paths(tmp_path, built_fmus, '[instances.plant.units]\nalpha1 = "deg"\n')
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "contradicts the unit 'rad'" in err


def test_the_declared_unit_or_the_same_unit_under_another_name_is_accepted(built_fmus, tmp_path):
    path = g1_with_paths(tmp_path, built_fmus, '[instances.plant.units]\nalpha1 = "rad"\nu1 = "Nm"\n')
    plan = _plan(path)
    assert plan.notes == []
    assert {(c.factor, c.offset) for c in plan.connections} == {(1.0, 0.0)}


def test_an_override_is_explicit_and_check_prints_it(built_fmus, tmp_path, capsys):
    path = g1_with_paths(tmp_path, built_fmus, _plant(built_fmus, 'override_declared_units = true\n'
                                                             '[instances.plant.units]\nalpha1 = "deg"\n'),
                         skip=("plant",))
    plan = _plan(path)
    conv = {c.spec.src: c.factor for c in plan.connections}
    assert conv["plant.alpha1"] == pytest.approx(math.pi / 180, rel=1e-15)   # the override is applied
    assert plan.notes == ["instances.plant.units.alpha1: 'deg' overrides the unit 'rad' that WmrPlant.fmu "
                          "declares for alpha1"]
    assert main(["check", str(path)]) == 0
    assert "note: instances.plant.units.alpha1: 'deg' overrides the unit 'rad'" in capsys.readouterr().out


def test_a_unit_on_a_variable_that_is_not_real_is_refused(built_fmus, tmp_path):
    path = g1_with_paths(tmp_path, built_fmus, '[instances.controller.units]\nadapt = "s"\n')
    with pytest.raises(ScenarioError, match=r"instances.controller.units.adapt: adapt is Boolean: units apply to "
                                            r"Real variables"):
        _plan(path)


def test_override_declared_units_must_be_a_boolean(built_fmus, tmp_path):
    path = g1_with_paths(tmp_path, built_fmus, _plant(built_fmus, 'override_declared_units = "yes"\n'),
                         skip=("plant",))
    with pytest.raises(ScenarioError, match=r"instances.plant.override_declared_units: 'yes': must be true or false"):
        cosim.load(path)


def test_the_columns_say_their_unit_and_fmu(built_fmus, tmp_path):
    plan = _plan(g1_with_paths(tmp_path, built_fmus))
    cols = plan.columns()
    assert cols["plant.alpha1"] == {"unit": "rad", "instance": "plant", "fmu": "WmrPlant.fmu", "variable": "alpha1"}
    assert cols["plant.x_A"]["unit"] == "m" and cols["time"]["unit"] == "s"
    assert set(cols) == {"time", *(r.column for r in plan.record)}
