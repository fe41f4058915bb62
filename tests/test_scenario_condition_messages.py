"""Conditions of events (cosim.scenario.condition): the exact one-line messages of refused conditions (what the user
sees), the nesting limit at its boundary, the tokens returned, and the type check of every operand."""
from __future__ import annotations

import pytest

from wmr_cosim.cosim.scenario.condition import (MAX_DEPTH, MAX_LENGTH, ConditionError, Token, check_types,
                                       compile_condition, parse, tokenize)

TYPES = {"p.x": "Real", "p.n": "Integer", "p.e": "Enumeration", "p.flag": "Boolean", "p.s": "String"}


def _message(text) -> str:
    with pytest.raises(ConditionError) as info:
        parse(text)
    return str(info.value)


def _type_error(text: str) -> str:
    with pytest.raises(ConditionError) as info:
        check_types(parse(text), TYPES)
    return str(info.value)


@pytest.mark.parametrize("text, message", [
    ("", "an empty condition"),
    ("a.x > 1 + 2", "unexpected '+' at character 9 of 'a.x > 1 + 2'"),
    ("a.x > 1 and x > 2", "'x' at character 13: a variable is \"instance.variable\" (or t for the time)"),
    ("a.x > - a.y", "expected a number after '-', found 'a.y' at character 9 of 'a.x > - a.y'"),
    ("a.x > 1 true", "expected and, or or the end, found 'true' at character 9 of 'a.x > 1 true'"),
    ("a.x > and", "expected a variable, a number, true, false, t or '(', found 'and' at character 7 of 'a.x > and'"),
    (") a.x", "expected a variable, a number, true, false, t or '(', found ')' at character 1 of ') a.x'"),
])
def test_refusals_are_one_exact_line(text, message):
    assert _message(text) == message


def test_a_condition_that_is_not_text_is_named():
    assert _message(5) == "must be a string, not 5"


def test_the_length_limit_is_inclusive():
    at_limit = "a.x > " + "1" * (MAX_LENGTH - 6)
    assert len(at_limit) == MAX_LENGTH
    assert parse(at_limit)[0] == "cmp"
    assert _message(at_limit + "1") == f"a condition of {MAX_LENGTH + 1} characters: at most {MAX_LENGTH}"


def test_tokens_end_with_an_end_token_at_the_length():
    assert tokenize("a.x<=1") == [Token("name", "a.x", 0), Token("op", "<=", 3), Token("number", "1", 5),
                                  Token("end", "", 6)]


def _deep(n: int, how: str) -> str:
    """``n`` levels of nesting around a.b: parentheses, nots, or both alternately."""
    text = "a.b"
    for k in range(n):
        kind = how if how != "mixed" else ("not" if k % 2 else "paren")
        text = f"not {text}" if kind == "not" else f"({text})"
    return text


@pytest.mark.parametrize("prefix", ["", "not a.b and ", "(a.b) and ", "not (not a.b) or ((a.b)) and "])
@pytest.mark.parametrize("how", ["not", "paren", "mixed"])
def test_the_nesting_limit_counts_the_open_levels_only(prefix, how):
    """Nesting that has closed before does not count: MAX_DEPTH open levels parse, one more does not."""
    parse(prefix + _deep(MAX_DEPTH, how))
    assert _message(prefix + _deep(MAX_DEPTH + 1, how)) == f"nested more than {MAX_DEPTH} deep"


@pytest.mark.parametrize("text, message", [
    ("t", "t is a number, not a condition: compare it (e.g. t > 0)"),
    ("p.x", "p.x is a number, not a condition: compare it (e.g. p.x > 0)"),
    ("1.5", "1.5 is a number, not a condition: compare it (e.g. 1.5 > 0)"),
    ("p.x or p.flag", "p.x is a number, not a condition: compare it (e.g. p.x > 0)"),
    ("p.x == true", "wrong type: p.x == true compares a number with a boolean"),
    ("false != p.n", "wrong type: false != p.n compares a boolean with a number"),
    ("p.flag < 2.5", "wrong type: p.flag < 2.5 compares a boolean with a number"),
    ("t >= p.flag", "wrong type: t >= p.flag compares a number with a boolean"),
    ("p.flag > false", "booleans compare with == or != only, not >"),
    ("p.e > p.s", "p.s is String: a condition compares numbers and booleans only"),
])
def test_type_errors_are_one_exact_line(text, message):
    assert _type_error(text) == message


def test_enumerations_compare_as_numbers_and_booleans_with_equality():
    check_types(parse("p.e == 2 and p.e < p.x and p.flag == true and false == p.flag"), TYPES)


@pytest.mark.parametrize("value", [True, False])
def test_a_boolean_alone_is_a_condition(value):
    pred = compile_condition(parse("p.flag"), {"p.flag": lambda: value})
    assert pred(0.0) is value
    assert compile_condition(parse("p.flag == true"), {"p.flag": lambda: value})(0.0) is value
