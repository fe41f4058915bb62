"""Requirements in signal temporal logic (cosim/requirements/): the formula language and its check, the
online monitor's robustness against rtamt's offline monitor and against a brute-force evaluation written
from the definitions, the verdicts and when they are known."""
from __future__ import annotations

import math
import random

import numpy as np
import pytest

from wmr_cosim.cosim.model.units import KNOWN
from wmr_cosim.cosim.requirements.formula import FormulaError, VarInfo, check, parse
from wmr_cosim.cosim.requirements.monitor import Monitor, evaluate

INFO = {"a.x": VarInfo("Real", KNOWN["m"]), "a.y": VarInfo("Real", KNOWN["m"]), "a.u": VarInfo("Real", KNOWN["N.m"]),
        "a.b": VarInfo("Boolean", None), "a.n": VarInfo("Integer", None), "a.s": VarInfo("String", None)}


def traces(n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"a.x": np.round(rng.normal(0, 2, n), 3), "a.y": np.round(rng.normal(0, 2, n), 3)}


def ours(formula: str, sig: dict[str, np.ndarray], step: float = 1.0) -> np.ndarray:
    """Our robustness of ``formula`` at every point (NaN where its windows are cut by the end)."""
    n = len(next(iter(sig.values())))
    c = check(f"historically[0,0] ({formula})", INFO, step, step * (n - 1))   # (a past operator of width 0:
    return evaluate("r", c, [k * step for k in range(n)], sig, step)[1]      # its operand at every point)


# ------------------------------------------------------------------------------------------- rtamt
RTAMT = [   # (ours, rtamt's): every operator, bounded and unbounded past
    ("always[0,3] a.x > 0 and eventually[1,4] a.y > 0.5", "always[0,3](x>0) and eventually[1,4](y>0.5)"),
    ("a.x > 0 until[1,3] a.y > 1", "(x>0) until[1,3] (y>1)"),
    ("not (a.x > 0 since[0,3] a.y > 1) or historically[1,2] a.x < 1", "not((x>0) since[0,3] (y>1)) or historically[1,2](x<1)"),
    ("once a.y > 2 implies historically abs(a.x) < 3", "once(y>2) -> historically(abs(x)<3)"),
    ("a.x > 0 since a.y > 1", "(x>0) since (y>1)"),
    ("once[2,5] (a.x + 2 * a.y >= 1 - a.x / 4)", "once[2,5](x + 2 * y >= 1 - x / 4)"),
    ("always[0,2] (a.x == a.y or a.x != 0.5)", "always[0,2]((x == y) or (x !== 0.5))"),
    ("eventually[0,4] (a.x <= -1 and not always[1,2] a.y > -a.x)", "eventually[0,4]((x <= -1) and not(always[1,2](y > 0 - x)))"),
    ("always[0,2] sqrt(a.x * a.x + a.y * a.y) < 1.5", "always[0,2](sqrt(x * x + y * y) < 1.5)"),
]


@pytest.mark.parametrize("formula,theirs", RTAMT)
def test_robustness_equals_rtamts(formula: str, theirs: str) -> None:
    """rtamt's discrete-time offline monitor on the same traces (80 points, two seeds): equal at every
    point whose windows lie inside the trace (rtamt cuts them at the end; we do not judge those)."""
    rtamt = pytest.importorskip("rtamt")
    for seed in (1, 2):
        sig = traces(80, seed)
        spec = rtamt.StlDiscreteTimeOfflineSpecification()
        spec.declare_var("x", "float")
        spec.declare_var("y", "float")
        spec.spec = theirs
        spec.parse()
        ref = np.array([v for _, v in spec.evaluate({"time": list(range(80)), "x": list(sig["a.x"]),
                                                    "y": list(sig["a.y"])})], dtype=float)
        got = ours(formula, sig)
        known = ~np.isnan(got)
        assert known.sum() >= 70
        assert np.array_equal(got[known], ref[known]), (formula, seed)


