"""0 for the step or the tolerance is "the tool's choice", as the FMI Cross-Check's option files write it
(``StepSize 0``, ``RelTol 0``): the step the FMUs' default experiments give, else (stop - start) / 500 as
FMPy chooses; the tolerance each FMU's own.  ``check`` says which value was used."""
from __future__ import annotations

import json

import pytest

from reference_fmus import REF
from wmr_cosim.cli import main
from wmr_cosim.runner import fmu_plan

DQ, FT = REF / "fmi2" / "Dahlquist.fmu", REF / "fmi2" / "Feedthrough.fmu"


def test_step_0_takes_the_fmus_default_step_and_says_so(capsys):
    assert main(["check", str(DQ), "--set", "experiment.step=0"]) == 0
    out = capsys.readouterr().out
    assert "100 steps of 0.1 s" in out
    assert "note: experiment.step = 0 (the tool's choice): 0.1 s, the FMUs' default experiment" in out


def test_step_0_without_a_default_step_is_fmpys_stop_over_500(capsys):
    # Feedthrough's default experiment gives stopTime 2 and no step
    plan = fmu_plan(FT, {"experiment.step": 0})
    assert plan.scenario.step == 2.0 / 500 and plan.n_steps == 500
    assert "experiment.step = 0 (the tool's choice): 0.004 s, (stop - start) / 500, as FMPy chooses" in plan.notes


def test_tolerance_0_is_each_fmus_own(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["check", str(DQ), "--set", "experiment.tolerance=0"]) == 0
    assert "note: experiment.tolerance = 0 (the tool's choice): each FMU's own (Dahlquist none;" in capsys.readouterr().out
    assert main(["run", str(DQ), "--set", "experiment.tolerance=0", "--solver", "cvode", "--out", "o", "--quiet"]) == 0
    scen = json.loads((tmp_path / "o" / "scenario.json").read_text())
    assert scen["experiment"]["tolerance"] is None and scen["instances"]["Dahlquist"]["tolerance"] is None


@pytest.mark.parametrize("value", ["-0.1", "true"])
def test_a_negative_or_other_step_is_still_refused(capsys, value):
    assert main(["check", str(DQ), "--set", f"experiment.step={value}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "experiment.step" in err, err
