"""``wmr-cosim export-fmu --fmi 3``: the container behind the FMI 3.0 co-simulation API (its inner FMUs FMI
2.0).  Run in FMPy (and in fmusim where it is beside the checkout), every output equals ``wmr-cosim run`` of
the same scenario bit for bit, the two-mass system (Gauss-Seidel and Jacobi) and G1 cut to 10 s (Float64,
Int32 and Boolean outputs); a start value the host sets reaches the inner FMU; its description is a valid
FMI 3.0 one; an FMI version other than 2 or 3 is refused in one line."""
from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim.cli import main

from coupling_fmus import build_mass
from host_tools import assert_printed_columns, fmusim_csv
from test_export_fmu import (G1_STEP, G1_STOP, STEP, STOP, assert_equal, assert_same_columns, export, g1_run,
                             g1_scenario, in_fmpy, run, two_mass)


@pytest.fixture(scope="module")
def mass3(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return build_mass(tmp_path_factory.mktemp("mass"))


@pytest.fixture(scope="module")
def runs3(mass3: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray]]:
    """Each algorithm's FMI 3.0 container of the two-mass system and the run of its scenario."""
    out = {}
    for alg in ("gauss-seidel", "jacobi"):
        d = tmp_path_factory.mktemp(alg)
        doc = two_mass(mass3, alg)
        out[alg] = export(doc, d, "--fmi", "3"), run(doc, d)
    return out


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_the_fmi3_container_in_fmpy_equals_the_run_bit_for_bit(algorithm: str, runs3: Any) -> None:
    fmu, ref = runs3[algorithm]
    assert len(ref) == round(STOP / STEP) + 1
    assert_equal(in_fmpy(fmu), ref)


def test_the_fmi3_container_is_a_valid_fmi3_fmu(runs3: Any) -> None:
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    fmu = runs3["jacobi"][0]
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    assert md.fmiVersion == "3.0" and md.coSimulation is not None and md.modelExchange is None
    assert md.instantiationToken.startswith("{")
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert outputs == ["body.x", "body.v", "coupler.x", "coupler.v", "coupler.F"]
    assert [u.variable.name for u in md.outputs] == outputs
    assert [u.variable.name for u in md.initialUnknowns] == outputs
    assert {v.type for v in md.modelVariables} == {"Float64"}
    params = {v.name: v for v in md.modelVariables if v.causality == "parameter"}
    assert params["body.m1"].start == "1.0" and params["coupler.kc"].unit == "N/m"
    names = zipfile.ZipFile(fmu).namelist()
    assert "binaries/x86_64-linux/system.so" in names and not any(n.startswith("binaries/linux64") for n in names)
    assert "resources/system.txt" in names and "sources/container3.c" in names
    assert "resources/fmu0/binaries/linux64/MassForce.so" in names   # (this system's inner FMUs: FMI 2.0)


def test_a_start_value_the_host_sets_reaches_the_inner_fmu(mass3: tuple[Path, Path], runs3: Any,
                                                           tmp_path: Path) -> None:
    fmu, ref = runs3["gauss-seidel"]
    got = in_fmpy(fmu, start_values={"body.m1": 2.0, "coupler.kc": 50.0})
    want = run(two_mass(mass3, "gauss-seidel"), tmp_path, "--set", "body.m1=2.0", "--set", "coupler.kc=50.0")
    assert not np.array_equal(want["body.x"], ref["body.x"])
    assert_equal(got, want)


def test_the_fmi3_container_in_fmusim_equals_the_run(runs3: Any, tmp_path: Path) -> None:
    """fmusim (a C host) loading the FMI 3.0 face, to the 16 digits it writes."""
    fmu, ref = runs3["gauss-seidel"]
    rows = fmusim_csv(fmu, STOP, STEP, tmp_path)
    assert rows[0] == list(ref.dtype.names) and len(rows) == len(ref) + 1
    assert_printed_columns(rows, ref)


# ------------------------------------------------------------------ G1: pythonfmu FMUs inside, Int32 and Boolean
@pytest.fixture(scope="module")
def g1_3(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    """G1 (Gauss-Seidel) cut to 10 s as an FMI 3.0 container, and the run of its scenario."""
    d = tmp_path_factory.mktemp("g1")
    sc = g1_scenario(d, "gauss-seidel")
    assert main(["export-fmu", str(sc), "--out", str(d / "G1.fmu"), "--fmi", "3"]) == 0
    return d / "G1.fmu", g1_run(sc, d / "run")


def g1_in_fmpy(fmu: Path, **kw: Any) -> np.ndarray:
    import fmpy

    return fmpy.simulate_fmu(str(fmu), stop_time=G1_STOP, output_interval=G1_STEP, **kw)


def test_g1_as_fmi3_in_fmpy_equals_the_run_bit_for_bit(g1_3: Any) -> None:
    """Float64, Int32 (sensor.count1) and Boolean (controller.adapting) outputs equal the run's."""
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    fmu, ref = g1_3
    assert validate_fmu(str(fmu)) == []
    md = {v.name: v for v in read_model_description(str(fmu)).modelVariables}
    assert (md["sensor.count1"].type, md["controller.adapting"].type) == ("Int32", "Boolean")
    assert (md["plant.substeps"].type, md["plant.substeps"].start) == ("Int32", "2")
    assert len(ref) == round(G1_STOP / G1_STEP) + 1
    assert_same_columns(g1_in_fmpy(fmu), ref)


def test_int32_and_boolean_start_values_the_host_sets_reach_the_pythonfmu_fmu(g1_3: Any, tmp_path: Path) -> None:
    """plant.substeps (Int32) and plant.foam_on_time (Boolean) set by FMPy, as --set does for the run."""
    fmu, ref = g1_3
    got = g1_in_fmpy(fmu, start_values={"plant.substeps": 4, "plant.foam_on_time": True})
    want = g1_run(g1_scenario(tmp_path, "gauss-seidel"), tmp_path / "run", "--set", "plant.substeps=4",
                  "--set", "plant.foam_on_time=true")
    assert not np.array_equal(want["plant.x_A"], ref["plant.x_A"])
    assert not np.array_equal(want["plant.foam_level"], ref["plant.foam_level"])
    assert_same_columns(got, want)


def test_g1_as_fmi3_in_fmusim_equals_the_run(g1_3: Any, tmp_path: Path) -> None:
    fmu, ref = g1_3
    rows = fmusim_csv(fmu, G1_STOP, G1_STEP, tmp_path)
    assert sorted(rows[0]) == sorted(ref.dtype.names) and len(rows) == len(ref) + 1
    assert_printed_columns(rows, ref)


# ------------------------------------------------------------------ the option
@pytest.mark.parametrize("value", ["4", "x"])
def test_an_fmi_version_other_than_2_or_3_is_refused_in_one_line(value: str, mass3: tuple[Path, Path],
                                                                  tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from cosim_support import write_document

    sc = write_document(tmp_path / "system.toml", two_mass(mass3, "jacobi"))
    before = sorted(tmp_path.iterdir())
    with pytest.raises(SystemExit) as exc:
        main(["export-fmu", str(sc), "--out", str(tmp_path / "S.fmu"), "--fmi", value])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim export-fmu: error: argument --fmi: invalid ") and "\n" not in err, err
    assert sorted(tmp_path.iterdir()) == before
