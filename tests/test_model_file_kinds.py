"""One function decides what a file given to the master is, by its suffix in any case."""
from __future__ import annotations

import shutil

import pytest

from reference_fmus import REF
from wmr_cosim.cli import main
from wmr_cosim.cosim.model.kinds import FileKind, file_kind, named_kind
from wmr_cosim.cosim.scenario.document import is_path


@pytest.mark.parametrize("name, kind", [("a.fmu", FileKind.FMU), ("A.FMU", FileKind.FMU), ("x/s.ssp", FileKind.SSP),
                                        ("S.Ssp", FileKind.SSP), ("g1.toml", FileKind.SCENARIO),
                                        ("G1.TOML", FileKind.SCENARIO), ("scenario", FileKind.SCENARIO),
                                        ("fmu", FileKind.SCENARIO)])
def test_the_kind_comes_from_the_suffix_in_any_case(name, kind):
    assert file_kind(name) is kind


def test_a_protocol_with_an_upper_case_suffix_is_checked_as_a_protocol(tmp_path, capsys):
    fmu = REF / "fmi2" / "Dahlquist.fmu"
    path = tmp_path / "P.TOML"
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.05\n[instances.d]\nfmu = "{fmu}"\n'
                    '[record]\nvariables = ["d.x"]\n[[runs]]\nname = "a"\n[[runs]]\nname = "b"\n'
                    'carry = { "d.k" = "a.d.x" }\n')
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "run a: ok" in out and "run b: ok: 2 steps, 1 recorded variable, 1 carried value" in out


def test_an_fmu_with_an_upper_case_suffix_takes_an_input_table(tmp_path, capsys):
    fmu = tmp_path / "FEEDTHROUGH.FMU"
    shutil.copy(REF / "fmi2" / "Feedthrough.fmu", fmu)
    table = tmp_path / "in.csv"
    table.write_text("time,Float64_continuous_input\n0,1\n1,2\n")
    assert main(["check", str(fmu), "--input", str(table)]) == 0


@pytest.mark.parametrize("name, kind", [("a.fmu", FileKind.FMU), ("A.Fmu", FileKind.FMU), ("s.SSP", FileKind.SSP),
                                        ("G1.TOML", FileKind.SCENARIO), ("notes.txt", None), ("fmu", None)])
def test_the_kind_a_name_declares(name, kind):
    assert named_kind(name) is kind


def test_every_dispatch_on_a_suffix_takes_any_case(tmp_path, capsys):
    """An instance's fmu "X.FMU" is a path, not a model name; export-ssp writes to "OUT.SSP"; and run's
    --record before the scenario takes the last word as the scenario when its suffix is ".TOML"."""
    assert is_path("Plant.FMU") and is_path("plant.fmu") and not is_path("WmrPlant")
    fmu = tmp_path / "DAHLQUIST.FMU"
    shutil.copy(REF / "fmi2" / "Dahlquist.fmu", fmu)
    path = tmp_path / "S.TOML"
    path.write_text('[experiment]\nstop = 0.1\nstep = 0.05\n[instances.d]\nfmu = "DAHLQUIST.FMU"\n')
    assert main(["export-ssp", str(path), "--out", str(tmp_path / "OUT.SSP")]) == 0
    assert (tmp_path / "OUT.SSP").is_file()
    assert main(["run", "--quiet", "--out", str(tmp_path / "out"), "--record", "d.x", str(path)]) == 0
    assert "S.TOML: ok" in capsys.readouterr().out
