"""Requirements checked while the loop runs: G1 on foam (scenarios/g1_requirements.toml) with a requirement
it violates and two it satisfies, against a brute-force evaluation over the recorded signals.npy (the same
grid); a requirement that stops the run; the command line's output, exit codes and refusals."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from wmr_cosim import cosim
from wmr_cosim.api import Simulation
from wmr_cosim.cli import main
from wmr_cosim.runner import resolve_model

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "g1_requirements.toml"
H = 0.002


@pytest.fixture(scope="module")
def g1_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("g1_requirements")
    res = cosim.run(cosim.resolve(cosim.load(str(SCENARIO), resolve_model)), out, progress=False)
    assert res.status == "ok", res.message
    return out


def brute(sig: np.ndarray) -> dict[str, tuple[np.ndarray, int, int]]:
    """Each requirement's robustness over time from the recording with numpy, written from its formula
    by hand; and the window of steps the verdict is judged over."""
    u1, u2 = sig["controller.u1"], sig["controller.u2"]
    x, y = sig["plant.x_A"], sig["plant.y_A"]
    e1, e2 = sig["controller.e1"], sig["controller.e2"]
    n = len(sig)
    return {"torque": (np.minimum(8 - np.abs(u1), 8 - np.abs(u2)), 0, n - 1),
            "goal": (0.05 - np.sqrt((x - 2) * (x - 2) + (y - 5) * (y - 5)), 0, 20000),
            "tracking": (np.minimum(0.05 - np.abs(e1), 0.05 - np.abs(e2)), 5000, 15000)}


def test_verdicts_first_violation_and_robustness_equal_a_brute_force_evaluation(g1_run: Path) -> None:
    """On the recorded grid: the torques stay under 8 N.m (holds), the robot is within 5 cm of G1 by
    40 s (holds, its best point), the tracking errors leave 0.05 rad between 10 and 30 s (violated at
    the first such point; its lowest robustness and when), each value to 1e-12, and the robustness over
    time in requirements.npy equal to the brute force's at every point."""
    sig = np.load(g1_run / "signals.npy")
    summary = {r["name"]: r for r in json.loads((g1_run / "summary.json").read_text())["requirements"]}
    rob = np.load(g1_run / "requirements.npy")
    assert np.array_equal(rob["time"], sig["time"])
    for name, (signal, lo, hi) in brute(sig).items():
        got = summary[name]
        window = signal[lo:hi + 1]
        assert np.allclose(rob[name][lo:hi + 1], window, rtol=0, atol=1e-12), name
        if name == "goal":   # eventually: the best point
            k = lo + int(np.argmax(window))
            assert got["verdict"] == "holds" and got["first_violation"] is None
            assert got["decided_at"] == pytest.approx(sig["time"][lo + int(np.argmax(window >= 0))], abs=1e-12)
        else:                # always: the worst point, and the first below zero
            k = lo + int(np.argmin(window))
            bad = np.flatnonzero(window < 0)
            if len(bad):
                assert got["verdict"] == "violated"
                assert got["first_violation"] == pytest.approx(sig["time"][lo + bad[0]], abs=1e-12)
            else:
                assert got["verdict"] == "holds" and got["first_violation"] is None
        assert got["robustness"] == pytest.approx(signal[k], abs=1e-12) and got["at"] == pytest.approx(sig["time"][k])
    assert [summary[n]["verdict"] for n in ("torque", "goal", "tracking")] == ["holds", "holds", "violated"]
    assert summary["torque"]["unit"] == "N.m" and summary["tracking"]["unit"] == "rad"
    assert [summary[n]["window"] for n in ("torque", "goal", "tracking")] == [[0.0, None], [0.0, 40.0], [10.0, 30.0]]
    assert summary["goal"]["variables"] == ["plant.x_A", "plant.y_A"]


def test_a_requirement_that_stops_the_run_ends_it_at_its_violation(tmp_path: Path, g1_run: Path, capsys) -> None:
    """on_violation = "stop": status violated, the run ended at the point the violation was known (10 s),
    the recording up to it kept and equal to the full run's; exit code 3, the reason in run's line."""
    sc = tmp_path / "stop.toml"
    sc.write_text(f'base = "{SCENARIO}"\nreplace = ["requirements"]\n'   # (this one requirement)
                  '[[requirements]]\nname = "tracking"\non_violation = "stop"\n'
                  'formula = "always[10,30] (abs(controller.e1) < 0.05 rad and abs(controller.e2) < 0.05 rad)"\n')
    code = main(["run", str(sc), "--out", str(tmp_path / "out"), "--quiet"])
    out = capsys.readouterr().out
    assert code == 3
    assert f"{sc}: requirement 'tracking' violated at t = 10 s (known at t = 10 s, robustness -0.641" in out
    assert "5000 steps to t = 10 s" in out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "violated" and summary["t_end"] == pytest.approx(10.0)
    short, full = np.load(tmp_path / "out" / "signals.npy"), np.load(g1_run / "signals.npy")
    assert short["time"][-1] == pytest.approx(10.0) and np.array_equal(short, full[:len(short)])
    signal = brute(full)["tracking"][0]
    (verdict,) = summary["requirements"]
    assert verdict["verdict"] == "violated" and verdict["robustness"] == pytest.approx(signal[5000], abs=1e-12)


