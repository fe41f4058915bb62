"""The report's pass/fail statements: each is generated from the number it sits beside, and any
disagreement between a statement and the metrics (value, verdict, wording, absence from the report) is
named in one line."""
from __future__ import annotations

import math

import pytest

from wmr_cosim.paper.claims import check_claims, claim_text, holds, make_claim, resolve

METRICS = {"tasks": {"G1": {"foam": {"edge_peak_u": 8.4, "cruise_u": [4.1, 3.9], "diverged": False}}},
           "runs": ["a", "b", "c"], "gamma_star": {"G1": 13.6, "G2": None, "G3": math.nan}}


def test_resolve_walks_keys_list_indices_and_lengths():
    assert resolve(METRICS, "tasks.G1.foam.edge_peak_u") == 8.4
    assert resolve(METRICS, "tasks.G1.foam.cruise_u.1") == 3.9
    assert resolve(METRICS, "runs.#len") == 3
    assert resolve(METRICS, "tasks.G1.foam.cruise_u.#len") == 2
    with pytest.raises(KeyError):
        resolve(METRICS, "tasks.G4")
    with pytest.raises(IndexError):
        resolve(METRICS, "runs.3")


@pytest.mark.parametrize("op, below, equal, above", [
    ("<=", True, True, False), ("<", True, False, False), (">=", False, True, True), (">", False, False, True),
    ("==", False, True, False)])
def test_holds_for_every_relation(op, below, equal, above):
    assert (holds(1.0, op, 2.0), holds(2.0, op, 2.0), holds(3.0, op, 2.0)) == (below, equal, above)
    assert holds(2, op, 2.0) is equal                       # integers (counts) compare too


@pytest.mark.parametrize("op", ["<=", "<", ">=", ">", "=="])
def test_a_missing_or_non_finite_value_never_holds(op):
    for value in (None, math.nan, math.inf, -math.inf):
        assert holds(value, op, 0.0) is False


def test_claim_text_states_the_relation_that_is_true():
    assert claim_text("gamma*", 13.6, "<=", 11.0, "gamma", 2) == "gamma* = 13.60 > 11.00 (gamma): no"
    assert claim_text("gamma*", 9.0, "<=", 11.0, "gamma", 2) == "gamma* = 9.00 <= 11.00 (gamma): yes"
    assert claim_text("x", 11.0, "<", 11.0, "b", 1) == "x = 11.0 >= 11.0 (b): no"
    assert claim_text("x", 1.0, ">=", 2.0, "b", 0) == "x = 1 < 2 (b): no"
    assert claim_text("x", 2.0, ">", 2.0, "b", 3) == "x = 2.000 <= 2.000 (b): no"
    assert claim_text("runs", 3, "==", 2, "two", 0) == "runs = 3 != 2 (two): no"
    assert claim_text("runs", 2, "==", 2, "two", 0) == "runs = 2 == 2 (two): yes"
    assert claim_text("x", math.nan, "<", 1.0, "one", 2) == "x = nan >= 1.00 (one): no"
    assert (claim_text("edge", None, ">", 8.4, "the paper", 1)
            == "edge: not available (claimed > 8.4, the paper): no")


def test_make_claim_records_the_number_and_its_statement():
    c = make_claim(METRICS, "G1.edge", "tasks.G1.foam.edge_peak_u", "peak u at the edge", ">", 5.0, "5 N.m", 1)
    assert c == {"id": "G1.edge", "path": "tasks.G1.foam.edge_peak_u", "subject": "peak u at the edge",
                 "value": 8.4, "op": ">", "bound": 5.0, "bound_name": "5 N.m", "digits": 1, "holds": True,
                 "text": "peak u at the edge = 8.4 > 5.0 (5 N.m): yes"}
    assert make_claim(METRICS, "g", "gamma_star.G1", "gamma*", "<=", 11.0, "gamma")["digits"] == 2


def test_make_claim_of_a_flag_or_a_missing_number():
    flag = make_claim(METRICS, "d", "tasks.G1.foam.diverged", "diverged", "==", 0, "no", 0)
    assert flag["value"] == 0 and type(flag["value"]) is int and flag["holds"] is True
    assert flag["text"] == "diverged = 0 == 0 (no): yes"
    for path in ("tasks.G4.foam", "runs.9", "runs.x", "runs.0.y", "gamma_star.G2"):
        c = make_claim(METRICS, "m", path, "m", "<", 1.0, "one")
        assert c["value"] is None and c["holds"] is False, path
        assert c["text"] == "m: not available (claimed < 1.00, one): no", path


