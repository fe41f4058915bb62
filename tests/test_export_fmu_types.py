"""``wmr-cosim export-fmu`` of systems with connections that are not Float64 to Float64 (Integer, Boolean,
Enumeration, the FMI 3.0 integer and float types, Boolean <-> Real conversions) and with FMI 3.0 FMUs inside
(alone, and beside FMI 2.0 ones), built of Reference FMUs: exported with ``--fmi 2`` and ``--fmi 3``, run in
FMPy (and fmusim where it is beside the checkout), every output equals ``wmr-cosim run`` of the same scenario
bit for bit, Gauss-Seidel and Jacobi; what the container cannot hold of them is refused in one line, exit
2, nothing written."""
from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim.cli import main

from cosim_support import write_document
from reference_fmus import REF
from test_export_fmu import assert_same_columns, export, run
from host_tools import assert_printed_columns, fmusim_csv

STOP, STEP = 5.0, 0.05


def ref2(model: str) -> str:
    return str(REF / "fmi2" / f"{model}.fmu")


def ref3(model: str) -> str:
    return str(REF / "fmi3" / f"{model}.fmu")


def link(src: str, dst: str, **kw: Any) -> dict[str, Any]:
    return {"from": src, "to": dst, **kw}


def fmi2_system() -> dict[str, Any]:
    """FMI 2.0 FMUs: Integer, Boolean and Enumeration connections, Real -> Boolean (threshold) and Boolean ->
    Real (factor, offset) conversions, beside a Real copy."""
    return {"experiment": {"start": 0.0, "stop": STOP, "step": STEP},
            "instances": {"stair": {"fmu": ref2("Stair")}, "vdp": {"fmu": ref2("VanDerPol")},
                          "a": {"fmu": ref2("Feedthrough"), "parameters": {"Enumeration_input": 2}},
                          "b": {"fmu": ref2("Feedthrough")}},
            "connections": [link("stair.counter", "a.Int32_input"),
                            link("vdp.x0", "a.Boolean_input", convert=True, threshold=0.25),
                            link("vdp.x1", "a.Float64_continuous_input", factor=0.5),
                            link("a.Int32_output", "b.Int32_input"),
                            link("a.Boolean_output", "b.Boolean_input"),
                            link("a.Boolean_output", "b.Float64_continuous_input", convert=True, factor=2.0,
                                 offset=0.25),
                            link("a.Enumeration_output", "b.Enumeration_input")],
            "record": {"variables": ["stair.counter", "vdp.x0", "a.Int32_output", "a.Boolean_output",
                                     "a.Float64_continuous_output", "b.Int32_output", "b.Boolean_output",
                                     "b.Float64_continuous_output", "b.Enumeration_output"]}}


def fmi3_system() -> dict[str, Any]:
    """FMI 3.0 FMUs: Int32 as it is, Int32 -> Int8 -> Int32, Float64 -> Float32 (a factor) -> Float64,
    Real -> Boolean, Boolean -> Boolean, Boolean -> Float32; a Float32 start value (set with fmi3SetFloat32),
    Int32, Boolean and String start values and a Float64 parameter."""
    return {"experiment": {"start": 0.0, "stop": STOP, "step": STEP},
            "instances": {"stair": {"fmu": ref3("Stair")},
                          "vdp": {"fmu": ref3("VanDerPol"), "parameters": {"mu": 1.5}},
                          "a": {"fmu": ref3("Feedthrough"), "parameters": {"Float32_discrete_input": 0.1}},
                          "b": {"fmu": ref3("Feedthrough"), "parameters": {"String_input": "set"}},
                          "c": {"fmu": ref3("Feedthrough"), "parameters": {"Int32_input": 7, "Boolean_input": True}}},
            "connections": [link("stair.counter", "a.Int32_input"),
                            link("stair.counter", "a.Int8_input"),
                            link("a.Int8_output", "b.Int32_input"),
                            link("vdp.x0", "a.Boolean_input", convert=True, threshold=0.25),
                            link("a.Boolean_output", "b.Boolean_input"),
                            link("vdp.x1", "a.Float32_continuous_input", factor=0.3),
                            link("a.Float32_continuous_output", "b.Float64_continuous_input"),
                            link("a.Boolean_output", "b.Float32_discrete_input", convert=True, factor=2.0,
                                 offset=0.25),
                            link("b.Float32_discrete_output", "c.Float64_continuous_input"),
                            link("a.Float32_discrete_output", "c.Float64_discrete_input")],
            "record": {"variables": ["stair.counter", "vdp.x0", "vdp.x1", "a.Int32_output", "a.Boolean_output",
                                     "b.Int32_output", "b.Boolean_output", "b.Float64_continuous_output",
                                     "c.Float64_continuous_output", "c.Float64_discrete_output", "c.Int32_output",
                                     "c.Boolean_output"]}}


