"""``wmr-cosim export-fmu`` of a system holding Model Exchange FMUs: the container integrates them with the
master's integrators (explicit Euler, RK4 with ``max_step`` sub-steps and state events located by bisection;
CVODE from FMPy's SUNDIALS libraries, shipped inside) and handles their events as the master does
(stepping/container_me.c), so that run in FMPy (and in fmusim, which links a SUNDIALS of its own) every
output equals ``wmr-cosim run`` of the same scenario bit for bit: our C plant as Model Exchange in G1
(Gauss-Seidel and Jacobi; its foam's time events and its state event), the Reference FMUs' BouncingBall
with its bounces.  What the container cannot hold is refused in one line, exit 2, nothing written."""
from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim.cli import main
from wmr_cosim.cosim.plan import container

from cosim_support import write_document
from host_tools import fmusim_csv
from reference_fmus import REF

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
G1_STOP, G1_STEP = 10.0, 0.002

#: The C plant's foam, reached by region (a state event: A enters the rectangle, at t = 6.45 s) or by time
#: (time events at its kinks, 3.00033 s and 0.1 s later, off the sub-steps' grid), and then felt by the wheels.
FOAM = {"none": {},
        "region": {"foam_on_region": True, "foam_x_min": 0.5, "foam_x_max": 3.0, "foam_y_min": 0.1,
                   "foam_y_max": 3.0, "foam_da1": 0.05, "foam_da2": 0.04},
        "time": {"foam_on_time": True, "foam_t_on": 3.00033, "foam_da1": 0.05, "foam_da2": 0.04}}

#: (solver, max_step or None, algorithm, foam)
G1_CASES = {"rk4 gauss-seidel": ("rk4", 0.001, "gauss-seidel", "none"),
            "rk4 jacobi": ("rk4", 0.001, "jacobi", "none"),
            "euler gauss-seidel": ("euler", 0.0005, "gauss-seidel", "none"),
            "euler jacobi": ("euler", 0.0005, "jacobi", "none"),
            "rk4 foam by region": ("rk4", 0.001, "gauss-seidel", "region"),
            "euler foam by time": ("euler", 0.0005, "jacobi", "time"),
            "rk4 one step per step": ("rk4", None, "gauss-seidel", "none"),
            "cvode gauss-seidel": ("cvode", None, "gauss-seidel", "none"),   # (g1_c_plant_me.toml as it is)
            "cvode jacobi": ("cvode", None, "jacobi", "none"),
            "cvode foam by region": ("cvode", None, "gauss-seidel", "region"),
            "cvode foam by time": ("cvode", 0.01, "jacobi", "time")}


def g1_scenario(folder: Path, case: str) -> Path:
    """G1 with our C plant as Model Exchange (scenarios/g1_c_plant_me.toml: CVODE at a relative tolerance of
    1e-9) cut to 10 s, with the case's integrator, algorithm and foam."""
    solver, max_step, algorithm, foam = G1_CASES[case]
    lines = [f"base = {str(SCENARIOS / 'g1_c_plant_me.toml')!r}", "[experiment]", f"stop = {G1_STOP!r}",
             f"algorithm = {algorithm!r}", "[instances.plant]", f"solver = {solver!r}"]
    if max_step is not None:
        lines.append(f"max_step = {max_step!r}")
    if FOAM[foam]:
        lines.append("[instances.plant.parameters]")
        lines += [f"{k} = {str(v).lower() if isinstance(v, bool) else repr(v)}" for k, v in FOAM[foam].items()]
    sc = folder / "g1.toml"
    sc.write_text("\n".join(lines) + "\n")
    return sc


def export_and_run(sc: Path, folder: Path) -> tuple[Path, np.ndarray, dict[str, Any]]:
    """The scenario's container and its run (signals, summary)."""
    import json

    assert main(["export-fmu", str(sc), "--out", str(folder / "S.fmu")]) == 0
    assert main(["run", str(sc), "--out", str(folder / "run"), "--quiet"]) == 0
    return (folder / "S.fmu", np.load(folder / "run" / "signals.npy"),
            json.loads((folder / "run" / "summary.json").read_text()))


