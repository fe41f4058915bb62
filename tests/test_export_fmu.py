"""``wmr-cosim export-fmu``: a scenario's system as one FMI 2.0 co-simulation FMU whose runtime is the
master's compiled loop.  Run in FMPy (and in fmusim where it is beside the checkout), every output equals
``wmr-cosim run`` of the same scenario bit for bit, Gauss-Seidel and Jacobi; a value the host sets reaches
the inner FMU; what the container cannot hold is refused in one line, exit 2, nothing written."""
from __future__ import annotations

import csv
import shutil
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim.cli import main

from cosim_support import write_document
from coupling_fmus import TwoMass, build_mass, two_mass_document
from host_tools import OMSIMULATOR, assert_printed_columns, fmusim_csv, run_omsimulator, tool
from reference_fmus import REF

STOP, STEP = 1.0, 0.01


@pytest.fixture(scope="module")
def mass(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return build_mass(tmp_path_factory.mktemp("mass"))


def two_mass(fmus: tuple[Path, Path], algorithm: str) -> dict[str, Any]:
    """The two-mass system of C FMUs, the coupling force through a factor and an offset."""
    doc = two_mass_document(fmus, TwoMass(), stop=STOP, step=STEP)
    doc["experiment"]["algorithm"] = algorithm
    doc["connections"][2].update(factor=0.5, offset=0.25)
    return doc


def export(doc: dict[str, Any], folder: Path, *extra: str) -> Path:
    sc = write_document(folder / "system.toml", doc)
    out = folder / "System.fmu"
    assert main(["export-fmu", str(sc), "--out", str(out), *extra]) == 0
    return out


def run(doc: dict[str, Any], folder: Path, *extra: str) -> np.ndarray:
    sc = write_document(folder / "system.toml", doc)
    assert main(["run", str(sc), "--out", str(folder / "run"), "--quiet", *extra]) == 0
    return np.load(folder / "run" / "signals.npy")


def in_fmpy(fmu: Path, **kw: Any) -> np.ndarray:
    import fmpy

    return fmpy.simulate_fmu(str(fmu), **{"stop_time": STOP, "output_interval": STEP, **kw})


def assert_equal(got: np.ndarray, ref: np.ndarray) -> None:
    """Every column of the run in the container, bit for bit."""
    assert got.dtype.names == ref.dtype.names
    for name in ref.dtype.names:
        assert np.array_equal(got[name], ref[name]), (name, np.max(np.abs(got[name] - ref[name])))


@pytest.fixture(scope="module")
def runs(mass: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray]]:
    out = {}
    for alg in ("gauss-seidel", "jacobi"):
        d = tmp_path_factory.mktemp(alg)
        doc = two_mass(mass, alg)
        out[alg] = export(doc, d), run(doc, d)
    return out


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_the_container_in_fmpy_equals_the_run_bit_for_bit(algorithm: str, runs: Any) -> None:
    fmu, ref = runs[algorithm]
    assert len(ref) == round(STOP / STEP) + 1
    assert_equal(in_fmpy(fmu), ref)


@pytest.fixture(scope="module")
def rated(mass: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray]]:
    """The coupler at 4 times the base step (the master's multi-rate passes), each algorithm: FMU and run."""
    out = {}
    for alg in ("gauss-seidel", "jacobi"):
        d = tmp_path_factory.mktemp(f"rated-{alg}")
        doc = two_mass(mass, alg)
        doc["instances"]["coupler"]["step"] = 4 * STEP
        out[alg] = export(doc, d), run(doc, d)
    return out


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_an_instance_at_its_own_rate_in_fmpy_equals_the_run_bit_for_bit(algorithm: str, rated: Any,
                                                                        runs: Any) -> None:
    fmu, ref = rated[algorithm]
    assert not np.array_equal(ref["coupler.F"], runs[algorithm][1]["coupler.F"])   # (the rate tells)
    assert_equal(in_fmpy(fmu), ref)
    # the host's steps spanning the slow instance's (and ending between its points)
    assert_equal(in_fmpy(fmu, output_interval=4 * STEP), ref[::4])
    assert_equal(in_fmpy(fmu, output_interval=2 * STEP), ref[::2])