def test_run_prints_the_verdicts(g1_run: Path) -> None:
    """The lines ``run`` ends with (the exit code of a violated one: the stop test above, and
    test_results_status), from this run's summary.json."""
    from wmr_cosim.cli import requirement_lines

    out = requirement_lines(json.loads((g1_run / "summary.json").read_text())["requirements"])
    assert out[0].startswith("requirement 'torque': holds; robustness ") and out[0].endswith(" N.m at t = 5.592 s")
    assert out[1].startswith("requirement 'goal': holds; robustness 0.0174")
    assert out[2].startswith("requirement 'tracking': VIOLATED at t = 10 s (known at t = 10 s); robustness -0.66")


def test_check_lists_the_requirements(capsys) -> None:
    assert main(["check", str(SCENARIO)]) == 0
    out = capsys.readouterr().out
    assert ("  requirement 'goal': eventually[0,40] sqrt((plant.x_A - 2 m) * (plant.x_A - 2 m) + (plant.y_A - 5 m) * "
            "(plant.y_A - 5 m)) < 5 cm") in out


@pytest.mark.parametrize("formula,message", [
    ("abs(controller.u1) <= 8 N.m and", "requirements[0].formula: requirement 'r': at character 32: expected"),
    ("plant.nowhere > 0", "requirements[0].formula: requirement 'r': at character 1: plant (WmrPlant.fmu) has no "
                          "variable 'nowhere'"),
    ("controller.u1 < 3 m", "requirements[0].formula: requirement 'r': at character 15: m does not convert to N.m"),
    ("eventually controller.u1 > 0", "requirements[0].formula: requirement 'r': at character 1: eventually without a bound"),
    ("1 < robot.x", "requirements[0].formula: requirement 'r': at character 5: robot.x: unknown instance 'robot'"),
])
def test_a_bad_requirement_is_one_line_and_exit_2(tmp_path: Path, capsys, formula: str, message: str) -> None:
    sc = tmp_path / "bad.toml"
    sc.write_text(f'base = "{SCENARIO}"\nreplace = ["requirements"]\n'   # (this one requirement)
                  f'[[requirements]]\nname = "r"\nformula = "{formula}"\n')
    assert main(["check", str(sc)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_a_bound_beyond_the_stop_time_is_a_note_and_the_verdict_undecided(tmp_path: Path, capsys) -> None:
    """Through the Python API: a 1 s run of G1 whose requirement looks 2 s ahead."""
    sim = Simulation.load(SCENARIO).experiment(stop=1.0)
    sim.document.pop("requirements")
    sim.require("late", "eventually[0,2] plant.y_A > 1 m")
    res = sim.run()
    v = res.requirements["late"]
    assert v["verdict"] == "undecided" and v["decided_at"] is None and v["first_violation"] is None
    assert any("reaches beyond the stop time 1 s" in n for n in sim.check().notes)
    assert math.isfinite(v["robustness"])


def test_plot_draws_a_requirements_robustness_below_the_signals_it_names(g1_run: Path, tmp_path: Path, capsys) -> None:
    assert main(["plot", str(g1_run), "--requirement", "tracking", "--out", str(tmp_path / "r.png")]) == 0
    out = capsys.readouterr().out
    assert "controller.e1, controller.e2, robustness of tracking drawn in" in out
    assert (tmp_path / "r.png").stat().st_size > 10_000
    assert main(["plot", str(g1_run), "--requirement", "trackin", "--out", str(tmp_path / "s.png")]) == 2
    assert "no requirement 'trackin' (did you mean 'tracking'?)" in capsys.readouterr().err
    assert not (tmp_path / "s.png").exists()


def test_the_paper_scenarios_state_their_signal_claims_as_requirements_of_the_learning_run() -> None:
    """scenarios/paper: the goal (every go-to-goal task) and G1's static error, monitored in the learning
    run only (``runs``); the formulas the same in protocol.toml and g1.toml, the static bound the paper's
    smaller figure; LINE declares none."""
    from wmr_cosim.components import paper

    paper_dir = SCENARIO.parent / "paper"
    plans = cosim.check_protocol(str(paper_dir / "g1.toml"), resolve_model)
    assert [r.name for r in plans["learn"].requirements] == ["goal", "static"]
    assert plans["frozen"].requirements == [] and plans["foam"].requirements == []
    proto = {r.name: r for r in cosim.load(str(paper_dir / "protocol.toml"), lambda n: Path(n)).requirements}
    g1 = {r.name: r for r in cosim.load(str(paper_dir / "g1.toml"), lambda n: Path(n)).requirements}
    assert proto["goal"].formula == g1["goal"].formula and "controller.eps_G" in g1["goal"].formula
    static = min(paper.results()["reported_figures"]["G1_static_error_rad"])
    assert f">= {static:g} rad" in g1["static"].formula
    assert cosim.load(str(paper_dir / "line.toml"), lambda n: Path(n)).requirements == []


def test_a_requirements_runs_must_be_the_protocols(tmp_path: Path, capsys) -> None:
    sc = tmp_path / "bad.toml"
    sc.write_text(f'base = "{SCENARIO}"\nreplace = ["requirements"]\n'   # (this one requirement)
                  '[[requirements]]\nname = "r"\nruns = ["foam"]\nformula = "t > 0"\n')
    assert main(["check", str(sc)]) == 2
    assert "requirements[0].runs: 'foam' is not a run of this file (run)" in capsys.readouterr().err