# ------------------------------------------------------------------------------------------ brute force
def brute(node, sig: dict[str, np.ndarray], n: int) -> list[float]:
    """Robustness by the definitions, with loops; NaN where a window leaves the trace."""
    from wmr_cosim.cosim.requirements import formula as f
    if isinstance(node, f.Cmp):
        a, b = num(node.a, sig, n), num(node.b, sig, n)
        return [(x - y if node.op in (">", ">=") else y - x if node.op in ("<", "<=")
                 else -abs(x - y) if node.op == "==" else abs(x - y)) for x, y in zip(a, b)]
    if isinstance(node, f.Not):
        return [-v for v in brute(node.a, sig, n)]
    if isinstance(node, f.Logic):   # (a chain of and/or folded left to right: nested pairs)
        out = brute(node.args[0], sig, n)
        for arg in node.args[1:]:
            a, b = out, brute(arg, sig, n)
            op = {"and": min, "or": max, "implies": lambda x, y: max(-x, y)}[node.op]
            out = [math.nan if math.isnan(x) or math.isnan(y) else op(x, y) for x, y in zip(a, b)]
        return out
    if isinstance(node, f.Temporal):
        a = brute(node.a, sig, n)
        agg = min if node.op in ("always", "historically") else max
        lo = int(node.lo)
        out = []
        for k in range(n):
            if node.op in ("always", "eventually"):
                idx = range(k + lo, k + int(node.hi) + 1)
                if idx[-1] >= n:
                    out.append(math.nan)
                    continue
            else:
                idx = range(0 if node.hi is None else max(0, k - int(node.hi)), k - lo + 1)
            vals = [a[j] for j in idx]
            out.append(math.nan if any(map(math.isnan, vals)) else
                       agg(vals) if vals else (math.inf if agg is min else -math.inf))
        return out
    assert isinstance(node, f.Until)
    a, b = brute(node.a, sig, n), brute(node.b, sig, n)
    out = []
    for k in range(n):
        if node.op == "until":
            if k + int(node.hi) >= n:
                out.append(math.nan)
                continue
            js = range(k + int(node.lo), k + int(node.hi) + 1)
            operands = [[b[j]] + [a[i] for i in range(k, j)] for j in js]
        else:
            js = range(0 if node.hi is None else max(0, k - int(node.hi)), k - int(node.lo) + 1)
            operands = [[b[j]] + [a[i] for i in range(j + 1, k + 1)] for j in js]
        if any(math.isnan(v) for vals in operands for v in vals):
            out.append(math.nan)
            continue
        terms = [min(vals) for vals in operands]
        out.append(max(terms) if terms else -math.inf)
    return out


def num(node, sig: dict[str, np.ndarray], n: int) -> list[float]:
    from wmr_cosim.cosim.requirements import formula as f
    if isinstance(node, f.Num):
        return [node.value] * n
    if isinstance(node, f.Var):
        return list(sig[node.name])
    if isinstance(node, f.Abs):
        return [abs(v) for v in num(node.a, sig, n)]
    if isinstance(node, f.Sqrt):
        return [math.sqrt(v) for v in num(node.a, sig, n)]
    if isinstance(node, f.Neg):
        return [-v for v in num(node.a, sig, n)]
    out = num(node.first, sig, n)   # an Arith chain, left to right
    for op, _, operand in node.rest:
        a, b = out, num(operand, sig, n)
        out = [x + y if op == "+" else x - y if op == "-" else x * y if op == "*" else x / y for x, y in zip(a, b)]
    return out


def random_formula(rng: random.Random, depth: int) -> str:
    """A random formula over a.x and a.y with bounds in whole seconds (the step is 1 s here)."""
    if depth == 0 or rng.random() < 0.25:
        lhs = rng.choice(["a.x", "a.y", "abs(a.x)", "a.x - a.y", "2 * a.y", "sqrt(a.x * a.x + a.y * a.y)"])
        return f"{lhs} {rng.choice(['<', '>', '>=', '<=', '==', '!='])} {rng.choice(['0', '1', '-0.5', 'a.y'])}"
    lo = rng.randint(0, 3)
    hi = lo + rng.randint(0, 4)
    sub = lambda: random_formula(rng, depth - 1)   # noqa: E731
    past = rng.choice(["", f"[{lo},{hi}]"])
    return rng.choice([
        f"not ({sub()})", f"({sub()}) and ({sub()})", f"({sub()}) or ({sub()})", f"({sub()}) implies ({sub()})",
        f"always[{lo},{hi}] ({sub()})", f"eventually[{lo},{hi}] ({sub()})", f"historically{past} ({sub()})",
        f"once{past} ({sub()})", f"({sub()}) until[{lo},{hi}] ({sub()})", f"({sub()}) since{past} ({sub()})"])


