"""Falsification (wmr_cosim/falsify.py): differential evolution over a parameter space on the sweep
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
from wmr_cosim.falsify import falsify, load_falsification, population

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
    r = falsify(spec, tmp_path / "out", workers=2, progress=False)
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
    a = falsify(spec, tmp_path / "a", workers=2, progress=False)
    b = falsify(spec, tmp_path / "b", workers=2, progress=False)
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
])
def test_a_bad_file_is_one_line(tmp_path: Path, capsys, text: str, message: str) -> None:
    (tmp_path / "short.toml").write_text(SHORT)
    (tmp_path / "bad.toml").write_text(text)
    with pytest.raises(ScenarioError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_falsification(tmp_path / "bad.toml")
    assert main(["falsify", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message.split(":")[0] in err[0]
