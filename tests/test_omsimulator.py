"""The exported SSP in OMSimulator (a C++ master, prebuilt beside the checkout: tests/host_tools.py; these
tests skip, saying why, where it is absent or cannot start).

OMSimulator takes a system's type only from an ``org.openmodelica`` annotation on ``ssd:System`` (without one
it aborts), imports neither a String connector nor a String parameter (it logs an error for each), and its
fixed-step master is a Jacobi master: the exported G1 system (a Gauss-Seidel scenario) must run there with no
error logged and end where our Jacobi run of the same scenario ends.  It runs with an empty environment: our
FMI 2.0 FMUs find their Python themselves (docs/hosts.md).
"""
from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from host_tools import OMSIMULATOR, run_omsimulator as _oms, tool
from cosim_support import G1, g1_with_paths
from wmr_cosim import cosim
from wmr_cosim.cosim.plan.ssp import export_ssp, load_ssp

ROOT = Path(__file__).resolve().parents[1]
POSE = ("x_A", "y_A", "beta")
#: OMSimulator's oms_solver_enu_t value of its fixed-step co-simulation master (oms-ma).
OMS_SOLVER_WC_MA = 6


@pytest.fixture(scope="module")
def omsimulator() -> Path:
    return tool(OMSIMULATOR)


def _errors(p: subprocess.CompletedProcess) -> list[str]:
    return [ln for ln in (p.stdout + p.stderr).splitlines() if re.search(r"\berror\b", ln, re.IGNORECASE)]


def _last_row(csv: Path) -> dict[str, float]:
    """The last row of an OMSimulator CSV result, by column name (the file holds every step: read its
    head and its tail only)."""
    with csv.open("rb") as fh:
        head = [h.strip().strip('"') for h in fh.readline().decode().split(",")]
        fh.seek(0, 2)
        fh.seek(max(0, fh.tell() - 65536))
        last = fh.read().decode().strip().splitlines()[-1]
    return dict(zip(head, (float(x) for x in last.split(","))))


@pytest.fixture(scope="module")
def g1_plan(built_fmus):
    """The plan of scenarios/g1_learn.toml (Gauss-Seidel) with the session's FMUs."""
    return cosim.resolve(cosim.load(G1, lambda name: built_fmus.get(name)))


@pytest.mark.slow  # OMSimulator takes about 10 s over the 25,000 steps, our three runs 2 s each
def test_omsimulator_runs_the_exported_g1_system_as_our_jacobi_run(omsimulator, g1_plan, built_fmus, tmp_path):
    archive = export_ssp(g1_plan, tmp_path / "g1.ssp")
    t0 = time.perf_counter()
    p = _oms(omsimulator, [archive.name, "--stopTime=50", "--stepSize=0.002", "--resultFile=r.csv"], tmp_path)
    wall = time.perf_counter() - t0
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    assert _errors(p) == [], p.stdout[-3000:]
    assert re.search(r"^info:\s+0 errors$", p.stdout, re.MULTILINE), p.stdout[-3000:]  # its own count
    row = _last_row(tmp_path / "r.csv")
    assert row["time"] == 50.0
    oms = np.array([row[f"g1_learn.g1_learn.plant.{v}"] for v in POSE])

    def ours(algorithm: str, plan=None) -> np.ndarray:
        if plan is None:
            sc = cosim.load(G1, lambda name: built_fmus.get(name))
            sc.algorithm = algorithm
            plan = cosim.resolve(sc)
        res = cosim.run(plan, tmp_path / f"ours_{algorithm}", progress=False)
        assert res.status == "ok", res.message
        data = np.load(tmp_path / f"ours_{algorithm}" / "signals.npy")
        return np.array([data[f"plant.{v}"][-1] for v in POSE])

    jacobi = ours("jacobi")
    diff = np.abs(oms - jacobi)
    print(f"OMSimulator {oms.tolist()} in {wall:.1f} s; ours (Jacobi) {jacobi.tolist()}; |difference| {diff.tolist()}")
    assert diff.max() <= 1e-9
    # the scenario's own Gauss-Seidel run is not what OMSimulator ran (the note export-ssp prints), and our
    # run of the archive is that Gauss-Seidel run: the String parameter held back is not lost for us
    gs = ours("gauss-seidel")
    assert np.abs(oms - gs).max() > 1e-7
    arch = load_ssp(archive)
    try:
        assert arch.scenario.instances["controller"].parameters["task"] == "goal"
        assert np.array_equal(ours("from_ssp", cosim.resolve(arch.scenario)), gs)
    finally:
        arch.cleanup()


def test_omsimulator_takes_its_master_and_the_scenarios_step_from_the_archive(omsimulator, built_fmus, tmp_path):
    """Imported through OMSimulator's Lua API (its command line passes a step of its own): the system is a
    co-simulation system with the fixed-step master, at the scenario's step, and nothing is refused."""
    path = g1_with_paths(tmp_path, built_fmus, "[experiment]\nstop = 1.0\nstep = 0.004\n")
    archive = export_ssp(cosim.resolve(cosim.load(path)), tmp_path / "g1.ssp")
    (tmp_path / "probe.lua").write_text(
        f'model, status = oms_importFile("{archive.name}")\nprint("import", model, status)\n'
        'step, status = oms_getFixedStepSize(model .. "." .. model)\nprint("step", step, status)\n'
        'solver, status = oms_getSolver(model .. "." .. model)\nprint("solver", solver, status)\n'
        "oms_delete(model)\n")
    p = _oms(omsimulator, ["probe.lua"], tmp_path)
    assert p.returncode == 0, (p.stdout + p.stderr)[-3000:]
    assert _errors(p) == [], p.stdout[-3000:]
    got = {ln.split("\t")[0]: ln.split("\t")[1:] for ln in p.stdout.splitlines() if "\t" in ln}
    assert got["import"] == ["g1", "0"]
    assert float(got["step"][0]) == 0.004 and got["step"][1] == "0"
    assert got["solver"] == [str(OMS_SOLVER_WC_MA), "0"]