def test_robustness_equals_a_brute_force_evaluation_on_random_formulas() -> None:
    """200 random formulas of depth up to 3 on random traces of 40 points: our online monitor's value at
    every point equals the definitions evaluated with loops (NaN in the same places: the windows cut by
    the end of the trace)."""
    rng = random.Random(7)
    for i in range(200):
        text = random_formula(rng, 3)
        sig = traces(40, i)
        want = np.array(brute(parse(text), sig, 40), dtype=float)
        got = ours(text, sig)
        assert np.array_equal(np.isnan(got), np.isnan(want)), text
        assert np.array_equal(got[~np.isnan(got)], want[~np.isnan(want)]), text


# --------------------------------------------------------------------------------------- verdicts
def online(formula: str, sig: dict[str, np.ndarray], step: float = 0.5, covered: bool = True):
    """The monitor fed point by point; the verdict after each point (``covered``: the run reached its
    planned stop)."""
    n = len(next(iter(sig.values())))
    c = check(formula, INFO, step, step * (n - 1))
    k = [0]
    read = {v: (lambda a=sig[v]: float(a[k[0]])) for v in c.variables}
    m = Monitor("r", c, read, step)
    seen = []
    for i in range(n):
        k[0] = i
        m.sample(i * step)
        seen.append((m.verdict.verdict, m.violated_now))
    m.finish(covered=covered)
    return m.verdict, seen


def test_a_violated_always_is_known_at_the_violating_point() -> None:
    x = np.array([1.0, 0.5, 0.2, -0.3, -1.0, 2.0])
    v, seen = online("a.x > 0", {"a.x": x})
    assert v.verdict == "violated" and v.first_violation == 1.5 and v.decided_at == 1.5
    assert v.robustness == -1.0 and v.at == 2.0
    assert [s for s, _ in seen] == ["undecided"] * 3 + ["violated"] * 3
    assert [now for _, now in seen] == [False, False, False, True, False, False]


def test_an_always_that_looks_ahead_is_decided_later_but_names_the_point_it_fails() -> None:
    """always (x > 0 implies eventually[0,1] y > 0): x > 0 at 0.5 s with no y > 0 until 1.5 s: the
    violation refers to 0.5 s and is known at 1.5 s, when the window closes."""
    x = np.array([-1.0, 1.0, -1.0, -1.0, -1.0, -1.0])
    y = np.array([-1.0, -1.0, -1.0, -1.0, 1.0, -1.0])
    v, _ = online("always (a.x > 0 implies eventually[0,1] a.y > 0)", {"a.x": x, "a.y": y})
    assert v.verdict == "violated" and v.first_violation == 0.5 and v.decided_at == 1.5


def test_an_eventually_holds_at_its_first_satisfying_point_and_reports_its_best() -> None:
    y = np.array([-3.0, -1.0, 0.5, 2.0, 1.0, -2.0])
    v, seen = online("eventually[0,2] a.y > 0", {"a.y": y})
    assert v.verdict == "holds" and v.decided_at == 1.0 and v.robustness == 2.0 and v.at == 1.5
    assert v.first_violation is None


def test_a_window_the_run_ends_inside_is_undecided_and_a_complete_one_is_not() -> None:
    x = np.ones(6)
    assert online("always[1,4] a.x > 0", {"a.x": x})[0].verdict == "undecided"      # 4 s > 2.5 s
    assert online("always[1,2] a.x > 0", {"a.x": x})[0].verdict == "holds"
    v, _ = online("eventually[0,1] a.x < 0", {"a.x": x})
    assert v.verdict == "violated" and v.first_violation == 1.0 and v.decided_at == 1.0


def test_a_constant_with_a_unit_is_converted_into_the_variables() -> None:
    """a.x in m against 5 cm: robustness in m; a torque in N.m against 8 N.m; a length against N.m is
    refused with the position."""
    x = np.array([0.01, 0.04, 0.07])
    v, _ = online("a.x < 5 cm", {"a.x": x})
    assert v.verdict == "violated" and v.robustness == pytest.approx(0.05 - 0.07, abs=1e-15)
    c = check("abs(a.u) <= 8 N.m", INFO, 0.5, 1.0)
    assert c.unit_of and set(c.unit_of.values()) == {"N.m"}
    d = check("sqrt((a.x - 2 m) * (a.x - 2 m) + a.y * a.y) < 5 cm", INFO, 0.5, 1.0)   # a distance, in m
    assert set(d.unit_of.values()) == {"m"}
    v, _ = online("sqrt((a.x - 2 m) * (a.x - 2 m) + a.y * a.y) < 5 cm", {"a.x": np.array([1.97]), "a.y": np.array([0.04])})
    assert v.robustness == pytest.approx(0.05 - math.hypot(0.03, 0.04), abs=1e-15) and v.robustness == pytest.approx(0.0)
    with pytest.raises(FormulaError, match=r"at character 5: N\.m does not convert to m"):
        check("a.x < 8 N.m", INFO, 0.5, 1.0)


