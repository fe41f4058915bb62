""""Did you mean" suggests only names that fit the place: an input for a connection's ``to``, an output for
its ``from``, a parameter for ``parameters`` and ``--set``, a known model name for ``fmu``."""
from __future__ import annotations

from pathlib import Path

import pytest

from wmr_cosim.cli import main

ROOT = Path(__file__).resolve().parents[1]
G1 = (ROOT / "scenarios" / "g1_learn.toml").read_text(encoding="utf-8")


def _error(tmp_path: Path, capsys, text: str, *args: str) -> str:
    path = tmp_path / "g1.toml"
    path.write_text(text, encoding="utf-8")
    assert main(["check", str(path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def _replace_once(old: str, new: str) -> str:
    assert G1.count(old) >= 1, old
    return G1.replace(old, new, 1)


def test_a_misspelt_connection_target_gets_the_input_not_the_output(tmp_path, capsys):
    # sensor has the input alpha1 and the outputs alpha_m1, alpha_dot_m1, ...
    err = _error(tmp_path, capsys, _replace_once('to = "sensor.alpha1"', 'to = "sensor.alpha_1"'))
    assert "did you mean 'alpha1'?" in err, err


def test_a_misspelt_connection_source_gets_an_output(tmp_path, capsys):
    # closest of all to 'alpha2x' is the input alpha2; of the outputs, alpha_m2
    err = _error(tmp_path, capsys, _replace_once('from = "sensor.alpha_m1"', 'from = "sensor.alpha2x"'))
    assert "did you mean 'alpha_m2'?" in err, err


def test_a_misspelt_parameter_gets_a_parameter(tmp_path, capsys):
    # of all the sensor's variables alpha1 (an input) and alpha_m1 (an output) are closest; of its parameters
    err = _error(tmp_path, capsys, G1, "--set", "sensor.alpha_1=0.5")
    assert "parameters.alpha_1" in err and "did you mean 'phase1'?" in err, err


def test_a_misspelt_model_name_gets_the_model(tmp_path, capsys):
    err = _error(tmp_path, capsys, _replace_once('fmu = "WmrPlant"', 'fmu = "WmrPlnt"'))
    assert "unknown model name 'WmrPlnt'" in err and "did you mean 'WmrPlant'?" in err, err


@pytest.mark.parametrize("line", ['to = "sensor.alpha1"', 'from = "sensor.alpha_m1"', 'fmu = "WmrPlant"'])
def test_the_lines_replaced_are_in_the_shipped_scenario(line):
    assert line in G1
