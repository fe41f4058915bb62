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


# ------------------------------------------------------------------ a run that ends before its planned stop
def _dahlquist(tmp_path: Path, stopper: bool) -> Path:
    """Dahlquist (x' = -x, x(0) = 1, forward Euler at the step: x_k = 0.9^k) for 2 s of 0.1 s steps, with
    requirements of every kind of window; ``stopper``: first of them one that stops the run at 0.7 s."""
    from reference_fmus import REF

    sc = tmp_path / ("stopped.toml" if stopper else "full.toml")
    text = f'[experiment]\nstop = 2.0\nstep = 0.1\n[instances.d]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n'
    if stopper:
        text += '[[requirements]]\nname = "stopper"\nformula = "d.x > 0.5"\non_violation = "stop"\n'
    for name, formula in [("whole", "always d.x > 0"), ("early", "eventually[0,0.5] d.x < 0.85"),
                          ("bounded", "always[0,1] d.x > 0"), ("ahead", "always (d.x > 0 implies eventually[0,0.3] d.x < 0.9)"),
                          ("until", "d.x > 0 until[0,0.5] d.x < 0.7")]:
        text += f'[[requirements]]\nname = "{name}"\nformula = "{formula}"\n'
    sc.write_text(text)
    return sc


def test_a_run_stopped_early_leaves_its_unbounded_always_undecided(tmp_path: Path, capsys) -> None:
    """Stopped by a requirement at 0.7 s of 2 s: the unbounded always (over the whole run) and the one over
    [0, 1] s are undecided (no decided_at; the robustness the lowest so far), what was decided stays (the
    eventually at 0.2 s, the until when its window closed at 0.5 s); requirements.npy has every monitor's 8 points (it was not
    written at all when the stopping requirement came first); run says why, exit code 3."""
    code = main(["run", str(_dahlquist(tmp_path, True)), "--out", str(tmp_path / "o"), "--quiet"])
    out = capsys.readouterr().out
    assert code == 3
    v = {r["name"]: r for r in json.loads((tmp_path / "o" / "summary.json").read_text())["requirements"]}
    x = 0.9 ** np.arange(8)
    assert v["stopper"]["verdict"] == "violated" and v["stopper"]["decided_at"] == pytest.approx(0.7)
    for name in ("whole", "bounded", "ahead"):
        assert v[name]["verdict"] == "undecided" and v[name]["decided_at"] is None, name
    assert v["whole"]["robustness"] == pytest.approx(x[7], abs=1e-12) and v["whole"]["window"] == [0.0, None]
    assert v["early"]["verdict"] == "holds" and v["early"]["decided_at"] == pytest.approx(0.2)
    assert v["until"]["verdict"] == "holds" and v["until"]["decided_at"] == pytest.approx(0.5)
    rob = np.load(tmp_path / "o" / "requirements.npy")
    assert len(rob) == 8 and np.allclose(rob["whole"], x, rtol=0, atol=1e-12)
    assert "requirement 'whole': undecided: the run ended before its planned stop; robustness 0.478297 at t = 0.7 s so far" in out
    assert "requirement 'bounded': undecided: the run ended before the formula's horizon" in out


