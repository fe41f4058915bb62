"""The robustness study and the study of when W stops adapting: the perturbations, the summary and the
decision rule on synthetic rows, and a reduced grid run end to end on Dask (12 s runs of G1)."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from wmr_cosim.paper import robustness as rb
from wmr_cosim.components import paper

DATA = Path(__file__).parent / "data"
A = paper.table1()["a"][4]


def test_mismatch_keeps_the_mean_and_splits_left_right():
    p = rb.mismatch_params(0.05)
    assert math.isclose((p["plant.a5"] - p["plant.a6"]) / A, 0.05, rel_tol=1e-12)
    assert math.isclose(0.5 * (p["plant.a5"] + p["plant.a6"]), A, rel_tol=1e-12)
    assert rb.mismatch_params(0.0) == {}          # the nominal point is the paper's run, bit for bit
    h = rb.heading_params(30.0)
    assert h["plant.beta0"] == h["controller.beta0"] == pytest.approx(math.pi / 6)
    assert rb.reading_params("P0", paper.table1()["P0"]) == {}
    assert rb.reading_params("T", 8.0) == {"controller.P0": 0.0, "controller.adapt_t_end": 8.0}


def _row(pid: int, diverged: bool = False, e: float = 0.3) -> dict:
    r = {"point": pid, "status": "diverged" if diverged else "ok"}
    for run in rb.RUNS:
        for i in (1, 2):
            r[f"{run}.rmse_e{i}"] = math.inf if diverged else e
            r[f"{run}.rmse_edot{i}"] = 0.1
            r[f"{run}.rmse_e_true{i}"] = 0.8 * e
        r[f"{run}.diverged"] = diverged and run == "foam"
    return r


def test_largest_converging_value_is_the_end_of_the_converging_prefix():
    grid = rb.StudyGrid(tasks=("G1",), mismatch=(0.0, 0.05, 0.1), axes=("mismatch",), freeze=False)
    layout = {"mismatch": [{"value": v, "points": {"G1": i}} for i, v in enumerate(grid.mismatch)]}
    # 0.1 diverges: the largest value with every run converging is 0.05
    s = rb.summarise({0: _row(0), 1: _row(1), 2: _row(2, diverged=True)}, layout, grid)["robustness"]
    assert s["max_mismatch_all_converge"] == 0.05
    assert s["mismatch"][2]["diverged_runs"] == ["G1.foam"]
    # a failure in the middle ends the prefix even if a larger value converges again
    s = rb.summarise({0: _row(0), 1: _row(1, diverged=True), 2: _row(2)}, layout, grid)["robustness"]
    assert s["max_mismatch_all_converge"] == 0.0
    s = rb.summarise({0: _row(0, diverged=True), 1: _row(1), 2: _row(2)}, layout, grid)["robustness"]
    assert s["max_mismatch_all_converge"] is None


def _reading(label, within, rms, div, mdiv, mwithin, kind="P0", value=1e-3):
    return {"kind": kind, "value": value, "label": label, "within_1_5": within, "rms_log_factor": rms,
            "diverged_runs": ["x"] * div, "mismatch_diverged_runs": ["x"] * mdiv, "mismatch_within_1_5": mwithin}


def test_default_changes_only_for_a_reading_better_on_all_three():
    p0 = paper.table1()["P0"]
    default = _reading("default", 26, 1.38, 0, 2, 20, value=p0)
    # better fidelity but worse robustness: no change
    assert not rb.decide([default, _reading("a", 28, 1.3, 0, 3, 20)])["change_default"]
    # better fidelity and robustness but more divergence: no change
    assert not rb.decide([default, _reading("b", 28, 1.3, 1, 0, 25)])["change_default"]
    # equal fidelity: no change
    assert not rb.decide([default, _reading("c", 26, 1.38, 0, 0, 25)])["change_default"]
    d = rb.decide([default, _reading("d", 27, 1.5, 0, 1, 18)])
    assert d["change_default"] and d["better_on_all_three"] == ["d"]


def test_reduced_study_runs_on_dask(built_fmus, tmp_path):
    """G1 cut to 12 s: nominal, 10 % mismatch, 30 deg heading, encoder noise, and one fixed freeze time;
    the points reach the FMUs (each perturbation changes the RMSE), and a second call resumes."""
    from wmr_cosim import runner

    mp = pytest.MonkeyPatch()
    mp.setattr(runner, "resolve_model", lambda name: built_fmus.get(name))
    try:
        manifest = tmp_path / "tasks.toml"
        manifest.write_text(f'[tasks]\nG1 = "{DATA / "short_protocol.toml"}"\n')
        grid = rb.StudyGrid(tasks=("G1",), mismatch=(0.0, 0.1), heading_deg=(0.0, 30.0), noise_counts=(0.0, 1.0),
                            bump_Nm=(0.0, 3.4), p0=(paper.table1()["P0"],), freeze_times=(8.0,),
                            freeze_mismatch=0.1, manifest=str(manifest))
        points, _ = rb.plan(grid)
        assert len(points) == 7          # the nominal and the 10 % points are shared by the axes and the readings
        s = rb.run_study(tmp_path / "study", grid, workers=2, progress=False)
        rob = s["robustness"]
        base = rob["mismatch"][0]["rmse_e_max"]["G1"]["learn"]
        for axis in ("mismatch", "heading", "noise"):
            assert rob[axis][0]["rmse_e_max"]["G1"]["learn"] == base
            assert rob[axis][1]["rmse_e_max"]["G1"]["learn"] != base, axis
            # the true error is smaller than the measured one (the filter's lag)
            assert rob[axis][1]["rmse_e_true_max"]["G1"]["learn"] < rob[axis][1]["rmse_e_max"]["G1"]["learn"]
        # the bump acts at the foam's edge only: learning run unchanged, the foam run's edge peak higher
        assert rob["bump"][1]["rmse_e_max"]["G1"]["learn"] == base
        assert rob["bump"][1]["edge_peak_u"]["G1"] > rob["bump"][0]["edge_peak_u"]["G1"] + 1.0
        fz = s["freeze_study"]
        assert [r["label"] for r in fz["readings"]] == ["P0 = 0.0005 (Table 1, the default)", "fixed freeze at T = 8 s"]
        assert len(list((tmp_path / "study" / "points").glob("*.json"))) == 7
        again = rb.run_study(tmp_path / "study", grid, workers=1, progress=False)   # all points saved: no run
        assert again["robustness"]["mismatch"] == rob["mismatch"]
    finally:
        mp.undo()


@pytest.mark.slow
def test_the_paper_command_runs_the_robustness_study(built_fmus, tmp_path, monkeypatch, capsys):
    """`wmr-cosim paper --robustness` end to end through the command line, as a user runs it (the study's
    grid names no tasks file: the job's is used), on G1 cut to 12 s and a reduced grid (4 points)."""
    import functools
    import json

    from wmr_cosim import cli, runner

    monkeypatch.setattr(runner, "resolve_model", lambda name: built_fmus.get(name))   # the job's workers fork
    monkeypatch.setattr(rb, "StudyGrid", functools.partial(
        rb.StudyGrid, mismatch=(0.0, 0.1), heading_deg=(0.0,), noise_counts=(0.0, 1.0), bump_Nm=(0.0, 3.4),
        p0=(paper.table1()["P0"],), freeze_times=(), freeze_mismatch=0.1))
    manifest = tmp_path / "tasks.toml"
    manifest.write_text(f'[tasks]\nG1 = "{DATA / "short_protocol.toml"}"\n')
    out = tmp_path / "job"
    code = cli.main(["paper", "--robustness", "--manifest", str(manifest), "--no-compare", "--out", str(out),
                     "--workers", "2", "--quiet"])
    assert code == 0, capsys.readouterr().err
    m = json.loads((out / "metrics.json").read_text())
    rob = m["robustness"]
    assert rob["tasks"] == ["G1"] and rob["n_points"] == 4
    assert [e["value"] for e in rob["mismatch"]] == [0.0, 0.1]
    assert rob["max_mismatch_all_converge"] == 0.1 and m["freeze_study"]["default"].startswith("P0 = 0.0005")
    assert isinstance(rob["bump"][1]["gamma_star"]["G1"], float)     # gamma* (53) of the point with the bump
    assert len(list((out / "robustness" / "points").glob("*.json"))) == 4
    md = (out / "report.md").read_text()
    assert "Robustness beyond the paper" in md and "figures/robustness.png" in md
