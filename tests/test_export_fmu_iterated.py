"""``wmr-cosim export-fmu`` of a scenario with ``algorithm = "iterated"``: the container iterates each coupling
loop as the master does (cosim/stepping/container_iter.c), rolling its inner FMUs back through
fmi2GetFMUstate / fmi2SetFMUstate.  Run in FMPy (and fmusim), every output equals ``wmr-cosim run`` bit for
bit: the two-mass oscillator of two C FMUs (a loop of three coupling inputs, the coupling force through a
factor and an offset) by the fixed point with relaxation, by Newton (a 3 by 3 Jacobian by forward
differences, kept while it serves) and by Newton with the inputs linear over the step; a pure algebraic
loop of two affine FMUs (one.u through a factor and an offset) by the fixed point (solved at
initialisation too), and an expanding one by Newton, its Jacobian by forward differences and by directional
derivatives (its rows swapped by the pivoting); the FMI 3.0 face.  A loop that fails mid-run ends the host's step with the run's own line, the
rows before it equal.  An instance of a loop that cannot get and set its state is refused in one line."""
from __future__ import annotations

import json
import random
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim.cli import main
from wmr_cosim.cosim.plan.container import FORMAT
from wmr_cosim.cosim.stepping.iterated import solve_linear

from cosim_support import write_document
from coupling_fmus import AffineLoop, build_affine, build_mass
from test_export_fmu import STEP, STOP, assert_equal, assert_fmusim_equals, export, in_fmpy, run, two_mass

#: Each case: the system ("mass", "affine": LOOP, "expanding": EXPANDING) and its [experiment.iteration].
CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "fixed point": ("mass", {"method": "fixed-point", "relaxation": 0.7, "max_iterations": 60}),
    "newton": ("mass", {"method": "newton"}),
    "newton, linear inputs": ("mass", {"method": "newton", "inputs": "linear"}),
    "expanding, newton, directional": ("expanding", {"method": "newton", "jacobian": "directional", "tolerance": 1e-12}),
    "expanding, newton": ("expanding", {"method": "newton", "tolerance": 1e-12}),
    "affine, fixed point": ("affine", {"method": "fixed-point", "tolerance": 1e-12, "max_iterations": 100}),
}
#: The algebraic loop: y1 = 0.5 u1 + 1 + 0.3 t + 0.5 sin 3t, y2 = 0.8 u2 - 1 + 0.2 sin 7t (the initial exchange,
#: three passes of outputs to inputs, leaves it unsolved at t = 0).
LOOP = AffineLoop(0.5, 0.8, (1.0, 0.3, 0.5, 3.0), (-1.0, 0.0, 0.2, 7.0))
#: The same with a1 = 2.3: the fixed point diverges, Newton's Jacobian needs its rows swapped (pivoting).
EXPANDING = AffineLoop(2.3, 0.7, (1.1, 0.3, 0.5, 3.0), (-0.9, 0.0, 0.2, 7.0))
#: ... with one.u = FACTOR * two.y + OFFSET.
FACTOR, OFFSET = 1.3, 0.35
#: A loop whose fixed point needs more iterations as the run goes on (33 are too few from about t = 0.3 s).
MID_RUN = AffineLoop(0.5, 0.8, (1.0, -1.5, 0.5, 3.0), (-2.0, 0.0, 0.0, 1.0))


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    d = tmp_path_factory.mktemp("fmus")
    return {"mass": build_mass(d), "affine": build_affine(d)}


def document(fmus: dict[str, Any], case: str, algorithm: str = "iterated") -> dict[str, Any]:
    system, iteration = CASES[case]
    if system == "mass":
        doc = two_mass(fmus["mass"], algorithm)
    else:
        doc = (LOOP if system == "affine" else EXPANDING).document(fmus["affine"], stop=STOP, step=STEP)
        doc["connections"][1].update(factor=FACTOR, offset=OFFSET)   # two.y -> one.u
    doc["experiment"]["algorithm"] = algorithm
    if algorithm == "iterated":
        doc["experiment"]["iteration"] = iteration
    return doc


@pytest.fixture(scope="module")
def runs(fmus: dict[str, Any], tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray]]:
    """Each case's container and the run of its scenario."""
    out = {}
    for case in CASES:
        d = tmp_path_factory.mktemp("case")
        doc = document(fmus, case)
        out[case] = export(doc, d), run(doc, d)
    return out


@pytest.mark.parametrize("case", list(CASES))
def test_the_iterated_container_in_fmpy_equals_the_run_bit_for_bit(case: str, runs: Any) -> None:
    fmu, ref = runs[case]
    assert len(ref) == round(STOP / STEP) + 1
    assert_equal(in_fmpy(fmu), ref)


def test_the_cases_differ_from_one_pass_and_from_each_other(fmus: dict[str, Any], runs: Any, tmp_path: Path) -> None:
    """(So the equalities above tell the methods apart.)  The algebraic loop is solved at t = 0 too: its
    first row meets the closed form, where one Gauss-Seidel pass (no solve at initialisation) does not."""
    gs = {}
    for system, case in (("mass", "newton"), ("affine", "affine, fixed point")):
        (tmp_path / system).mkdir()
        gs[system] = run(document(fmus, case, "gauss-seidel"), tmp_path / system)
    for case, (system, _) in CASES.items():
        if system != "expanding":
            assert not np.array_equal(runs[case][1]["body.x" if system == "mass" else "one.y"],
                                      gs[system]["body.x" if system == "mass" else "one.y"]), case
    assert not np.array_equal(runs["expanding, newton"][1]["one.y"], runs["expanding, newton, directional"][1]["one.y"])
    fp, nw, lin = (runs[c][1]["coupler.F"] for c in ("fixed point", "newton", "newton, linear inputs"))
    assert not np.array_equal(fp, nw) and not np.array_equal(nw, lin)
    b1, b2 = LOOP.b1[0], LOOP.b2[0]   # (at t = 0)
    y1 = (LOOP.a1 * (FACTOR * b2 + OFFSET) + b1) / (1.0 - LOOP.a1 * FACTOR * LOOP.a2)
    y2 = LOOP.a2 * y1 + b2

    def first_row_error(sig: np.ndarray) -> float:
        return max(abs(sig["one.y"][0] - y1), abs(sig["two.y"][0] - y2))
    assert first_row_error(runs["affine, fixed point"][1]) < 1e-10
    assert first_row_error(gs["affine"]) > 1e-3