def test_gauss_seidel_and_jacobi_differ(runs: Any) -> None:
    """(So the equality above tells the two algorithms apart.)"""
    assert not np.array_equal(runs["gauss-seidel"][1]["coupler.F"], runs["jacobi"][1]["coupler.F"])


def test_a_start_value_the_host_sets_reaches_the_inner_fmu(mass: tuple[Path, Path], runs: Any,
                                                           tmp_path: Path) -> None:
    fmu, ref = runs["gauss-seidel"]
    got = in_fmpy(fmu, start_values={"body.m1": 2.0, "coupler.kc": 50.0})
    want = run(two_mass(mass, "gauss-seidel"), tmp_path, "--set", "body.m1=2.0", "--set", "coupler.kc=50.0")
    assert not np.array_equal(want["body.x"], ref["body.x"])
    assert_equal(got, want)


def test_the_container_is_a_valid_fmu(runs: Any) -> None:
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    fmu = runs["jacobi"][0]
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert outputs == ["body.x", "body.v", "coupler.x", "coupler.v", "coupler.F"]
    assert [u.variable.name for u in md.outputs] == outputs
    params = {v.name: v for v in md.modelVariables if v.causality == "parameter"}
    assert params["body.m1"].start == "1.0" and params["coupler.kc"].unit == "N/m"
    names = zipfile.ZipFile(fmu).namelist()
    assert "resources/system.txt" in names and "binaries/linux64/system.so" in names
    assert "resources/fmu0/binaries/linux64/MassForce.so" in names


def test_open_inputs_are_the_containers_and_the_host_drives_them(tmp_path: Path) -> None:
    """Feedthrough -> Feedthrough with a factor and offset: the first one's open input is the container's
    (its start value the scenario's), and an input signal of the host goes through both."""
    ft = str(REF / "fmi2" / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": STOP, "step": STEP},
           "instances": {"a": {"fmu": ft, "parameters": {"Float64_continuous_input": 3.0}}, "b": {"fmu": ft}},
           "connections": [{"from": "a.Float64_continuous_output", "to": "b.Float64_continuous_input",
                            "factor": 2.0, "offset": 1.0}],
           "record": {"variables": ["a.Float64_continuous_output", "b.Float64_continuous_output"]}}
    fmu = export(doc, tmp_path, "--name", "Twice")
    ref = run(doc, tmp_path)
    got = in_fmpy(fmu)
    assert_equal(got, ref)
    assert np.all(got["b.Float64_continuous_output"] == 7.0)
    signal = np.array([(0.0, 5.0), (STOP, 5.0)], dtype=[("time", float), ("a.Float64_continuous_input", float)])
    driven = in_fmpy(fmu, input=signal)
    assert np.all(driven["b.Float64_continuous_output"][1:] == 11.0)


@pytest.mark.parametrize("rates", ["one rate", "own rates"])
def test_the_container_in_fmusim_equals_the_run(rates: str, runs: Any, rated: Any, tmp_path: Path) -> None:
    """fmusim (a C host), to the 16 digits it writes; the coupler at its own rate too."""
    assert_fmusim_equals((runs if rates == "one rate" else rated)["gauss-seidel"], tmp_path)


def assert_fmusim_equals(case: tuple[Path, np.ndarray], tmp_path: Path) -> None:
    """The container ``case[0]`` run by fmusim (STOP, STEP), every column equal to the run ``case[1]`` to
    the 16 digits fmusim writes."""
    fmu, ref = case
    rows = fmusim_csv(fmu, STOP, STEP, tmp_path)
    assert rows[0] == list(ref.dtype.names) and len(rows) == len(ref) + 1
    assert_printed_columns(rows, ref)


# ------------------------------------------------------------------ what the container cannot hold yet
def _no_binary(mass: tuple[Path, Path], d: Path) -> Path:
    out = d / "NoBinary.fmu"
    with zipfile.ZipFile(mass[0]) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.infolist():
            if not item.filename.startswith("binaries/"):
                dst.writestr(item, src.read(item))
    return out


