"""The figures of benchmarks/mutation.py: what counts as killed, equivalent, unreachable or a survivor."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def harness(monkeypatch, tmp_path):
    spec = importlib.util.spec_from_file_location("mutation_harness", ROOT / "benchmarks" / "mutation.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    monkeypatch.setattr(mod, "SAMPLE", tmp_path / "sample.json")
    diffs = {"wmr_cosim.cosim.a.x_f__mutmut_2": "x = g(1, )", "wmr_cosim.cosim.a.x_f__mutmut_3": "moved elsewhere"}
    monkeypatch.setattr(mod, "mutant_diff", lambda name: diffs[name])
    return mod


def test_summary_counts_each_kind(harness):
    status = {
        "wmr_cosim.components.p.x_a__mutmut_1": "killed",
        "wmr_cosim.components.p.x_a__mutmut_2": "timeout",
        "wmr_cosim.components.p.x_a__mutmut_3": "survived",
        "wmr_cosim.cosim.a.x_f__mutmut_1": "killed",
        "wmr_cosim.cosim.a.x_f__mutmut_2": "survived",      # equivalent, its line still matches
        "wmr_cosim.cosim.a.x_f__mutmut_3": "survived",      # equivalent entry gone stale
        "wmr_cosim.cosim.iso.x__serve__mutmut_1": "no tests",  # only a child process runs it
        "wmr_cosim.cosim.iso.x_other__mutmut_1": "no tests",   # no test: a survivor
        "wmr_cosim.paper.analysis.x_g__mutmut_1": "not checked",
    }
    equivalents = {"wmr_cosim.cosim.a.x_f__mutmut_2": {"line": "x = g(1, )", "reason": "r"},
                   "wmr_cosim.cosim.a.x_f__mutmut_3": {"line": "x = g(2, )", "reason": "r"},
                   "wmr_cosim.cosim.a.x_f__mutmut_9": {"line": "y", "reason": "r"}}
    s = harness.summarise(status, equivalents, 1.0, unreachable={"wmr_cosim.cosim.iso.x__serve": "child"})
    assert (s["mutants"], s["killed"], s["equivalent"], s["unreachable"], s["not_checked"]) == (6, 3, 1, 1, 1)
    assert s["kill_rate"] == 0.5
    assert s["per_area"]["components"] == {"mutants": 3, "killed": 2, "kill_rate": 0.6667}
    assert s["per_area"]["cosim"] == {"mutants": 3, "killed": 1, "kill_rate": 0.3333}
    assert s["stale_equivalents"] == ["wmr_cosim.cosim.a.x_f__mutmut_3", "wmr_cosim.cosim.a.x_f__mutmut_9"]
    assert s["survivors"] == ["wmr_cosim.components.p.x_a__mutmut_3", "wmr_cosim.cosim.a.x_f__mutmut_3",
                              "wmr_cosim.cosim.iso.x_other__mutmut_1"]


def test_the_equivalents_file_gives_a_reason_for_each_entry(harness):
    for name, entry in harness.load_equivalents().items():
        assert name.startswith("wmr_cosim.") and "__mutmut_" in name and entry["line"] and entry["reason"]
    for function, reason in harness.load_unreachable().items():
        assert function.startswith("wmr_cosim.") and "__mutmut_" not in function and reason


def test_a_sample_is_drawn_per_file_and_kept(harness):
    """ceil(fraction x n) of each file's unchecked mutants; the same fraction and seed give the kept sample
    back (an interrupted run goes on with it), another seed draws again."""
    status = {f"wmr_cosim.cosim.a.x_f__mutmut_{i}": "not checked" for i in range(10)}
    status.update({f"wmr_cosim.cosim.a.x_g__mutmut_{i}": "killed" for i in range(5)})
    status.update({f"wmr_cosim.components.b.x_h__mutmut_{i}": "not checked" for i in range(3)})
    drawn = harness.draw_sample(status, 0.25, seed=7)
    assert len([n for n in drawn if ".cosim.a." in n]) == 3 and len([n for n in drawn if ".b." in n]) == 1
    assert all(status[n] == "not checked" for n in drawn)
    saved = json.loads(harness.SAMPLE.read_text())
    assert saved["population"] == {"wmr_cosim.cosim.a": [f"wmr_cosim.cosim.a.x_f__mutmut_{i}" for i in range(10)],
                                   "wmr_cosim.components.b": [f"wmr_cosim.components.b.x_h__mutmut_{i}"
                                                              for i in range(3)]}
    assert harness.draw_sample({}, 0.25, seed=7) == drawn            # kept, whatever the status says now
    harness.SAMPLE.unlink()
    assert harness.draw_sample(status, 0.25, seed=7) == drawn        # the seed fixes the draw
    others = {tuple(harness.draw_sample(status, 0.25, seed=s)) for s in range(8, 16)}
    assert len(others) > 1


def test_the_estimate_weighs_each_file_sample_by_its_population(harness):
    """File a: a census of 10 (9 killed) and a sample of 10 from 100 unchecked mutants (8 killed, 1 survived,
    1 equivalent): 10 + 100 x 9/10 = 100 mutants, 9 + 90 x 8/9 = 89 killed; the lower bound with the 8 of 9
    at the low end of their Wilson interval, 0.5650: (9 + 90 x 0.5650) / 100."""
    status = {f"wmr_cosim.cosim.a.x_c__mutmut_{i}": "killed" for i in range(9)}
    status["wmr_cosim.cosim.a.x_c__mutmut_9"] = "survived"
    drawn = [f"wmr_cosim.cosim.a.x_s__mutmut_{i}" for i in range(10)]
    status.update({n: "killed" for n in drawn[:8]})
    status[drawn[8]] = "survived"
    status[drawn[9]] = "survived"
    status.update({f"wmr_cosim.cosim.a.x_s__mutmut_{i}": "not checked" for i in range(10, 100)})
    equivalents = {drawn[9]: {"line": "x = g(1, )", "reason": "r"}}
    harness.mutant_diff = lambda name: "x = g(1, )"
    population = [f"wmr_cosim.cosim.a.x_s__mutmut_{i}" for i in range(100)]
    sample = {"fraction": 0.1, "seed": 1, "sample": drawn, "population": {"wmr_cosim.cosim.a": population}}
    s = harness.summarise(status, equivalents, 1.0, unreachable={}, sample=sample)
    assert s["estimate"]["cosim"] == {"mutants": 100, "killed": 89, "kill_rate": 0.89, "low95": 0.5985}
    assert s["sample"] == {"fraction": 0.1, "seed": 1, "drawn": 10, "checked": 10, "population": 100}
    assert s["estimate"]["components"]["mutants"] == 0
    # measured alone (no sample): the 19 checked mutants that count
    assert (s["mutants"], s["killed"]) == (19, 17)
    # once the whole population is checked it is counted as it is, not estimated
    status.update({n: "killed" for n in population[10:]})
    s = harness.summarise(status, equivalents, 1.0, unreachable={}, sample=sample)
    assert s["estimate"]["cosim"] == {"mutants": 109, "killed": 107, "kill_rate": round(107 / 109, 4),
                                          "low95": round(107 / 109, 4)}


def test_the_wilson_bound_of_a_sample_without_survivors_is_below_one(harness):
    """20 of 20 killed: the 95 % lower bound is 1 / (1 + 1.96^2 / 20) = 0.839, not 1."""
    assert harness.wilson_low(20, 20) == pytest.approx(1 / (1 + 1.96 ** 2 / 20))
    assert harness.wilson_low(8, 9) == pytest.approx(0.5650, abs=1e-4)