def assert_same_columns(got: np.ndarray, ref: np.ndarray) -> None:
    """Every column of the run, bit for bit, by name."""
    assert sorted(got.dtype.names) == sorted(ref.dtype.names) and len(got) == len(ref)
    for name in ref.dtype.names:
        assert np.array_equal(got[name], ref[name]), name


def in_fmpy(fmu: Path, stop: float, step: float, **kw: Any) -> np.ndarray:
    import fmpy

    return fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=step, **kw)


@pytest.fixture(scope="module")
def g1(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray, dict[str, Any]]]:
    out = {}
    for case in G1_CASES:
        d = tmp_path_factory.mktemp("g1me")
        out[case] = export_and_run(g1_scenario(d, case), d)
    return out


@pytest.mark.parametrize("case", list(G1_CASES))
def test_the_c_plant_as_model_exchange_in_fmpy_equals_the_run_bit_for_bit(case: str, g1: Any) -> None:
    fmu, ref, _ = g1[case]
    assert len(ref) == round(G1_STOP / G1_STEP) + 1
    assert_same_columns(in_fmpy(fmu, G1_STOP, G1_STEP), ref)


def test_the_cases_differ_and_the_foam_events_happen(g1: Any) -> None:
    """(So the equalities above tell the integrators, the algorithms and the events apart.)"""
    x = {case: g1[case][1]["plant.x_A"] for case in G1_CASES}
    for a, b in [("rk4 gauss-seidel", "rk4 jacobi"), ("rk4 gauss-seidel", "euler gauss-seidel"),
                 ("euler gauss-seidel", "euler jacobi"), ("rk4 gauss-seidel", "rk4 one step per step"),
                 ("cvode gauss-seidel", "cvode jacobi"), ("cvode gauss-seidel", "rk4 gauss-seidel")]:
        assert not np.array_equal(x[a], x[b]), (a, b)
    assert not np.any(g1["rk4 gauss-seidel"][1]["plant.foam_level"])
    for solver in ("rk4", "euler", "cvode"):
        events = {case: [(e["time"], e["kind"]) for e in g1[case][2]["events"]]
                  for case in (f"{solver} foam by region", f"{solver} foam by time") if case in g1}
        region, timed = events.get(f"{solver} foam by region"), events.get(f"{solver} foam by time")
        if region is not None:   # (the entry, then the ramp's end)
            assert [k for _, k in region] == ["state", "time"] and 6.4 < region[0][0] < 6.5, region
        if timed is not None:    # (off the grid of the sub-steps)
            assert timed == [(3.00033, "time"), (3.00033 + 0.1, "time")], timed
    system = zipfile.ZipFile(g1["rk4 foam by region"][0]).read("resources/system.txt").decode()
    assert f"me rk4 1 {0.001.hex()} {1e-10.hex()} 0x0.0p+0 7 1 1 0" in system
    system = zipfile.ZipFile(g1["cvode gauss-seidel"][0]).read("resources/system.txt").decode()
    assert f"me cvode 1 {(10.0 / 50).hex()} {1e-10.hex()} {1e-9.hex()} 7 1 1 0" in system   # (stop / 50, the tolerance)


# ------------------------------------------------------------------ BouncingBall: state events, its bounces
BALL_STOP, BALL_STEP = 3.0, 0.01
BALL_CASES = {"rk4": {"solver": "rk4", "max_step": 0.001}, "euler": {"solver": "euler"},
              "rk4 coarse events": {"solver": "rk4", "max_step": 0.002, "event_tolerance": 1e-4},
              "cvode": {}, "cvode tight": {"solver": "cvode", "tolerance": 1e-10, "max_step": 0.05}}