REFUSALS: dict[str, Any] = {
    "adaptive": lambda doc, m, d: doc["experiment"].update(algorithm="adaptive"),
    "condition events": lambda doc, m, d: doc.update(events=[{"when": "body.x > 0.1", "variable": "body.F",
                                                             "action": "override", "value": 1.0}]),
    "tables and own rates": lambda doc, m, d: (
        (d / "in.csv").write_text("time,body.F\n0.0,1.0\n1.0,2.0\n"), doc.update(inputs={"file": str(d / "in.csv")}),
        doc["instances"]["coupler"].update(step=4 * STEP), doc["connections"].pop(2)),
    "requirements": lambda doc, m, d: doc.update(requirements=[{"name": "r", "formula": "always body.x < 10"}]),
    "an FMI 3.0 Float32 output": lambda doc, m, d: (
        doc["instances"].update(ft3={"fmu": str(REF / "fmi3" / "Feedthrough.fmu")}),
        doc["record"]["variables"].append("ft3.Float32_continuous_output")),
    "FMI 3.0 model exchange": lambda doc, m, d: doc["instances"].update(
        ref={"fmu": str(REF / "fmi3" / "Dahlquist.fmu"), "interface": "model-exchange"}),
    "iterated with an FMI 3.0 FMU": lambda doc, m, d: (
        doc["experiment"].update(algorithm="iterated"),
        doc["instances"].update(ref={"fmu": str(REF / "fmi3" / "Dahlquist.fmu")})),
    "iterated with events": lambda doc, m, d: (
        doc["experiment"].update(algorithm="iterated"),
        doc.update(events=[{"time": 0.5, "variable": "body.F", "action": "override", "value": 1.0}])),
    "an Integer event on a Model Exchange instance": lambda doc, m, d: (
        doc["instances"].update(ft={"fmu": str(REF / "fmi2" / "Feedthrough.fmu"), "interface": "model-exchange",
                                    "solver": "rk4"}),
        doc.update(events=[{"time": 0.5, "variable": "ft.Int32_input", "action": "override", "value": 3}])),
    "an event on an FMI 3.0 Int8": lambda doc, m, d: (
        doc["instances"].update(ft3={"fmu": str(REF / "fmi3" / "Feedthrough.fmu")}),
        doc.update(events=[{"time": 0.5, "variable": "ft3.Int8_input", "action": "override", "value": 3}])),
    "scheduled execution": lambda doc, m, d: doc["instances"].update(
        clocks={"fmu": str(REF / "fmi3" / "Clocks.fmu"), "clock_ticks": {"inClock2": [0.0]}}),
    "no linux64 binary": lambda doc, m, d: doc["instances"]["body"].update(fmu=str(_no_binary(m, d))),
    "an FMI 3.0 UInt64 output": lambda doc, m, d: (
        doc["instances"].update(ft={"fmu": str(REF / "fmi3" / "Feedthrough.fmu")}),
        doc["record"]["variables"].append("ft.UInt64_output")),
    "an output name twice": lambda doc, m, d: doc["record"]["variables"].append("body.m1"),
    "a stop off the step's grid": lambda doc, m, d: doc["experiment"].update(stop=doc["experiment"]["stop"] + STEP / 2),
}


#: The field each refusal names.
REFUSED_AT = {"adaptive": "experiment.algorithm", "condition events": "events", "tables and own rates": "inputs",
              "requirements": "requirements", "an FMI 3.0 Float32 output": "record",
              "FMI 3.0 model exchange": "instances.ref", "scheduled execution": "instances.clocks",
              "iterated with an FMI 3.0 FMU": "instances.ref", "iterated with events": "events",
              "an Integer event on a Model Exchange instance": "events", "an event on an FMI 3.0 Int8": "events",
              "no linux64 binary": "instances.body.fmu",
              "an FMI 3.0 UInt64 output": "record", "an output name twice": "record",
              "a stop off the step's grid": "experiment.stop"}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_what_the_container_cannot_hold_is_refused_in_one_line(case: str, mass: tuple[Path, Path], tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    doc = two_mass(mass, "gauss-seidel")
    REFUSALS[case](doc, mass, tmp_path)
    sc = write_document(tmp_path / "system.toml", doc)
    before = sorted(tmp_path.iterdir())
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "System.fmu")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: error: ") and "\n" not in err, err
    assert f"system.toml: {REFUSED_AT[case]}: " in err, err   # the field that holds what cannot go
    assert sorted(tmp_path.iterdir()) == before