def test_the_settings_and_loops_are_in_system_txt(runs: Any) -> None:
    text = zipfile.ZipFile(runs["newton"][0]).read("resources/system.txt").decode()
    assert text.startswith(FORMAT + "\n")
    lines = text.splitlines()
    head = next(line for line in lines if line.startswith("iteration "))
    assert head.split()[:3] == ["iteration", "1", "1"] and head.split()[-1] == "1"   # Newton; one component
    comp = next(line for line in lines if line.startswith("comp "))
    assert comp == "comp 1 2 0 1 3"   # a loop of body and coupler, three coupling inputs
    assert sum(line.startswith("unknown ") for line in lines) == 3
    names = zipfile.ZipFile(runs["newton"][0]).namelist()
    assert "sources/container_iter.c" in names


def test_the_fmi3_face_iterates_as_the_run(fmus: dict[str, Any], runs: Any, tmp_path: Path) -> None:
    fmu = export(document(fmus, "newton"), tmp_path, "--fmi", "3")
    assert_equal(in_fmpy(fmu), runs["newton"][1])


def test_the_iterated_container_in_fmusim_equals_the_run(runs: Any, tmp_path: Path) -> None:
    """fmusim (a C host), to the 16 digits it writes: Newton on the two-mass system."""
    assert_fmusim_equals(runs["newton"], tmp_path)


def test_a_loop_failing_mid_run_ends_the_hosts_step_with_the_runs_line(fmus: dict[str, Any], tmp_path: Path) -> None:
    """The fixed point limited to 33 iterations fails at a step after the first tens: the container's
    fmi2DoStep returns fmi2Error with the run's own message (the host's logger gets it), and every row
    before it equals the run's."""
    import fmpy
    from fmpy.fmi1 import FMICallException

    doc = MID_RUN.document(fmus["affine"], stop=STOP, step=STEP)
    doc["experiment"].update(algorithm="iterated", iteration={"method": "fixed-point", "max_iterations": 33})
    fmu = export(doc, tmp_path)
    sc = write_document(tmp_path / "system.toml", doc)
    assert main(["run", str(sc), "--out", str(tmp_path / "run"), "--quiet"]) == 1
    message = json.loads((tmp_path / "run" / "summary.json").read_text())["message"]
    ref = np.load(tmp_path / "run" / "signals.npy")
    assert 20 <= len(ref) < 101 and "the coupling loop one <-> two did not converge at step" in message
    logged: list[bytes] = []
    seen: dict[str, Any] = {}

    def finished(t: float, recorder: Any) -> bool:
        seen["recorder"] = recorder
        return True

    unzipped = fmpy.extract(str(fmu), unzipdir=str(tmp_path / "unzipped"))   # (FMPy's own is left where it fails)
    with pytest.raises(FMICallException, match="fmi2DoStep"):
        fmpy.simulate_fmu(unzipped, stop_time=STOP, output_interval=STEP, step_finished=finished,
                          logger=lambda env, name, status, category, text: logged.append(text))
    assert logged == [message.encode()]
    assert_equal(seen["recorder"].result(), ref)


def test_a_loop_instance_that_cannot_get_and_set_its_state_is_refused(fmus: dict[str, Any], tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    body = tmp_path / "MassForce.fmu"
    with zipfile.ZipFile(fmus["mass"][0]) as src, zipfile.ZipFile(body, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'canGetAndSetFMUstate="true"', b'canGetAndSetFMUstate="false"')
            dst.writestr(item, data)
    doc = document({**fmus, "mass": (body, fmus["mass"][1])}, "newton")
    sc = write_document(tmp_path / "system.toml", doc)
    before = sorted(tmp_path.iterdir())
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "System.fmu")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: error: ") and "\n" not in err, err
    assert "system.toml: instances.body: MassForce.fmu cannot get and set its state" in err, err
    assert sorted(tmp_path.iterdir()) == before


def test_newtons_linear_solve_is_gaussian_elimination_in_plain_floats() -> None:
    """solve_linear (the master's, which container_iter.c repeats operation for operation): within 1e-12 of
    numpy's solve on random systems of 1 to 4 unknowns, exactly b / a for one, None where a pivot is zero;
    it pivots (a zero in the first pivot's place is no obstacle)."""
    rng = random.Random(7)
    for n in (1, 2, 3, 4):
        for _ in range(200):
            a = [[rng.uniform(-2, 2) * 10 ** rng.randint(-3, 3) for _ in range(n)] for _ in range(n)]
            b = [rng.uniform(-1, 1) for _ in range(n)]
            x = solve_linear(a, b)
            assert x is not None and all(type(v) is float for v in x)
            assert np.allclose(x, np.linalg.solve(np.array(a), np.array(b)), rtol=1e-9, atol=1e-12)
            if n == 1:
                assert x == [b[0] / a[0][0]]
    assert solve_linear([[0.0, 1.0], [2.0, 0.0]], [3.0, 4.0]) == [2.0, 3.0]
    assert solve_linear([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0]) is None
    assert solve_linear([[0.0]], [1.0]) is None