def ball_doc(case: str, algorithm: str = "gauss-seidel") -> dict[str, Any]:
    return {"experiment": {"start": 0.0, "stop": BALL_STOP, "step": BALL_STEP, "algorithm": algorithm},
            "instances": {"ball": {"fmu": str(REF / "fmi2" / "BouncingBall.fmu"), "interface": "model-exchange",
                                   **BALL_CASES[case]}},
            "record": {"variables": ["ball.h", "ball.v"]}}


@pytest.fixture(scope="module")
def balls(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray, dict[str, Any]]]:
    out = {}
    for case in BALL_CASES:
        d = tmp_path_factory.mktemp("ball")
        out[case] = export_and_run(write_document(d / "ball.toml", ball_doc(case)), d)
    return out


@pytest.mark.parametrize("case", list(BALL_CASES))
def test_bouncing_ball_in_fmpy_equals_the_run_with_its_bounces(case: str, balls: Any) -> None:
    fmu, ref, summary = balls[case]
    bounces = [e for e in summary["events"] if e["kind"] == "state"]
    assert len(bounces) >= 8, summary["events"]                  # (it bounces, then lies on the floor)
    assert np.count_nonzero(np.diff(ref["ball.v"]) > 0) >= 8     # (its speed turned at each)
    assert_same_columns(in_fmpy(fmu, BALL_STOP, BALL_STEP), ref)


def test_the_ball_cases_differ(balls: Any) -> None:
    h = [balls[c][1]["ball.h"] for c in BALL_CASES]
    assert all(not np.array_equal(a, b) for j, a in enumerate(h) for b in h[j + 1:])


def test_a_model_exchange_instance_at_its_own_rate_equals_the_run(tmp_path: Path) -> None:
    """The ball stepping every 4 base steps beside a Feedthrough at the base step (the multi-rate passes)."""
    doc = ball_doc("rk4", "jacobi")
    doc["instances"]["ball"]["step"] = 4 * BALL_STEP
    doc["instances"]["ft"] = {"fmu": str(REF / "fmi2" / "Feedthrough.fmu")}
    doc["connections"] = [{"from": "ball.h", "to": "ft.Float64_continuous_input"}]
    doc["record"]["variables"].append("ft.Float64_continuous_output")
    fmu, ref, _ = export_and_run(write_document(tmp_path / "rated.toml", doc), tmp_path)
    assert_same_columns(in_fmpy(fmu, BALL_STOP, BALL_STEP), ref)
    assert_same_columns(in_fmpy(fmu, BALL_STOP, 4 * BALL_STEP), ref[::4])


def fmusim_columns(fmu: Path, stop: float, step: float, folder: Path) -> tuple[list[str], np.ndarray]:
    rows = fmusim_csv(fmu, stop, step, folder)
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


@pytest.mark.parametrize("which", ["ball rk4", "ball cvode", "c plant rk4 foam by region",
                                   "c plant cvode foam by region"])
def test_in_fmusim_equals_the_run(which: str, balls: Any, g1: Any, tmp_path: Path) -> None:
    """fmusim (a C host that links SUNDIALS 6: the container's CVODE, FMPy's SUNDIALS 7, keeps to its own),
    to the 16 digits it writes."""
    ball = which.startswith("ball")
    fmu, ref, _ = balls[which[5:]] if ball else g1[which[8:]]
    stop, step = (BALL_STOP, BALL_STEP) if ball else (G1_STOP, G1_STEP)
    names, got = fmusim_columns(fmu, stop, step, tmp_path)
    assert sorted(names) == sorted(ref.dtype.names) and len(got) == len(ref)
    for j, name in enumerate(names):
        assert [float(x) for x in got[:, j]] == [float(f"{x:.16g}") for x in ref[name].astype(float)], name