@pytest.mark.parametrize("formula,message", [
    ("a.x > ", "at character 7: expected a variable, a number, t, true, false, abs(...), sqrt(...) or '(', found the end"),
    ("a.x > 0 and (a.y < 1", "at character 21: expected ')', found the end"),
    ("a.z > 0", "at character 1: unknown variable a.z"),
    ("a.x > 5 furlong", "at character 9: unknown unit 'furlong'"),
    ("eventually a.x > 0", "at character 1: eventually without a bound: a future operator needs one"),
    ("a.x > 0 and always a.y > 0", "at character 13: always without a bound"),
    ("always[0,0.3] a.x > 0", "at character 1: always[0,0.3]: 0.3 s is not a multiple of the communication step 0.2 s"),
    ("always[2,1] a.x > 0", "at character 1: always[2,1]: a bound [a,b] needs 0 <= a <= b"),
    ("a.x and a.y > 0", "at character 1: a.x is a number, not a condition"),
    ("a.s == 1", "at character 1: a.s is String: arithmetic and comparisons take numbers"),
    ("a.b > 1", "at character 1: a.b is Boolean"),
    ("x > 0", "at character 1: 'x': a variable is \"instance.variable\""),
    ("a.x > 0 $", "at character 9: unexpected '$'"),
    ("sqrt(a.x) < 1", "at character 1: sqrt of m: a unit whose exponents are not all even"),
    ("eventualy[0,1] a.x > 0", "at character 1: 'eventualy': not an operator, nor a variable (\"instance.variable\") "
                               "(did you mean 'eventually'?)"),
    ("alwys (a.x > 0)", "at character 1: 'alwys': not an operator, nor a variable (\"instance.variable\") "
                        "(did you mean 'always'?)"),
    ("(a.x > 0) untl[0,1] a.y > 0", "at character 11: 'untl': not an operator, nor a variable (\"instance.variable\") "
                                    "(did you mean 'until'?)"),
    ("a.x > 0 untl[0,1] a.y > 0", "at character 9: 'untl': not a unit, nor an operator (did you mean 'until'?)"),
    ("a.x > 0 adn a.y > 0", "at character 9: 'adn': not a unit, nor an operator (did you mean 'and'?)"),
    ("a.x > 1e400", "at character 7: 1e400: beyond the largest number (about 1.8e308)"),
    ("eventually[0,1e999] a.x > 0", "at character 14: 1e999: beyond the largest number"),
])
def test_bad_formulas_say_where(formula: str, message: str) -> None:
    with pytest.raises(FormulaError) as e:
        check(formula, INFO, 0.2, 10.0)
    assert str(e.value).startswith(message), str(e.value)


def test_a_comparison_of_nan_is_false_with_robustness_minus_infinity() -> None:
    """sqrt of a negative number is NaN: the comparison it enters is violated, robustness -inf, whatever
    the order of the minimum it meets."""
    x = np.array([4.0, -1.0, 9.0])
    v, seen = online("sqrt(a.x * a.x * a.x / 1 m) > 1 m", {"a.x": x})
    assert v.verdict == "violated" and v.first_violation == 0.5 and v.robustness == -math.inf
    assert online("a.x > 0 and sqrt(a.x * a.x * a.x / 1 m) > 1 m", {"a.x": x})[0].robustness == -math.inf


def test_a_bound_beyond_the_stop_time_is_a_note() -> None:
    c = check("eventually[0,20] a.x > 0", INFO, 0.5, 10.0)
    assert c.notes == ["eventually[0,20] at character 1 reaches beyond the stop time 10 s: its verdict may stay "
                       "undecided"]


def test_a_formula_without_a_temporal_operator_is_read_as_always_over_the_run() -> None:
    c = check("a.b", INFO, 0.5, 1.0)
    assert c.node.op == "always" and c.node.hi is None   # type: ignore[attr-defined]
    v, _ = online("a.b", {"a.b": np.array([1.0, 1.0, 1.0])})
    assert v.verdict == "holds" and v.robustness == math.inf