@pytest.mark.parametrize("args", [["--name", "1-bad"], ["--out-is-inner"], ["--out-not-fmu"]])
def test_bad_names_and_outputs_are_refused(args: list[str], mass: tuple[Path, Path], tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    body = shutil.copy(mass[0], tmp_path / "MassForce.fmu")
    doc = two_mass((Path(body), mass[1]), "jacobi")
    sc = write_document(tmp_path / "system.toml", doc)
    out = {"--out-is-inner": str(body), "--out-not-fmu": str(tmp_path / "System.zip")}.get(args[0],
                                                                                         str(tmp_path / "S.fmu"))
    before = {p: p.read_bytes() for p in tmp_path.iterdir()}
    extra = args if args[0] == "--name" else []
    assert main(["export-fmu", str(sc), "--out", out, *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: error: ") and "\n" not in err, err
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_our_c_plant_alone_in_the_container_equals_the_run(tmp_path: Path) -> None:
    """WmrCPlant by its model name: its open inputs the container's, its recorded outputs equal to the run's."""
    doc = {"instances": {"plant": {"fmu": "WmrCPlant"}}, "experiment": {"stop": 0.5, "step": STEP}}
    fmu = export(doc, tmp_path)
    ref = run(doc, tmp_path)
    assert len(ref.dtype.names) > 2
    import fmpy

    assert_equal(fmpy.simulate_fmu(str(fmu), stop_time=0.5, output_interval=STEP), ref)


# ------------------------------------------------------------------ G1: our robot's loop, pythonfmu FMUs inside
SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
G1_STOP, G1_STEP = 10.0, 0.002
G1_CASES = {"gauss-seidel": ("g1_learn.toml", "gauss-seidel"), "jacobi": ("g1_learn.toml", "jacobi"),
            "c plant": ("g1_c_plant.toml", "gauss-seidel")}


def g1_scenario(folder: Path, case: str) -> Path:
    """G1 (or G1 with our C plant: degrees and rpm at its ports) cut to 10 s, with the case's algorithm."""
    base, algorithm = G1_CASES[case]
    sc = folder / "g1.toml"
    sc.write_text(f"base = {str(SCENARIOS / base)!r}\n[experiment]\nstop = {G1_STOP!r}\n"
                  f"algorithm = {algorithm!r}\n")
    return sc


def g1_run(sc: Path, folder: Path, *extra: str) -> np.ndarray:
    assert main(["run", str(sc), "--out", str(folder), "--quiet", *extra]) == 0
    return np.load(folder / "signals.npy")


@pytest.fixture(scope="module")
def g1(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray]]:
    """Each case's container and the run of its scenario."""
    out = {}
    for case in G1_CASES:
        d = tmp_path_factory.mktemp("g1")
        sc = g1_scenario(d, case)
        assert main(["export-fmu", str(sc), "--out", str(d / "G1.fmu")]) == 0
        out[case] = d / "G1.fmu", g1_run(sc, d / "run")
    return out


def assert_same_columns(got: np.ndarray, ref: np.ndarray) -> None:
    """Every column of the run, bit for bit, by name (a host may order the columns by type)."""
    assert sorted(got.dtype.names) == sorted(ref.dtype.names) and len(got) == len(ref)
    for name in ref.dtype.names:
        assert np.array_equal(got[name], ref[name]), name


def g1_in_fmpy(fmu: Path, **kw: Any) -> np.ndarray:
    import fmpy

    return fmpy.simulate_fmu(str(fmu), stop_time=G1_STOP, output_interval=G1_STEP, **kw)


@pytest.mark.parametrize("case", list(G1_CASES))
def test_g1_through_pythonfmu_fmus_in_fmpy_equals_the_run_bit_for_bit(case: str, g1: Any) -> None:
    """Three pythonfmu FMUs (or two and our C plant) inside, called from a Python host that lets go of
    the GIL: Real, Integer (sensor.count1) and Boolean (controller.adapting) outputs equal the run's."""
    fmu, ref = g1[case]
    assert len(ref) == round(G1_STOP / G1_STEP) + 1
    assert ref["sensor.count1"].dtype.kind == "i" and ref["controller.adapting"].dtype == bool
    assert_same_columns(g1_in_fmpy(fmu), ref)


def test_g1_gauss_seidel_jacobi_and_the_c_plant_differ(g1: Any) -> None:
    """(So the equalities above tell the cases apart; the C plant's alpha1 is in degrees, its sensor's
    input in rad: the conversion is in the container.)"""
    gs, j, c = (g1[k][1] for k in G1_CASES)
    assert not np.array_equal(gs["plant.x_A"], j["plant.x_A"])
    assert np.allclose(c["plant.alpha1"][1:] * np.pi / 180, gs["plant.alpha1"][1:], rtol=1e-6)
    system = zipfile.ZipFile(g1["c plant"][0]).read("resources/system.txt").decode()
    assert f"copy 0 1 {(np.pi / 180).hex()} 0x0.0p+0" in system


def test_integer_and_boolean_parameters_the_host_sets_reach_the_pythonfmu_fmu(g1: Any, tmp_path: Path) -> None:
    """plant.substeps (Integer) and plant.foam_on_time (Boolean) set by FMPy, as --set does for the run."""
    fmu, ref = g1["gauss-seidel"]
    got = g1_in_fmpy(fmu, start_values={"plant.substeps": 4, "plant.foam_on_time": True})
    want = g1_run(g1_scenario(tmp_path, "gauss-seidel"), tmp_path / "run", "--set", "plant.substeps=4",
                  "--set", "plant.foam_on_time=true")
    assert not np.array_equal(want["plant.x_A"], ref["plant.x_A"])          # substeps
    assert not np.array_equal(want["plant.foam_level"], ref["plant.foam_level"])   # foam_on_time
    assert_same_columns(got, want)


def test_g1_container_declares_integer_and_boolean_variables(g1: Any) -> None:
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    fmu = g1["gauss-seidel"][0]
    assert validate_fmu(str(fmu)) == []
    md = {v.name: v for v in read_model_description(str(fmu)).modelVariables}
    assert (md["sensor.count1"].type, md["sensor.count1"].causality) == ("Integer", "output")
    assert (md["controller.adapting"].type, md["controller.adapting"].causality) == ("Boolean", "output")
    assert (md["plant.substeps"].type, md["plant.substeps"].start) == ("Integer", "2")
    assert (md["controller.adapt"].type, md["controller.adapt"].start) == ("Boolean", "true")   # the scenario's
    assert "controller.task" not in md   # (String parameters: the scenario's value, not the host's)


def test_g1_container_in_our_master_equals_the_run(g1: Any, tmp_path: Path) -> None:
    """The container as an instance of our master (which calls it holding the GIL), its columns the run's."""
    fmu, ref = g1["jacobi"]
    doc = {"experiment": {"start": 0.0, "stop": G1_STOP, "step": G1_STEP}, "instances": {"g1": {"fmu": str(fmu)}},
           "record": {"variables": ["*.*"]}}
    got = run(doc, tmp_path)
    assert got.dtype.names == tuple(["time"] + ["g1." + n for n in ref.dtype.names[1:]])
    for name in ref.dtype.names[1:]:
        assert np.array_equal(got["g1." + name], ref[name]), name


@pytest.mark.parametrize("case", list(G1_CASES))
def test_g1_in_fmusim_equals_the_run(case: str, g1: Any, tmp_path: Path) -> None:
    """fmusim (a C host, no Python in it: our loader starts one), to the 16 digits it writes."""
    fmu, ref = g1[case]
    rows = fmusim_csv(fmu, G1_STOP, G1_STEP, tmp_path)
    assert sorted(rows[0]) == sorted(ref.dtype.names) and len(rows) == len(ref) + 1
    assert_printed_columns(rows, ref)


@pytest.mark.parametrize("case", ["gauss-seidel", "c plant", "fmi 3"])
def test_g1_in_omsimulator_equals_the_run(case: str, g1: Any, tmp_path: Path) -> None:
    """OMSimulator (a C++ host, an empty environment: our loader finds the Python) runs the container, FMI 2.0
    and 3.0 faces, with no error logged; every recorded output equal to the run's to the 12 digits it writes
    (it writes each communication point twice, before and after its step: the last row of each time is
    taken; it adds the container's open inputs and, FMI 3.0, its ``time`` as columns)."""
    exe = tool(OMSIMULATOR)
    if case == "fmi 3":
        fmu = tmp_path / "G1v3.fmu"
        assert main(["export-fmu", str(g1_scenario(tmp_path, "gauss-seidel")), "--out", str(fmu), "--fmi", "3"]) == 0
        ref = g1["gauss-seidel"][1]
    else:
        fmu, ref = g1[case]
    p = run_omsimulator(exe, [str(fmu), "--mode=cs", f"--stopTime={G1_STOP!r}", f"--stepSize={G1_STEP!r}",
                              "--resultFile=r.csv"], tmp_path)
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    assert [ln for ln in (p.stdout + p.stderr).splitlines() if "error" in ln.lower()] == []
    with (tmp_path / "r.csv").open() as f:
        rows = list(csv.reader(f))
    head = [h.strip() for h in rows[0]]
    last: dict[str, list[str]] = {}
    for r in rows[1:]:
        last[r[0].strip()] = [x.strip() for x in r]
    assert list(last) == [f"{t:.12g}" for t in ref["time"]]
    for name in ref.dtype.names[1:]:
        j = head.index(name)
        got = [float(r[j]) for r in last.values()]
        assert got == [float(f"{float(x):.12g}") for x in ref[name]], name


def test_a_container_nests_in_a_container_and_an_ssp_archive(g1: Any, tmp_path: Path) -> None:
    """A scenario holding the G1 container exported again (a container inside a container) and to SSP: the
    outer container in FMPy and the run of the archive equal the run of G1, column by column; the outer
    container cannot be written over the inner one."""
    fmu, ref = g1["gauss-seidel"]
    doc = {"experiment": {"start": 0.0, "stop": G1_STOP, "step": G1_STEP}, "instances": {"g1": {"fmu": str(fmu)}},
           "record": {"variables": ["*.*"]}}
    sc = write_document(tmp_path / "nest.toml", doc)
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "Outer.fmu")]) == 0
    assert main(["export-ssp", str(sc), "--out", str(tmp_path / "nest.ssp")]) == 0
    assert main(["run", str(tmp_path / "nest.ssp"), "--out", str(tmp_path / "ssp"), "--quiet"]) == 0
    outer = g1_in_fmpy(tmp_path / "Outer.fmu")
    from_ssp = np.load(tmp_path / "ssp" / "signals.npy")
    for name in ref.dtype.names[1:]:
        assert np.array_equal(outer["g1." + name], ref[name]), name
        assert np.array_equal(from_ssp["g1." + name], ref[name]), name
    before = fmu.read_bytes()
    assert main(["export-fmu", str(sc), "--out", str(fmu)]) == 2
    assert fmu.read_bytes() == before