def test_a_run_to_its_planned_stop_decides_every_window_it_covers(tmp_path: Path, capsys) -> None:
    """The same requirements over the whole run: the unbounded always holds, known at the run's end (2 s);
    the one over [0, 1] s at 1 s; the one whose operand looks 0.3 s ahead holds over the points judged
    (its window ends at 1.7 s); exit code 0."""
    code = main(["run", str(_dahlquist(tmp_path, False)), "--out", str(tmp_path / "o"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    v = {r["name"]: r for r in json.loads((tmp_path / "o" / "summary.json").read_text())["requirements"]}
    assert all(r["verdict"] == "holds" for r in v.values()), v
    assert v["whole"]["decided_at"] == pytest.approx(2.0) and v["whole"]["window"] == [0.0, None]
    assert v["whole"]["robustness"] == pytest.approx(0.9 ** 20, abs=1e-12)
    assert v["bounded"]["decided_at"] == pytest.approx(1.0)
    assert v["ahead"]["decided_at"] == pytest.approx(2.0) and v["ahead"]["window"] == [0.0, pytest.approx(1.7)]


@pytest.mark.parametrize("entry,message", [
    ('name = "time"', "requirements[0].name: 'time' is reserved: requirements.npy's column of the time; another name"),
    ('name = "a\\nb"', "requirements[0].name: 'a\\nb': a name of printable characters"),
    ('name = "a\\tb"', "requirements[0].name: 'a\\tb': a name of printable characters"),
    ('name = ""', "requirements[0].name: missing: every requirement has a name"),
    ("name = 5", "requirements[0].name: must be a string, not 5"),
    ('name = "r"\nformula = "d.x > 1"\n[[requirements]]\nname = "r"', "requirements[1].name: 'r' names two requirements"),
])
def test_a_requirement_name_requirements_npy_cannot_hold_is_refused_at_check(tmp_path: Path, capsys, entry: str,
                                                                           message: str) -> None:
    """Refused before the run (the run used to end with a ValueError writing requirements.npy and no
    summary.json for a requirement named time)."""
    from reference_fmus import REF

    sc = tmp_path / "bad.toml"
    sc.write_text(f'[experiment]\nstop = 0.3\nstep = 0.1\n[instances.d]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n'
                  f'[[requirements]]\n{entry}\nformula = "d.x > 0"\n')
    for cmd in (["check", str(sc)], ["run", str(sc), "--out", str(tmp_path / "o"), "--quiet"]):
        assert main(cmd) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "o").exists()


def test_any_other_name_is_a_column_of_requirements_npy(tmp_path: Path, capsys) -> None:
    """Names beyond Latin-1, of 300 characters, with spaces, dots and commas, and "f0" (numpy's default
    field name): each its own column of requirements.npy, read back by numpy without a warning, and a
    verdict in summary.json."""
    import warnings

    from reference_fmus import REF

    names = ["Überschwingung ≤ 5 %", "x" * 300, "a.b, c", "f0", "时间"]
    sc = tmp_path / "names.toml"
    sc.write_text(f'[experiment]\nstop = 0.3\nstep = 0.1\n[instances.d]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n'
                  + "".join(f'[[requirements]]\nname = "{n}"\nformula = "d.x > {i / 10}"\n' for i, n in enumerate(names)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["run", str(sc), "--out", str(tmp_path / "o"), "--quiet"]) == 0, capsys.readouterr().err
        rob = np.load(tmp_path / "o" / "requirements.npy")
    assert rob.dtype.names == ("time", *names)
    for i, n in enumerate(names):
        assert np.allclose(rob[n], 0.9 ** np.arange(4) - i / 10, rtol=0, atol=1e-12), n
    summary = json.loads((tmp_path / "o" / "summary.json").read_text(encoding="utf-8"))
    assert [r["name"] for r in summary["requirements"]] == names


def test_plot_shades_what_decides_the_verdict(tmp_path: Path) -> None:
    """Dahlquist (x_k = 0.9^k) for 2 s: a holding eventually (x < 0.7 from 0.4 s) has no red, green over
    the values that satisfy it inside its window [0, 1] s; a violated eventually (x < 0.5 within [0, 0.5] s)
    red over its window only; a violated always (x > 0.5) red from its first violation (0.7 s) on.  Read
    from the figure's filled areas: their colour and the times they span."""
    from matplotlib.colors import to_rgba

    from reference_fmus import REF
    from wmr_cosim.runs.plot import plot_results

    sc = tmp_path / "s.toml"
    sc.write_text(f'[experiment]\nstop = 2.0\nstep = 0.1\n[instances.d]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n'
                  + "".join(f'[[requirements]]\nname = "{n}"\nformula = "{f}"\n' for n, f in [
                      ("reaches", "eventually[0,1] d.x < 0.7"), ("late", "eventually[0,0.5] d.x < 0.5"),
                      ("above", "d.x > 0.5")]))
    assert main(["run", str(sc), "--out", str(tmp_path / "o"), "--quiet"]) == 3
    plotted = plot_results(tmp_path / "o", requirements=["reaches", "late", "above"], out=tmp_path / "p.png")
    red, green = to_rgba("C3", 0.3), to_rgba("C2", 0.3)

    def shaded(ax, colour) -> list[tuple[float, float]]:
        """The time spans of the filled areas of ``colour`` (empty ones left out)."""
        out = []
        for c in ax.collections:
            fc = c.get_facecolor()
            for p in c.get_paths():
                if len(fc) and np.allclose(fc[0], colour) and len(p.vertices):
                    out.append((float(p.vertices[:, 0].min()), float(p.vertices[:, 0].max())))
        return out
    reaches, late, above = plotted.figure.axes[-3:]
    assert shaded(reaches, red) == []
    assert shaded(reaches, green) == [(pytest.approx(0.4), pytest.approx(1.0))]
    assert shaded(late, red) == [(pytest.approx(0.0), pytest.approx(0.5))] and shaded(late, green) == []
    assert shaded(above, red) == [(pytest.approx(0.7), pytest.approx(2.0))]


def test_long_formulas_run_and_too_deep_ones_are_one_line(tmp_path: Path, capsys) -> None:
    """495 ors and 1,990 +s (within the 4,000 characters) check and run to the verdict of their shallow
    equivalent (a RecursionError before); 61 levels of parentheses: one line, exit 2, before the run."""
    from reference_fmus import REF

    head = f'[experiment]\nstop = 0.5\nstep = 0.1\n[instances.d]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n'
    formulas = {"ors": "or ".join(f"d.x>{k % 10}" for k in range(496)), "sum": "d.x" + "+0" * 1990 + ">0",
                "short": "d.x > 0"}
    sc = tmp_path / "long.toml"
    sc.write_text(head + "".join(f'[[requirements]]\nname = "{n}"\nformula = "{f}"\n' for n, f in formulas.items()))
    assert main(["run", str(sc), "--out", str(tmp_path / "o"), "--quiet"]) == 0, capsys.readouterr().err
    v = {r["name"]: r for r in json.loads((tmp_path / "o" / "summary.json").read_text())["requirements"]}
    for name in ("ors", "sum"):
        assert {k: v[name][k] for k in ("verdict", "robustness", "at", "decided_at")} == \
               {k: v["short"][k] for k in ("verdict", "robustness", "at", "decided_at")}
    assert v["short"]["verdict"] == "holds" and v["short"]["robustness"] == pytest.approx(0.9 ** 5, abs=1e-12)
    deep = tmp_path / "deep.toml"
    deep.write_text(head + '[[requirements]]\nname = "r"\nformula = "' + "(" * 61 + "d.x > 0" + ")" * 61 + '"\n')
    capsys.readouterr()
    assert main(["run", str(deep), "--out", str(tmp_path / "p"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "requirements[0].formula: requirement 'r': at character 61: nested too deeply (at most 60" in err[0]
    assert not (tmp_path / "p").exists()