def test_an_unbounded_always_holds_only_over_a_run_that_reached_its_planned_stop() -> None:
    """Every value >= 0: over a run to its stop, holds, known at its last point (2.5 s); over a run that
    ended early, undecided (robustness and its time: the lowest so far); an operand that looks 1 s ahead
    leaves the last points unjudged: the window ends at the last point judged; a run too short for any
    point to be judged is undecided with no robustness."""
    x = np.array([3.0, 2.0, 1.0, 2.0, 3.0, 4.0])
    v, _ = online("always a.x > 0", {"a.x": x})
    assert (v.verdict, v.decided_at, v.robustness, v.at, v.window) == ("holds", 2.5, 1.0, 1.0, (0.0, None))
    v, _ = online("always a.x > 0", {"a.x": x}, covered=False)
    assert (v.verdict, v.decided_at, v.robustness, v.at) == ("undecided", None, 1.0, 1.0)
    v, _ = online("always eventually[0,1] a.x > 0", {"a.x": x})
    assert (v.verdict, v.decided_at, v.window) == ("holds", 2.5, (0.0, 1.5))
    v, _ = online("always eventually[0,1] a.x > 0", {"a.x": x[:2]})
    assert (v.verdict, v.decided_at, v.robustness, v.at) == ("undecided", None, None, None)


@pytest.mark.parametrize("covered", [True, False])
def test_every_decided_verdict_says_when_it_was_decided(covered: bool) -> None:
    """A run that ended early keeps what was decided before it ended, with its time; a bounded window it
    did not reach is undecided whether or not the run reached its planned stop."""
    x = np.array([3.0, 2.0, -1.0, 2.0, 3.0, 4.0])
    cases = [("always[0,0.5] a.x > 0", "holds", 0.5), ("eventually[0,2] a.x < 0", "holds", 1.0),
             ("always a.x > 0", "violated", 1.0), ("eventually[0,0.5] a.x < 0", "violated", 0.5),
             ("a.x > 0 until[0,2] a.x < 0", "holds", 2.0), ("not always[0,0.5] a.x > 2.5", "holds", 0.5),
             ("always[0,4] a.x > -2", "undecided", None)]
    for formula, verdict, at in cases:
        v, _ = online(formula, {"a.x": x}, covered=covered)
        assert (v.verdict, v.decided_at) == (verdict, at), formula


# ------------------------------------------------------------------------- long and deeply nested formulas
def _same_as(long: str, short: str, sig: dict[str, np.ndarray]) -> None:
    """``long`` (within the length limit) checks, survives pickling and copying (a sweep ships it to its
    workers) and gives the verdict and robustness of ``short`` at every point, exactly."""
    import copy
    import pickle

    assert len(long) <= 4000
    c = check(long, INFO, 0.5, 10.0)
    assert pickle.loads(pickle.dumps(c.node)) == c.node and copy.deepcopy(c.node) == c.node
    n = len(next(iter(sig.values())))
    (v, r), (w, s) = (evaluate("r", check(f, INFO, 0.5, 10.0), [k * 0.5 for k in range(n)], sig, 0.5)
                      for f in (long, short))
    assert (v.verdict, v.robustness, v.at, v.decided_at) == (w.verdict, w.robustness, w.at, w.decided_at)
    assert np.array_equal(r, s, equal_nan=True)


def test_a_chain_of_495_ors_equals_its_shallow_equivalent() -> None:
    """The or of a.x > k for k cycling over 0..9, 495 times (a RecursionError before): the maximum of
    x - k, that is a.x > 0; the and of 388 of them, a.x > 9."""
    long = "or ".join(f"a.x>{k % 10}" for k in range(496))
    assert long.count("or") == 495
    _same_as(long, "a.x > 0", {"a.x": np.array([3.0, -1.0, 0.5, 12.0, -7.0])})
    _same_as(long[:3500].rsplit("or", 1)[0].replace("or", "and"), "a.x > 9",
             {"a.x": np.array([13.0, 11.0, 9.5, 12.0, 10.0, -1.0])})


