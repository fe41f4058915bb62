"""The condition grammar of events (cosim.scenario.condition) and real-time pacing (cosim.runtime.pacing), without FMUs:
the parser against the precedence of Python's own operators, its refusals, the type check, and the pacer
against a simulated clock."""
from __future__ import annotations

import itertools
import random

import pytest

from cosim_support import FakeClock
from wmr_cosim.cosim.runtime import pacing
from wmr_cosim.cosim.scenario.condition import ConditionError, check_types, compile_condition, parse, tokenize, variables


def _eval(text: str, values: dict[str, float], t: float = 0.0) -> bool:
    node = parse(text)
    return compile_condition(node, {k: (lambda v=v: v) for k, v in values.items()})(t)


def test_precedence_is_not_then_and_then_or():
    assert parse("a.x > 1 or a.y > 2 and not a.z > 3") == \
        ("or", ("cmp", ">", ("var", "a.x"), ("num", 1.0)),
         ("and", ("cmp", ">", ("var", "a.y"), ("num", 2.0)), ("not", ("cmp", ">", ("var", "a.z"), ("num", 3.0)))))
    assert parse("(a.x > 1 or a.y > 2) and t >= 5")[0] == "and"


def test_evaluation_agrees_with_python_on_every_combination():
    """Random conditions over three variables, evaluated on every combination of values, against the same
    text evaluated by Python's own operators (the grammar's keywords are Python's)."""
    rng = random.Random(3)
    ops = ["<", "<=", ">", ">=", "==", "!="]
    names = ["p.a", "p.b", "q.c"]

    def gen(depth: int) -> str:
        r = rng.random()
        if depth == 0 or r < 0.3:
            left = rng.choice(names + ["t"])
            right = rng.choice(names + ["1", "-1", "0.5", "2e0", "t"])
            return f"{left} {rng.choice(ops)} {right}"
        if r < 0.45:
            return f"not {gen(depth - 1)}"
        if r < 0.6:
            return f"({gen(depth - 1)})"
        return f"{gen(depth - 1)} {rng.choice(['and', 'or'])} {gen(depth - 1)}"

    for _ in range(200):
        text = gen(4)
        for a, b, c, t in itertools.product([-1.0, 0.5, 1.0], [0.5, 2.0], [-1.0, 1.0], [0.0, 1.0]):
            env = {"p_a": a, "p_b": b, "q_c": c, "t": t}
            expected = eval(text.replace("p.a", "p_a").replace("p.b", "p_b").replace("q.c", "q_c"), {}, env)
            assert _eval(text, {"p.a": a, "p.b": b, "q.c": c}, t) == bool(expected), text


def test_booleans_numbers_and_names():
    assert _eval("not c.flag", {"c.flag": False})
    assert _eval("c.flag == true and c.n >= 3", {"c.flag": True, "c.n": 3})
    assert not _eval("c.x < -1.5e-3", {"c.x": 0.0})
    assert variables(parse("a.b.c[1] > 0 and t > 1 or a.b.c[1] < x.y")) == ["a.b.c[1]", "x.y"]
    assert [tk.kind for tk in tokenize("a.x<=1")] == ["name", "op", "number", "end"]


def test_a_syntax_error_names_the_token_and_its_position_or_the_end():
    for text, message in [
            ("plant.x_A > 1 2", "expected and, or or the end, found '2' at character 15 of 'plant.x_A > 1 2'"),
            ("plant.x_A >", "expected a variable, a number, true, false, t or '(', found at the end of 'plant.x_A >'"),
            ("(a.b > 1", "expected ')', found at the end of '(a.b > 1'")]:
        with pytest.raises(ConditionError) as info:
            parse(text)
        assert str(info.value) == message


@pytest.mark.parametrize("text, words", [
    ("", "empty"),
    ("plant.x_A >", "expected a variable"),
    ("plant.x_A > 1 and", "expected a variable"),
    ("(plant.x_A > 1", "expected ')'"),
    ("plant.x_A > 1)", "expected and, or or the end"),
    ("x > 1", "instance.variable"),
    ("plant.x_A + 1 > 2", "unexpected '+'"),
    ("__import__('os').system('true')", "instance.variable"),
    ("plant.f(1) > 1", "expected and, or or the end"),
    ("plant.f('x') > 1", "unexpected"),
    ("plant.x_A > 1 2", "expected and, or"),
    ("- plant.x_A > 1", "a number after '-'"),
    ("not " * 60 + "a.b", "nested more than"),
    ("a.b > " + "1" * 3000, "at most"),
])
def test_refused_conditions_say_why(text, words):
    with pytest.raises(ConditionError, match=None) as info:
        parse(text)
    assert words in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("text, words", [
    ("p.x > true", "compares a number with a boolean"),
    ("p.flag < p.flag", "== or != only"),
    ("p.x", "not a condition"),
    ("t", "not a condition"),
    ("p.s == 1", "String"),
])
def test_type_check(text, words):
    with pytest.raises(ConditionError) as info:
        check_types(parse(text), {"p.x": "Real", "p.flag": "Boolean", "p.s": "String"})
    assert words in str(info.value)


def test_type_check_accepts_numbers_and_booleans():
    check_types(parse("p.x > p.n and p.flag != false or not p.flag and t < 3"),
                {"p.x": "Real", "p.n": "Integer", "p.flag": "Boolean"})


def test_pacer_sleeps_to_each_due_time_and_counts_the_late_steps(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(pacing.time, "sleep", clock.sleep)
    p = pacing.Pacer(2.0, _clock=clock)      # twice real time: a step of 0.1 s is due every 0.05 s
    p.start(0.0)
    work = [0.01, 0.01, 0.12, 0.01, 0.01, 0.01]   # the third step takes longer than its slot
    due = []
    for k, w in enumerate(work, start=1):
        clock.now += w
        p.wait(k * 0.1)
        due.append(clock.now)
    t0 = 100.0
    # on schedule: wake exactly at the due time; late: no sleep, and later steps catch up without skipping
    assert due[0] == pytest.approx(t0 + 0.05) and due[1] == pytest.approx(t0 + 0.10)
    assert due[2] == pytest.approx(t0 + 0.22)                 # 0.07 s late (due at 0.15)
    assert due[3] == pytest.approx(t0 + 0.23)                 # 0.03 s late (due at 0.20)
    assert due[4] == pytest.approx(t0 + 0.25) and due[5] == pytest.approx(t0 + 0.30)
    s = p.summary()
    assert s["steps"] == 6 and s["overruns"] == 2
    assert s["late_max_s"] == pytest.approx(0.07) and s["late_mean_s"] == pytest.approx(0.05)
    assert p.describe() == "real time x2: 2 of 6 steps finished late (by up to 70 ms, 50 ms on average)"


def test_pacer_without_overruns_says_so(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(pacing.time, "sleep", clock.sleep)
    p = pacing.Pacer(0.5, _clock=clock)     # half real time: the step of 0.1 s is due after 0.2 s
    p.start(0.0)
    clock.now += 0.1
    p.wait(0.1)
    assert p.describe() == "real time x0.5: no overruns in 1 step" and p.summary()["late_mean_s"] == 0.0


@pytest.mark.parametrize("factor", [0, -1, float("nan"), float("inf")])
def test_pacer_refuses_a_bad_factor(factor):
    with pytest.raises(ValueError):
        pacing.Pacer(factor)
