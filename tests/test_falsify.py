"""Falsification (wmr_cosim/studies/falsification.py): differential evolution over a parameter space on the sweep
machinery, minimising a requirement's robustness: G1 on foam shortened to 11 s (its tracking on the foam), and
Dahlquist for what does not need the robot."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd
import pytest

from wmr_cosim.cli import main
from wmr_cosim.cosim import ScenarioError
from wmr_cosim.studies.falsification import falsify, load_falsification, population
from wmr_cosim.paper import robot_system

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "g1_requirements.toml"
SHORT = f'''base = "{SCENARIO}"
replace = ["requirements"]
[experiment]
stop = 11.0
[[requirements]]
name = "tracking"
formula = "always[9,11] (abs(controller.e1) < 0.5 rad and abs(controller.e2) < 0.5 rad)"
'''
SPACE = '''[space]
"plant.foam_da1+plant.foam_da2" = { low = 0.2, high = 1.2 }
"plant.foam_t_on" = { low = 8.0, high = 10.0 }
'''


def files(folder: Path, budget: int, seed: int = 3) -> Path:
    (folder / "short.toml").write_text(SHORT)
    spec = folder / "f.toml"
    spec.write_text(f'base = "short.toml"\nrequirement = "tracking"\nseed = {seed}\nbudget = {budget}\n{SPACE}')
    return spec


def test_the_population_spends_the_budget() -> None:
    assert population(40, 2) == (10, 3)       # 10 + 3 generations of 10: 40 runs
    assert population(10, 2) == (5, 1)
    assert population(41, 3) == (10, 3)


@pytest.mark.slow
def test_a_search_of_40_runs_finds_a_worse_case_than_the_nominal_run_and_its_rerun_agrees(tmp_path: Path) -> None:
    """Budget 40 on two axes (the friction change and its onset): the worst case's robustness is below the
    nominal run's, the re-run of the worst case gives the same value bit for bit, every run is in the
    table."""
    spec = files(tmp_path, 40)
    r = falsify(spec, tmp_path / "out", workers=2, progress=False, system=robot_system())
    assert r["optimiser"]["runs"] == 40 and r["failed"] == 0
    assert r["worst"]["robustness"] < r["nominal"]["robustness"]
    assert r["rerun"]["same"] and r["rerun"]["robustness"] == r["worst"]["robustness"]
    table = pd.read_csv(tmp_path / "out" / "falsify.csv")
    assert len(table) == 40 and table["robustness"].min() == r["worst"]["robustness"]


def test_the_search_is_deterministic_for_its_seed(tmp_path: Path) -> None:
    """The same file run twice into two folders (Dahlquist, x' = -k x from x(0), the requirement "x stays
    above 0.3"; k and the start of x searched, budget 10): the same points, robustness and worst case; the
    worst is the lowest of the table, below the nominal run's, and its re-run gives the same value."""
    from reference_fmus import REF

    (tmp_path / "dq.toml").write_text(
        f'[experiment]\nstop = 1.0\nstep = 0.01\n[instances.dq]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n'
        '[record]\nvariables = ["dq.x"]\n[[requirements]]\nname = "above"\nformula = "dq.x > 0.3"\n')
    spec = tmp_path / "f.toml"
    spec.write_text('base = "dq.toml"\nrequirement = "above"\nseed = 5\nbudget = 10\n[space]\n'
                    '"dq.k" = { low = 0.5, high = 3.0 }\n"dq.x" = { low = 0.5, high = 2.0 }\n')
    a = falsify(spec, tmp_path / "a", workers=2, progress=False, system=robot_system())
    b = falsify(spec, tmp_path / "b", workers=2, progress=False, system=robot_system())
    ta, tb = (pd.read_csv(tmp_path / d / "falsify.csv") for d in ("a", "b"))
    assert len(ta) == 10 and ta.equals(tb)
    assert a["worst"] == {**b["worst"], "command": a["worst"]["command"]} and a["rerun"]["same"]
    assert a["worst"]["robustness"] == ta["robustness"].min() < a["nominal"]["robustness"]
    assert json.loads((tmp_path / "a" / "falsify.json").read_text())["worst"] == a["worst"]
    assert math.isfinite(a["worst"]["robustness"])


@pytest.mark.parametrize("text,message", [
    ('requirement = "tracking"\n' + SPACE, "base: missing"),
    ('base = "short.toml"\nrequirement = "nope"\n' + SPACE, "requirement: 'nope': the base declares 'tracking'"),
    ('base = "short.toml"\nrequirement = "tracking"\n[space]\n"plant.foam_t_on" = { low = 2.0, high = 1.0 }\n',
     "space.plant.foam_t_on.high: must be above low"),
    ('base = "short.toml"\nrequirement = "tracking"\nbudget = 4\n' + SPACE, "budget: 4: at least 10"),
    ('base = "short.toml"\nrequirement = "tracking"\nrun = "foam"\n' + SPACE, "run: 'foam': one of the base's runs (run)"),
    pytest.param("x = " + "[" * 5000 + "]" * 5000 + "\n", "not valid TOML (nested too deeply)", id="nested too deeply"),
    pytest.param('base = "' + "b" * 5000 + '.toml"\nrequirement = "tracking"\n' + SPACE, "base: 'bbbb",
                 id="a base too long for the system"),
])
def test_a_bad_file_is_one_line(tmp_path: Path, capsys, text: str, message: str) -> None:
    (tmp_path / "short.toml").write_text(SHORT)
    (tmp_path / "bad.toml").write_text(text)
    with pytest.raises(ScenarioError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_falsification(tmp_path / "bad.toml")
    assert main(["falsify", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message.split(":")[0] in err[0]


# ---------------------------------------------------------------------- refused before any run
def _reference_base(folder: Path) -> None:
    """Three Reference FMUs side by side: Dahlquist (k: Real, no range), BouncingBall (e: Real in [0.5, 1]),
    Feedthrough (Int32_input: Integer); the requirement "dq.x stays above 0.3"."""
    from reference_fmus import REF

    (folder / "three.toml").write_text(
        "[experiment]\nstop = 1.0\nstep = 0.01\n"
        + "".join(f'[instances.{i}]\nfmu = "{REF / "fmi2" / f"{m}.fmu"}"\n'
                  for i, m in (("dq", "Dahlquist"), ("bb", "BouncingBall"), ("ft", "Feedthrough")))
        + '[record]\nvariables = ["dq.x"]\n[[requirements]]\nname = "above"\nformula = "dq.x > 0.3"\n')


def _refused(capsys, args: list, out: Path, *words: str) -> None:
    """`wmr-cosim falsify ARGS`: exit code 2, one line holding ``words``, no results folder (nothing ran)."""
    code = main(["falsify", *map(str, args), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert all(w in err[0] for w in words), err[0]
    assert not out.exists()


@pytest.mark.parametrize("space, words", [
    ('"dq.kk" = { low = 0.5, high = 3.0 }', ["f.toml: space.dq.kk:", "no variable 'kk' (did you mean 'k'?)"]),
    ('"dqq.k" = { low = 0.5, high = 3.0 }', ["f.toml: space.dqq.k:", "no instance 'dqq' (did you mean 'dq'?)"]),
    ('"ft.Int32_input" = { low = 0, high = 3 }', ["f.toml: space.ft.Int32_input:", "is Integer: a search varies Real"]),
    ('"bb.e" = { low = 0.2, high = 0.9 }', ["f.toml: space.bb.e:", "value 0.2 is below the minimum 0.5"]),
    ('"dq.k+bb.e" = { low = 0.6, high = 1.5 }', ["f.toml: space.dq.k+bb.e:", "value 1.5 is above the maximum 1.0"]),
])
def test_a_space_the_base_cannot_take_is_refused_before_any_run(tmp_path: Path, capsys, space: str,
                                                                 words: list[str]) -> None:
    """An unknown parameter, an Integer one (differential evolution proposes Reals) or a box beyond the
    declared range ran the whole budget before refusing, naming the base: now one line naming the
    falsification file and the space's field, before any run."""
    _reference_base(tmp_path)
    f = tmp_path / "f.toml"
    f.write_text(f'base = "three.toml"\nrequirement = "above"\nbudget = 10\n[space]\n{space}\n')
    _refused(capsys, [f, "--workers", "1"], tmp_path / "out", *words)


@pytest.mark.parametrize("text, args, words", [
    ("seed = 4294967296\n", [], ["f.toml: seed: 4294967296: must be a whole number from 0 to 4294967295"]),
    ("seed = -1\n", [], ["f.toml: seed: -1: must be a whole number"]),
    ("budget = 10.5\n", [], ["f.toml: budget: 10.5: must be a whole number"]),
    ("", ["--seed", "4294967296"], ["--seed 4294967296: must be a whole number from 0 to 4294967295"]),
    ("", ["--seed", "-1"], ["--seed -1: must be a whole number"]),
    ("", ["--budget", "9"], ["--budget 9: at least 10 co-simulations"]),
    ("", ["--budget", "-3"], ["--budget -3: must be a whole number"]),
    ("", ["--workers", "0"], ["--workers 0: must be a whole number >= 1"]),
])
def test_seeds_budgets_and_workers_out_of_range_are_refused_up_front(tmp_path: Path, capsys, text: str,
                                                                     args: list[str], words: list[str]) -> None:
    """A seed of 2**32 crashed the optimiser (numpy's RandomState takes 32 bits) after the nominal run: the
    seed, in the file or on the command line, is refused before anything runs, as are a budget and a
    number of workers out of range."""
    _reference_base(tmp_path)
    f = tmp_path / "f.toml"
    f.write_text(f'base = "three.toml"\nrequirement = "above"\n{text}[space]\n"dq.k" = {{ low = 0.5, high = 3.0 }}\n')
    _refused(capsys, [f, *args], tmp_path / "out", *words)


def test_budget_and_seed_on_the_command_line_win_over_the_files(tmp_path: Path, monkeypatch) -> None:
    """`falsify --budget 12 --seed 7`: the search runs with those (the file says 10 and 3)."""
    from wmr_cosim.studies import falsification as falsify_module
    from wmr_cosim.cosim import CosimError

    _reference_base(tmp_path)
    f = tmp_path / "f.toml"
    f.write_text('base = "three.toml"\nrequirement = "above"\nseed = 3\nbudget = 10\n[space]\n'
                 '"dq.k" = { low = 0.5, high = 3.0 }\n')
    seen = []

    def search(spec, *a, **kw):
        seen.append(spec)
        raise CosimError("(stopped by the test)")

    monkeypatch.setattr(falsify_module, "_search", search)
    assert main(["falsify", str(f), "--budget", "12", "--seed", "7", "--out", str(tmp_path / "out")]) == 2
    assert (seen[0].budget, seen[0].seed) == (12, 7)
    assert main(["falsify", str(f), "--out", str(tmp_path / "out")]) == 2
    assert (seen[1].budget, seen[1].seed) == (10, 3)
    assert load_falsification(f, seed=0, budget=40).seed == 0


def test_a_copied_falsification_file_finds_its_base_among_the_shipped_scenarios(tmp_path: Path, capsys) -> None:
    """As `run` finds a copied scenario's base: the shipped falsify-foam.toml copied elsewhere searches the
    shipped g1_requirements.toml; a base found nowhere is one line that says it is the base."""
    from wmr_cosim.scenario_files import folder

    copy = tmp_path / "mine.toml"
    copy.write_text((folder() / "falsify-foam.toml").read_text())
    assert Path(load_falsification(copy).base) == (folder() / "g1_requirements.toml").resolve()
    # a scenario of one's own over a shipped one: its base found as `run` finds it
    (tmp_path / "short.toml").write_text('base = "g1_requirements.toml"\n[experiment]\nstop = 11.0\n')
    copy.write_text('base = "short.toml"\nrequirement = "tracking"\nbudget = 10\n' + SPACE)
    assert load_falsification(copy).requirement == "tracking"
    copy.write_text('base = "nope.toml"\nrequirement = "tracking"\n' + SPACE)
    _refused(capsys, [copy], tmp_path / "out", "mine.toml: base: 'nope.toml': the base scenario is not found",
             "nor a shipped scenario")
