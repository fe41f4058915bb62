"""The figures of benchmarks/mutation.py: what counts as killed, equivalent, unreachable or a survivor."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def harness(monkeypatch):
    spec = importlib.util.spec_from_file_location("mutation_harness", ROOT / "benchmarks" / "mutation.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
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
        "wmr_cosim.analysis.x_g__mutmut_1": "not checked",
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