def test_a_sum_of_1990_terms_equals_its_shallow_equivalent() -> None:
    """a.x + 1 + 1 + ... (1,990 +) against a.x + 1990, on integers (every partial sum exact), and a chain
    of 600 products and quotients against the one product it amounts to."""
    x = np.array([3.0, -2000.0, 10.0, -1990.0, 7.0])
    long = "a.x" + "+1" * 1990 + " > 5"
    assert long.count("+") == 1990
    _same_as(long, "a.x + 1990 > 5", {"a.x": x})
    _same_as("a.x" + "*2/2" * 300 + " >= 5", "a.x >= 5", {"a.x": x})
    _same_as("a.x" + "-1" * 1000 + "+1" * 990 + " < -3", "a.x - 10 < -3", {"a.x": x})


@pytest.mark.parametrize("depth", [60, 61])
def test_deep_nesting_is_honoured_up_to_its_limit_and_refused_in_one_line_beyond(depth: int) -> None:
    """60 levels of parentheses, of not, of always, of abs(...) and of implies give what their shallow
    equivalent gives; one level more is a FormulaError naming the limit (never a RecursionError)."""
    sig = {"a.x": np.array([3.0, -1.0, 0.5, 2.0, -7.0, 1.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]),
           "a.y": np.array([1.0, 2.0, -3.0, 0.5, 1.0, -1.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])}
    cases = [("(" * depth + "a.x > 0" + ")" * depth, "a.x > 0"),
             ("not " * depth + "a.x > 0", "a.x > 0" if depth % 2 == 0 else "not a.x > 0"),
             ("a.x > " + "abs(" * depth + "a.y" + ")" * depth, "a.x > abs(a.y)"),
             ("always[0,0] " * depth + "a.y < 2", "always[0,0] a.y < 2"),
             (" implies ".join(["a.y > 0"] * depth + ["a.x > 0"]), "a.y > 0 implies a.x > 0"),
             ("(" * (depth - 40) + "(a.x > 0 or (a.y > 0 and " * 20 + "a.x > 1" + "))" * 20 + ")" * (depth - 40),
              "a.x > 0 or (a.y > 0 and a.x > 1)")]
    for long, short in cases:
        if depth <= 60:
            _same_as(long, short, sig)
        else:
            with pytest.raises(FormulaError, match=r"nested too deeply \(at most 60 levels"):
                check(long, INFO, 0.5, 10.0)


def test_an_unbounded_always_whose_operand_looks_ahead_is_a_note() -> None:
    """The last points of the run are not judged: check says how many seconds (the sum of the future
    bounds on the deepest way down), and the monitor's window ends there."""
    c = check("always (a.x > 0 implies eventually[0,1] (a.y > 0 or a.x > 0 until[0,0.5] a.y < 0))", INFO, 0.5, 10.0)
    assert c.notes == ["always without a bound at character 1 over an operand that looks 1.5 s ahead: the last "
                       "1.5 s of the run are not judged (its window ends there)"]
    assert check("always historically[0,3] a.x > 0", INFO, 0.5, 10.0).notes == []
    v, _ = online("always (a.x > 0 implies eventually[0,1] (a.y > 0 or a.x > 0 until[0,0.5] a.y < 0))",
                  {"a.x": np.ones(8), "a.y": np.ones(8)})
    assert (v.verdict, v.window, v.decided_at) == ("holds", (0.0, 3.5 - 1.5), 3.5)


def test_an_unbounded_always_from_a_later_start_over_a_run_that_ended_before_it_is_undecided() -> None:
    """always[2 s, end of run) (a tree the language does not write but the monitor takes): a run of 1.5 s
    judges none of its values: undecided, no robustness, even at its planned stop; a run of 2.5 s holds."""
    import dataclasses

    from wmr_cosim.cosim.requirements.formula import Temporal

    c = check("a.x > 0", INFO, 0.5, 1.5)
    c = dataclasses.replace(c, node=Temporal(1, "always", 2.0, None, c.node.a))   # type: ignore[attr-defined]
    for n, verdict in ((4, "undecided"), (6, "holds")):
        k = [0]
        m = Monitor("r", c, {"a.x": lambda: 1.0 + k[0]}, 0.5)
        for i in range(n):
            k[0] = i
            m.sample(i * 0.5)
        m.finish()   # (the run reached its planned stop)
        v = m.verdict
        assert v.verdict == verdict and v.window == (2.0, None)
        assert (v.robustness, v.decided_at) == ((None, None) if verdict == "undecided" else (5.0, 2.5))