# ------------------------------------------------------------------ an FMU that ends the simulation
@pytest.fixture(scope="module")
def stair(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray, dict[str, Any], Path]:
    """The Reference FMUs' Stair as Model Exchange (a time event each second; at the tenth, t = 9 s, it ends
    the simulation), run to 12 s: its container (FMI 2.0), its run, and its container with --fmi 3."""
    d = tmp_path_factory.mktemp("stair")
    doc = {"experiment": {"start": 0.0, "stop": 12.0, "step": 0.1},
           "instances": {"stair": {"fmu": str(REF / "fmi2" / "Stair.fmu"), "interface": "model-exchange",
                                   "solver": "euler"}},
           "record": {"variables": ["stair.counter"]}}
    sc = write_document(d / "stair.toml", doc)
    assert main(["export-fmu", str(sc), "--out", str(d / "S3.fmu"), "--fmi", "3"]) == 0
    return (*export_and_run(sc, d), d / "S3.fmu")


@pytest.mark.parametrize("fmi", [2, 3])
def test_an_fmu_ending_the_simulation_ends_the_host_run_where_the_run_ends(fmi: int, stair: Any) -> None:
    """The container says so (fmi2Discard with fmi2Terminated and the last row's time; FMI 3.0:
    terminateSimulation): the host's last row is the run's."""
    fmu, ref, summary, fmu3 = stair
    assert summary["status"] == "terminated" and ref["time"][-1] == 9.0 and ref["stair.counter"][-1] == 10
    assert_same_columns(in_fmpy(fmu if fmi == 2 else fmu3, 12.0, 0.1), ref)


def test_an_fmu_ending_the_simulation_in_fmusim(stair: Any, tmp_path: Path) -> None:
    fmu, ref, _, _ = stair
    names, got = fmusim_columns(fmu, 12.0, 0.1, tmp_path)
    assert names == ["time", "stair.counter"] and len(got) == len(ref)
    assert [int(x) for x in got[:, 1]] == list(ref["stair.counter"])


def test_cvode_ships_fmpys_sundials_with_its_notice(balls: Any) -> None:
    names = zipfile.ZipFile(balls["cvode"][0]).namelist()
    assert {f"resources/sundials/{lib}.so" for lib in container.SUNDIALS_LIBS} <= set(names)
    assert "resources/sundials/LICENSE-FMPy.txt" in names
    assert not any("sundials" in n for n in zipfile.ZipFile(balls["rk4"][0]).namelist())


# ------------------------------------------------------------------ what the container cannot hold
def _no_sundials(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(container, "sundials_folder", lambda: tmp_path / "nowhere")


REFUSALS: dict[str, tuple[Any, str, Any]] = {
    "event rows": (lambda doc: doc["record"].update(event_rows=True), "record.event_rows", None),
    "cvode without FMPy's SUNDIALS": (lambda doc: doc["instances"]["ball"].update(solver="cvode"),
                                      "instances.ball.solver", _no_sundials),
}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_what_the_container_cannot_hold_is_refused_in_one_line(case: str, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    doc = ball_doc("rk4")
    edit, field, patch = REFUSALS[case]
    edit(doc)
    if patch is not None:
        patch(monkeypatch, tmp_path / "elsewhere")
    sc = write_document(tmp_path / "system.toml", doc)
    assert main(["check", str(sc)]) == 0            # (the master runs it)
    capsys.readouterr()
    before = sorted(tmp_path.iterdir())
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "System.fmu")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: error: ") and "\n" not in err, err
    assert f"system.toml: {field}: " in err, err
    assert sorted(tmp_path.iterdir()) == before


def test_cvode_inside_is_built_for_linux64_only(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """(FMPy's SUNDIALS is shipped for linux64: asking for win64 is refused, saying so.)"""
    sc = write_document(tmp_path / "system.toml", ball_doc("cvode"))
    before = sorted(tmp_path.iterdir())
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "S.fmu"), "--platforms", "linux64,win64"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--platforms: win64 cannot be built: CVODE inside" in err and "\n" not in err, err
    assert sorted(tmp_path.iterdir()) == before
