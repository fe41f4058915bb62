"""Steps of varying length: an FMU that declares canHandleVariableCommunicationStepSize = false is never
given one.  Our sensor chain and controller are sampled-data blocks (their sample period is the
communication step: the filter (43) is discretised for it, the critic adapts once per step), so they
declare false and refuse a step of another length; the master refuses, at check and naming the
instance, the step-size control over any such FMU (ours or a third party's)."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from cosim_support import edited_fmu
from reference_fmus import REF
from wmr_cosim.cli import main
from wmr_cosim.cosim.model.description import load_model

ROOT = Path(__file__).resolve().parents[1]


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("fmi3", [False, True])
def test_our_sampled_data_fmus_declare_a_fixed_step_and_the_plant_a_variable_one(tmp_path, fmi3):
    from wmr_cosim.fmus.build import build_all
    names = ("WmrPlant3", "WmrSensor3", "WmrController3") if fmi3 else ("WmrPlant", "WmrSensor", "WmrController")
    fmus = build_all(tmp_path, models=names)
    declared = {n: load_model(fmus[n]).can_vary_step for n in names}
    assert declared == dict(zip(names, (True, False, False)))


def test_g1_under_the_step_size_control_is_refused_at_check_naming_the_sensor(capsys):
    rc = main(["check", str(ROOT / "scenarios" / "g1_learn.toml"), "--set", "experiment.algorithm=adaptive"])
    err = _one_line(capsys)
    assert rc == 2
    assert "instances.sensor" in err and "canHandleVariableCommunicationStepSize = false" in err, err
    assert "adaptive" in err


def test_g1_under_a_fixed_step_algorithm_is_accepted(capsys):
    assert main(["check", str(ROOT / "scenarios" / "g1_learn.toml")]) == 0, capsys.readouterr().err


def _dahlquist_fixed_step(folder: Path) -> Path:
    """The Reference FMU Dahlquist with canHandleVariableCommunicationStepSize edited to false."""
    def edit(name: str, data: bytes) -> bytes:
        if name != "modelDescription.xml":
            return data
        text = data.decode("utf-8")
        assert 'canHandleVariableCommunicationStepSize="true"' in text
        return text.replace('canHandleVariableCommunicationStepSize="true"',
                            'canHandleVariableCommunicationStepSize="false"').encode("utf-8")
    return edited_fmu(REF / "fmi2" / "Dahlquist.fmu", folder / "DahlquistFixed.fmu", edit)


def _scenario(folder: Path, fmu: Path, algorithm: str) -> Path:
    path = folder / f"dq_{algorithm}.toml"
    path.write_text(f'[experiment]\nstop = 1.0\nstep = 0.1\nalgorithm = "{algorithm}"\n'
                    f'[instances.dq]\nfmu = "{fmu}"\n')
    return path


def test_a_third_party_fmu_that_declares_a_fixed_step_is_refused_under_the_step_size_control(tmp_path, capsys):
    fixed = _dahlquist_fixed_step(tmp_path)
    assert load_model(fixed).can_vary_step is False
    rc = main(["check", str(_scenario(tmp_path, fixed, "adaptive"))])
    err = _one_line(capsys)
    assert rc == 2 and "instances.dq" in err and "DahlquistFixed.fmu" in err, err
    assert main(["check", str(_scenario(tmp_path, fixed, "gauss-seidel"))]) == 0, capsys.readouterr().err


def test_the_same_fmu_declaring_a_variable_step_runs_under_the_step_size_control(tmp_path, capsys):
    plain = tmp_path / "Dahlquist.fmu"
    shutil.copy(REF / "fmi2" / "Dahlquist.fmu", plain)
    assert main(["check", str(_scenario(tmp_path, plain, "adaptive"))]) == 0, capsys.readouterr().err


@pytest.mark.parametrize("model", ["WmrSensor", "WmrController"])
def test_our_sampled_data_fmu_refuses_a_step_of_another_length(built_fmus, model):
    """Stepped by FMPy directly (as any host would): steps of 2 ms, then one of 1 ms is refused with
    fmi2Discard."""
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

    fmu = built_fmus[model]
    md = read_model_description(str(fmu))
    unzipped = extract(str(fmu))
    try:
        slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                          instanceName="probe")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.doStep(0.0, 0.002)
        slave.doStep(0.002, 0.002)
        with pytest.raises(FMICallException, match="discard"):
            slave.doStep(0.004, 0.001)
        slave.terminate()
        slave.freeInstance()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)