def mixed_system() -> dict[str, Any]:
    """FMI 2.0 and 3.0 FMUs side by side: Integer -> Int32 -> Integer, Boolean -> Boolean across versions
    (C int <-> C bool), Enumeration -> Enumeration (C int -> Int64), Float64 copies both ways."""
    return {"experiment": {"start": 0.0, "stop": STOP, "step": STEP},
            "instances": {"stair": {"fmu": ref2("Stair")}, "vdp": {"fmu": ref3("VanDerPol")},
                          "dahl": {"fmu": ref3("Dahlquist"), "parameters": {"k": 0.5}},
                          "f2": {"fmu": ref2("Feedthrough")}, "f3": {"fmu": ref3("Feedthrough")},
                          "g2": {"fmu": ref2("Feedthrough")}},
            "connections": [link("stair.counter", "f3.Int32_input"),
                            link("vdp.x0", "f2.Boolean_input", convert=True, threshold=0.25),
                            link("f2.Boolean_output", "f3.Boolean_input"),
                            link("f3.Boolean_output", "g2.Boolean_input"),
                            link("f2.Enumeration_output", "f3.Enumeration_input"),
                            link("dahl.x", "f2.Float64_continuous_input", factor=2.0),
                            link("f2.Float64_continuous_output", "f3.Float64_continuous_input", offset=1.0),
                            link("f3.Int32_output", "g2.Int32_input")],
            "record": {"variables": ["stair.counter", "vdp.x0", "dahl.x", "f2.Boolean_output",
                                     "f2.Float64_continuous_output", "f2.Enumeration_output", "f3.Int32_output",
                                     "f3.Boolean_output", "f3.Float64_continuous_output", "g2.Int32_output",
                                     "g2.Boolean_output"]}}


def arrays_system() -> dict[str, Any]:
    """FMI 3.0 arrays: StateSpace -> StateSpace, a Float64 vector through a factor (fmi3Set/GetFloat64 with
    the count of values), matrix and vector parameters (fmi3SetFloat64 of an array, whole)."""
    return {"experiment": {"start": 0.0, "stop": STOP, "step": STEP},
            "instances": {"s1": {"fmu": ref3("StateSpace"), "parameters": {
                              "A": [-1.0, 0.0, 0.0, 0.0, -2.0, 0.0, 0.0, 0.0, -0.5], "x0": [1.0, 2.0, 3.0]}},
                          "s2": {"fmu": ref3("StateSpace"), "parameters": {
                              "A": [-0.5, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -3.0]}}},
            "connections": [link("s1.y", "s2.u", factor=0.5)],
            "record": {"variables": ["s1.y", "s2.y"]}}


def mixed_rated_system() -> dict[str, Any]:
    """The mixed system with two instances at their own rates (the master's multi-rate passes)."""
    doc = mixed_system()
    doc["instances"]["f3"]["step"] = 4 * STEP
    doc["instances"]["vdp"]["step"] = 2 * STEP
    return doc


SYSTEMS = {"fmi2": fmi2_system, "fmi3": fmi3_system, "mixed": mixed_system, "arrays": arrays_system,
           "mixed at own rates": mixed_rated_system}
CASES = [(system, alg, face) for system in SYSTEMS for alg in ("gauss-seidel", "jacobi") for face in ("2", "3")]


def document(system: str, algorithm: str) -> dict[str, Any]:
    doc = SYSTEMS[system]()
    doc["experiment"]["algorithm"] = algorithm
    return doc


