"""The events' conditions as the Boolean part of the requirements' language: one tokenizer and parser
(cosim.requirements.formula, the condition dialect), so that the same mistake gets the same reason in a
condition and in a formula, the requirements' operators are refused in a condition with a message that
says so, and a condition is true exactly where the same formula's robustness is positive."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from wmr_cosim.cosim.requirements import formula
from wmr_cosim.cosim.requirements.formula import ExpressionError, FormulaError, VarInfo, check
from wmr_cosim.cosim.requirements.monitor import evaluate
from wmr_cosim.cosim.scenario import condition
from wmr_cosim.cosim.scenario.condition import ConditionError


def _refusal(parse, text) -> ExpressionError:
    with pytest.raises(ExpressionError) as info:
        parse(text)
    return info.value


@pytest.mark.parametrize("text", [
    "a.x > 0 $",                      # a character outside the language
    "a.x >= 'q'",
    "a.x > 1 and x > 2",              # a name without its instance
    "a.x > b.y adn a.y > 0",          # a misspelt operator: the same suggestion
    "nto a.x > 1",
    "(a.x > 1",                       # a parenthesis left open
    "(a.x > b.y c.z",
    5,                                # not text
])
def test_the_same_mistake_gets_the_same_reason_in_a_condition_and_a_formula(text):
    c, f = _refusal(condition.parse, text), _refusal(formula.parse, text)
    assert isinstance(c, ConditionError) and isinstance(f, FormulaError)
    assert (c.reason, c.pos, c.word, c.found) == (f.reason, f.pos, f.word, f.found)
    assert "\n" not in str(c) and "\n" not in str(f)


def test_a_misspelt_operator_is_suggested_in_a_condition_as_in_a_formula():
    assert str(_refusal(condition.parse, "a.x > b.y adn a.y > 0")) == (
        "'adn' at character 11: not an operator, nor a variable (\"instance.variable\") (did you mean 'and'?)")
    assert str(_refusal(formula.parse, "a.x > b.y adn a.y > 0")) == (
        "at character 11: 'adn': not an operator, nor a variable (\"instance.variable\") (did you mean 'and'?)")


@pytest.mark.parametrize("text, word, pos", [
    ("always a.x > 0", "always", 1),
    ("eventually[0,1] a.x > 0", "eventually", 1),
    ("not historically a.x > 0", "historically", 5),
    ("once a.x > 0", "once", 1),
    ("a.x > 0 until a.y > 0", "until", 9),
    ("a.x > 0 since a.y > 0", "since", 9),
])
def test_a_temporal_operator_in_a_condition_is_refused_as_one(text, word, pos):
    formula.parse(text)   # (a formula takes it)
    assert str(_refusal(condition.parse, text)) == (
        f"{word!r} at character {pos}: a temporal operator: a condition is true or false at each communication "
        "point (temporal operators are for requirements)")


@pytest.mark.parametrize("text, words", [
    ("a.x > 0 implies a.y > 0", "an operator of requirements, not of conditions"),
    ("abs(a.x) > 1", "an operator of requirements, not of conditions"),
    ("sqrt(a.x) > 1", "an operator of requirements, not of conditions"),
    ("a.x + 1 > 2", "unexpected '+'"),
    ("a.x * 2 > 2", "unexpected '*'"),
    ("a.x - 1 > 2", "expected and, or or the end, found '-'"),
    ("a.x > -a.y", "expected a number after '-'"),
    ("a.x > 5 cm", "'cm' at character 9: a variable is"),
    ("(a.x) > 1", "expected and, or or the end, found '>'"),
    ("a.x > (1)", "expected a variable, a number, true, false, t or '(', found '('"),
])
def test_what_only_a_formula_takes_is_refused_in_a_condition(text, words):
    formula.parse(text)
    assert words in str(_refusal(condition.parse, text))


def test_a_condition_keeps_a_number_beyond_the_largest_as_infinite():
    """(A formula refuses it; a condition always took it.)"""
    assert condition.parse("a.x < 1e999") == ("cmp", "<", ("var", "a.x"), ("num", float("inf")))
    assert "beyond the largest number" in str(_refusal(formula.parse, "a.x < 1e999"))


def test_one_table_of_comparisons():
    assert condition.COMPARE is formula.COMPARE
    assert [(op, c.truth(1.0, 2.0), c.truth(2.0, 2.0)) for op, c in formula.COMPARE.items()] == [
        ("<", True, False), ("<=", True, True), (">", False, False), (">=", False, True), ("==", False, True),
        ("!=", True, False)]


# --------------------------------------------------------------------- a condition and a formula agree
NUMBERS = ["p.a", "p.b", "q.c", "t", "1", "-0.5", "2.5e0", "0"]
BOOLEANS = ["p.f", "true", "false"]


@st.composite
def _conditions(draw, depth: int = 3) -> str:
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        if draw(st.integers(0, 4)) == 0:
            return draw(st.sampled_from(BOOLEANS))
        return f"{draw(st.sampled_from(NUMBERS))} {draw(st.sampled_from(list(formula.COMPARE)))} " \
               f"{draw(st.sampled_from(NUMBERS))}"
    how = draw(st.sampled_from(["and", "or", "not", "paren"]))
    if how == "not":
        return f"not {draw(_conditions(depth - 1))}"
    if how == "paren":
        return f"({draw(_conditions(depth - 1))})"
    return f"{draw(_conditions(depth - 1))} {how} {draw(_conditions(depth - 1))}"


_VALUES = st.floats(-3.0, 3.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(_conditions(), _VALUES, _VALUES, _VALUES, st.booleans(), st.floats(0.0, 3.0))
def test_a_condition_is_true_where_the_same_formula_is_positive(text, a, b, c, f, t):
    """Where no comparison is at a tie (there a robustness is 0 whatever the comparison), the condition is
    true exactly where the requirement of the same text has a positive robustness."""
    values = {"p.a": a, "p.b": b, "q.c": c, "p.f": f}
    node = condition.parse(text)

    def value(operand: tuple) -> float:
        return t if operand[0] == "time" else operand[1] if operand[0] == "num" else values[operand[1]]

    def pairs(n: tuple):
        if n[0] == "cmp":
            yield value(n[2]), value(n[3])
        for x in n[1:]:
            if isinstance(x, tuple):
                yield from pairs(x)
    assume(all(x != y for x, y in pairs(node)))
    truth = condition.compile_condition(node, {k: (lambda v=v: v) for k, v in values.items()})(t)
    info = {k: VarInfo("Boolean" if k == "p.f" else "Real", None) for k in values}
    verdict, _ = evaluate("r", check(text, info, 1.0, 10.0), [t], {k: np.array([float(v)]) for k, v in values.items()},
                          1.0)
    assert verdict.robustness != 0.0 and truth == (verdict.robustness > 0.0), (text, verdict.robustness)
