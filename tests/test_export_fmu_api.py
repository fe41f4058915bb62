"""``Simulation.export_fmu``: the scenario a Simulation holds (built in code, parameters set on it) written
as one FMU, whose outputs in FMPy equal ``Simulation.run`` of the same document bit for bit; checked as the
command checks it (a ScenarioError naming the field, nothing written)."""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from wmr_cosim import ScenarioError, Simulation

from reference_fmus import REF

STOP, STEP = 2.0, 0.05


def chain(algorithm: str) -> Simulation:
    """Dahlquist -> Feedthrough (a factor and an offset) -> Feedthrough, Reference C FMUs."""
    ft = REF / "fmi2" / "Feedthrough.fmu"
    return (Simulation()
            .experiment(start=0.0, stop=STOP, step=STEP, algorithm=algorithm)
            .instance("d", REF / "fmi2" / "Dahlquist.fmu", k=0.5)
            .instance("f1", ft)
            .instance("f2", ft)
            .connect("d.x", "f1.Float64_continuous_input", factor=2.0, offset=1.0)
            .connect("f1.Float64_continuous_output", "f2.Float64_continuous_input")
            .record("d.x", "f1.Float64_continuous_output", "f2.Float64_continuous_output"))


@pytest.mark.parametrize("algorithm, fmi", [("gauss-seidel", 2), ("jacobi", 2), ("gauss-seidel", 3)])
def test_the_exported_fmu_in_fmpy_equals_the_run_bit_for_bit(algorithm: str, fmi: int, tmp_path: Path) -> None:
    import fmpy

    sim = chain(algorithm).parameter("d.k", 0.75)     # (an override the export must carry too)
    out = sim.export_fmu(tmp_path / "Chain.fmu", fmi=fmi)
    assert fmpy.read_model_description(str(out)).fmiVersion == f"{fmi}.0"
    assert out == tmp_path / "Chain.fmu" and out.is_file()
    ref = sim.run().signals
    got = fmpy.simulate_fmu(str(out), stop_time=STOP, output_interval=STEP)
    assert got.dtype.names == ref.dtype.names == ("time", "d.x", "f1.Float64_continuous_output",
                                                  "f2.Float64_continuous_output")
    assert len(ref) == round(STOP / STEP) + 1
    assert len(np.unique(ref["f2.Float64_continuous_output"])) > 5      # (the signals move)
    for name in ref.dtype.names:
        assert np.array_equal(got[name], ref[name]), (name, np.max(np.abs(got[name] - ref[name])))
    other = chain(algorithm).run().signals                             # (without the override: different)
    assert not np.array_equal(other["d.x"], ref["d.x"])


def test_its_name_is_a_c_name_system_by_default_for_a_simulation_built_in_code(tmp_path: Path) -> None:
    from fmpy import read_model_description

    sim = chain("jacobi")
    md = read_model_description(str(sim.export_fmu(tmp_path / "A.fmu")))
    assert md.modelName == "system" and md.coSimulation.modelIdentifier == "system"
    md = read_model_description(str(sim.export_fmu(tmp_path / "B.fmu", name="Chain3")))
    assert md.coSimulation.modelIdentifier == "Chain3"
    assert "binaries/linux64/Chain3.so" in zipfile.ZipFile(tmp_path / "B.fmu").namelist()


@pytest.mark.parametrize("case", ["events", "out", "name", "fmi"])
def test_what_it_cannot_hold_is_the_commands_scenario_error_and_nothing_is_written(case: str, tmp_path: Path) -> None:
    sim = chain("gauss-seidel")
    out, name, fmi = tmp_path / "S.fmu", None, 2
    if case == "events":
        sim.event(when="f1.Float64_continuous_output > 0.5", variable="f1.Float64_continuous_input",
                  action="override", value=1.0)   # (an event on a condition)
    elif case == "out":
        out = tmp_path / "S.zip"
    elif case == "name":
        name = "1-bad"
    else:
        fmi = 4
    with pytest.raises(ScenarioError) as err:
        sim.export_fmu(out, name, fmi)
    assert err.value.field == {"events": "events", "out": "out", "name": "--name", "fmi": "fmi"}[case]
    assert list(tmp_path.iterdir()) == []