#: Recorded outputs that hold one value (a start value through a copy; checked below).
CONSTANT = ("c.Float64_discrete_output", "b.Enumeration_output", "f2.Enumeration_output", "c.Int32_output",
            "c.Boolean_output")


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str], np.ndarray]:
    """Each system's run, Gauss-Seidel and Jacobi."""
    out = {}
    for system in SYSTEMS:
        for alg in ("gauss-seidel", "jacobi"):
            out[(system, alg)] = run(document(system, alg), tmp_path_factory.mktemp(f"{system}-{alg}"))
    return out


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str, str], Path]:
    """Each case's container."""
    return {(system, alg, face): export(document(system, alg), tmp_path_factory.mktemp(f"{system}-{alg}-{face}"),
                                        "--fmi", face)
            for system, alg, face in CASES}


def in_fmpy(fmu: Path) -> np.ndarray:
    import fmpy

    return fmpy.simulate_fmu(str(fmu), stop_time=STOP, output_interval=STEP)


@pytest.mark.parametrize("system,algorithm,face", CASES)
def test_the_container_in_fmpy_equals_the_run_bit_for_bit(system: str, algorithm: str, face: str, runs: Any,
                                                          fmus: Any) -> None:
    ref = runs[(system, algorithm)]
    assert len(ref) == round(STOP / STEP) + 1
    assert_same_columns(in_fmpy(fmus[(system, algorithm, face)]), ref)


def test_the_runs_move_and_tell_the_conversions_apart(runs: Any) -> None:
    """(So that the equalities above say something: every recorded output changes, Gauss-Seidel and Jacobi
    differ, and the conversions leave their marks: Float32 rounding, the threshold, the factor and offset.)"""
    for system in SYSTEMS:
        gs, j = runs[(system, "gauss-seidel")], runs[(system, "jacobi")]
        for name in gs.dtype.names[1:]:
            if name not in CONSTANT:
                assert len(np.unique(gs[name])) > 1, (system, name)
        assert any(not np.array_equal(gs[n], j[n]) for n in gs.dtype.names[1:]), system
    r2 = runs[("fmi2", "gauss-seidel")]
    assert np.array_equal(r2["b.Boolean_output"], r2["vdp.x0"] > 0.25)
    assert set(np.unique(r2["b.Float64_continuous_output"])) == {0.25, 2.25}
    assert np.array_equal(r2["b.Int32_output"], r2["stair.counter"])
    assert np.all(r2["b.Enumeration_output"] == 2)   # (its own start is 1)
    r3 = runs[("fmi3", "gauss-seidel")]
    assert np.all(r3["c.Float64_discrete_output"] == float(np.float32(0.1)))
    assert np.array_equal(r3["b.Float64_continuous_output"], (r3["vdp.x1"] * 0.3).astype(np.float32).astype(float))
    assert set(np.unique(r3["c.Float64_continuous_output"])) == {0.25, 2.25}
    assert np.array_equal(r3["b.Int32_output"], r3["stair.counter"])
    assert np.all(r3["c.Int32_output"] == 7) and np.all(r3["c.Boolean_output"])
    rm = runs[("mixed", "gauss-seidel")]
    assert np.array_equal(rm["g2.Boolean_output"], rm["vdp.x0"] > 0.25)
    assert np.array_equal(rm["g2.Int32_output"], rm["stair.counter"])
    for alg in ("gauss-seidel", "jacobi"):   # (the rates tell)
        rated, one = runs[("mixed at own rates", alg)], runs[("mixed", alg)]
        assert not np.array_equal(rated["f3.Float64_continuous_output"], one["f3.Float64_continuous_output"])
        assert not np.array_equal(rated["g2.Boolean_output"], one["g2.Boolean_output"])