def _claims(*cs: dict) -> dict:
    return {**METRICS, "claims": list(cs)}


def test_claims_that_agree_with_the_metrics_and_the_report():
    a = make_claim(METRICS, "a", "tasks.G1.foam.edge_peak_u", "edge", ">", 5.0, "five", 1)
    b = make_claim(METRICS, "b", "gamma_star.G2", "gamma* G2", "<=", 11.0, "gamma")   # missing both sides
    m = _claims(a, b)
    assert check_claims(m) == []
    assert check_claims(m, f"text\n{a['text']}\n{b['text']}\n") == []
    assert check_claims({"x": 1}) == []                        # no claims, nothing to disagree with


def test_a_claim_whose_number_changed():
    a = make_claim(METRICS, "a", "tasks.G1.foam.edge_peak_u", "edge", ">", 5.0, "five", 1)
    changed = _claims(a)
    changed["tasks"] = {"G1": {"foam": {"edge_peak_u": 8.4 * (1 + 1e-10)}}}
    assert check_claims(changed) == [f"a: the claim says 8.4, metrics.tasks.G1.foam.edge_peak_u is {8.4 * (1 + 1e-10)!r}"]
    changed["tasks"]["G1"]["foam"]["edge_peak_u"] = 8.4 * (1 + 1e-13)     # rounding is not a change
    assert check_claims(changed) == []
    gone = _claims(a)
    gone["tasks"] = {}
    assert check_claims(gone) == ["a: the claim says 8.4, metrics.tasks.G1.foam.edge_peak_u is None"]
    b = make_claim(METRICS, "b", "gamma_star.G2", "g", "<", 1.0, "one")
    appeared = _claims(b)
    appeared["gamma_star"] = {"G2": 0.5}
    assert check_claims(appeared) == ["b: the claim says None, metrics.gamma_star.G2 is 0.5"]


def test_a_claim_whose_number_is_a_flag():
    c = make_claim(METRICS, "d", "tasks.G1.foam.diverged", "diverged", "==", 0, "no", 0)
    assert check_claims(_claims(c)) == []
    flipped = _claims(c)
    flipped["tasks"] = {"G1": {"foam": {"diverged": True}}}
    assert check_claims(flipped) == ["d: the claim says 0, metrics.tasks.G1.foam.diverged is 1"]


def test_a_claim_whose_verdict_or_wording_was_edited():
    a = make_claim(METRICS, "a", "gamma_star.G1", "gamma*", "<=", 11.0, "gamma")
    assert a["text"] == "gamma* = 13.60 > 11.00 (gamma): no"
    wrong_verdict = dict(a, holds=True)
    assert check_claims(_claims(wrong_verdict)) == ["a: holds = True but 13.6 <= 11.0 is False"]
    edited = dict(a, text="gamma* = 13.60 <= 11.00 (gamma): yes")
    assert check_claims(_claims(edited)) == [
        "a: the text 'gamma* = 13.60 <= 11.00 (gamma): yes' does not state 'gamma* = 13.60 > 11.00 (gamma): no'"]
    both = dict(a, holds=True, text="x")
    assert len(check_claims(_claims(both))) == 2


def test_a_claim_missing_from_the_report():
    a = make_claim(METRICS, "a", "gamma_star.G1", "gamma*", "<=", 11.0, "gamma")
    b = make_claim(METRICS, "b", "runs.#len", "runs", "==", 3, "three", 0)
    assert check_claims(_claims(a, b), a["text"]) == ["b: not in the report: 'runs = 3 == 3 (three): yes'"]
    # every claim is checked, after a wrong one too
    wrong = dict(a, value=1.0)
    assert check_claims(_claims(wrong, b), b["text"]) == ["a: the claim says 1.0, metrics.gamma_star.G1 is 13.6"]
    assert check_claims(_claims(wrong, b), "") == ["a: the claim says 1.0, metrics.gamma_star.G1 is 13.6",
                                                   "b: not in the report: 'runs = 3 == 3 (three): yes'"]
    # a claim that is wrong is named for that, not also for its absence
    moved = dict(b, value=4)
    assert check_claims(_claims(a, moved), "") == ["a: not in the report: 'gamma* = 13.60 > 11.00 (gamma): no'",
                                                   "b: the claim says 4, metrics.runs.#len is 3"]