def test_outputs_that_feed_nothing_are_those_of_the_step_when_the_host_reads_them(tmp_path: Path) -> None:
    """An instance whose outputs feed no connection has them read when the host asks (the container saves
    the reads of the steps between): the host reads the outputs of the last step, also after it has set a
    new input that the FMU passes straight through, as the master's row holds them."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    ft = str(REF / "fmi2" / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": STOP, "step": STEP},
           "instances": {"b": {"fmu": ft, "parameters": {"Float64_continuous_input": 3.0}}},
           "record": {"variables": ["b.Float64_continuous_output"]}}
    fmu = export(doc, tmp_path)
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    d = extract(str(fmu), unzipdir=str(tmp_path / "x"))
    s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="c")
    s.instantiate()
    try:
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        out, inp = [vr["b.Float64_continuous_output"]], [vr["b.Float64_continuous_input"]]
        s.doStep(0.0, STEP)
        s.setReal(inp, [5.0])
        assert s.getReal(out) == [3.0]
        s.doStep(STEP, STEP)
        assert s.getReal(out) == [5.0]
        s.doStep(2 * STEP, STEP)
        s.setReal(inp, [6.0])
        s.doStep(3 * STEP, STEP)
        assert s.getReal(out) == [6.0]
        s.terminate()
    finally:
        s.freeInstance()