@pytest.mark.parametrize("face", ["2", "3"])
def test_values_the_host_sets_reach_the_inner_fmi3_fmu(face: str, fmus: Any, tmp_path: Path) -> None:
    """An FMI 3.0 FMU's Float64 parameter, Int32 and Boolean inputs set by FMPy, as --set does for the run."""
    import fmpy

    sets = {"vdp.mu": 0.75, "c.Int32_input": -9, "c.Boolean_input": False}
    got = fmpy.simulate_fmu(str(fmus[("fmi3", "gauss-seidel", face)]), stop_time=STOP, output_interval=STEP,
                            start_values=sets)
    want = run(document("fmi3", "gauss-seidel"), tmp_path, *(a for k, v in sets.items()
                                                             for a in ("--set", f"{k}={str(v).lower()}")))
    assert np.all(want["c.Int32_output"] == -9) and not np.any(want["c.Boolean_output"])
    assert_same_columns(got, want)


def test_the_container_declares_the_types(fmus: Any) -> None:
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    for face, types in (("2", ("Integer", "Boolean", "Integer")), ("3", ("Int32", "Boolean", "Int32"))):
        fmu = fmus[("mixed", "jacobi", face)]
        assert validate_fmu(str(fmu)) == []
        md = {v.name: v for v in read_model_description(str(fmu)).modelVariables}
        assert (md["f3.Int32_output"].type, md["f3.Boolean_output"].type, md["f2.Enumeration_output"].type) == types
        assert "f3.Int32_input" not in md and "g2.Boolean_input" not in md   # (driven by connections)
        names = zipfile.ZipFile(fmu).namelist()
        assert any(n.endswith("/binaries/x86_64-linux/Feedthrough.so") for n in names)
        assert "sources/container_inner3.c" in names


@pytest.mark.parametrize("system,face", [("fmi3", "2"), ("mixed", "3")])
def test_the_container_in_fmusim_equals_the_run(system: str, face: str, runs: Any, fmus: Any,
                                                 tmp_path: Path) -> None:
    """fmusim (a C host), to the 16 digits it writes."""
    ref = runs[(system, "gauss-seidel")]
    rows = fmusim_csv(fmus[(system, "gauss-seidel", face)], STOP, STEP, tmp_path)
    assert sorted(rows[0]) == sorted(ref.dtype.names) and len(rows) == len(ref) + 1
    assert_printed_columns(rows, ref)


# ------------------------------------------------------------------ what the container cannot hold of them
def _many_others(doc: dict[str, Any]) -> None:
    """257 connections that are not Float64 to Float64 (a chain of FMI 3.0 Feedthroughs, 12 each)."""
    ports = ["Float32_continuous", "Float32_discrete", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
             "Int64", "UInt64", "Boolean", "Enumeration"]
    n = 257 // len(ports) + 2
    doc["instances"] = {f"f{i}": {"fmu": ref3("Feedthrough")} for i in range(n)}
    doc["connections"] = [link(f"f{i}.{p}_output", f"f{i + 1}.{p}_input") for i in range(n - 1) for p in ports][:257]
    doc["record"] = {"variables": ["f0.Float64_continuous_output"]}


REFUSALS: dict[str, Any] = {
    "a String connection": lambda doc: doc["connections"].append(link("a.String_output", "b.String_input")),
    "an Int8 output": lambda doc: doc["record"]["variables"].append("a.Int8_output"),
    "a Float32 output": lambda doc: doc["record"]["variables"].append("a.Float32_continuous_output"),
    "an FMI 3.0 Enumeration output": lambda doc: doc["record"]["variables"].append("a.Enumeration_output"),
    "a Binary value": lambda doc: doc["instances"]["b"].update(parameters={"Binary_input": "00ff"}),
    "257 other connections": _many_others,
}
REFUSED_AT = {"a String connection": "connections", "an Int8 output": "record", "a Float32 output": "record",
              "an FMI 3.0 Enumeration output": "record", "a Binary value": "instances.b.parameters.Binary_input",
              "257 other connections": "connections"}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_what_the_container_cannot_hold_is_refused_in_one_line(case: str, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    doc = fmi3_system()
    REFUSALS[case](doc)
    sc = write_document(tmp_path / "system.toml", doc)
    before = sorted(tmp_path.iterdir())
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "System.fmu")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: error: ") and "\n" not in err, err
    assert f"system.toml: {REFUSED_AT[case]}: " in err, err
    assert sorted(tmp_path.iterdir()) == before
