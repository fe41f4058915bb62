"""The parameter checks of components/params.py, each made afresh here: its kind, the range an FMU
declares for it, and the values it accepts and refuses with one line naming the owner, the parameter and
the value."""
from __future__ import annotations

import pytest

from wmr_cosim.components import params as P
from wmr_cosim.components.validation import ParameterError


def refused(check: P.Check, value, message: str) -> None:
    with pytest.raises(ParameterError) as e:
        check.apply("plant", "q", value)
    assert str(e.value) == f"plant parameter {message}"


def test_half_open_interval():
    c = P.half_open(0.0, 1.0, "s")
    assert (c.kind, c.bounds, c.hi_open, c.values) == ("half_open", (0.0, 1.0), True, ())
    assert c.apply("plant", "q", 0.0) == 0.0 and c.apply("plant", "q", 0.999) == 0.999
    refused(c, 1.0, "q = 1.0: must be in [0, 1) s")
    refused(c, -0.1, "q = -0.1: must be in [0, 1) s")
    refused(c, "x", "q = 'x': not a real number")
    refused(P.half_open(0.5, 2.0), 2.0, "q = 2.0: must be in [0.5, 2)")


def test_one_of_a_few_integers():
    c = P.one_of_int(1, 2)
    assert (c.kind, c.bounds, c.hi_open, c.values) == ("one_of_int", (1, 2), False, (1, 2))
    assert c.apply("plant", "q", 2.0) == 2 and type(c.apply("plant", "q", 2.0)) is int
    assert c.apply("plant", "q", 1) == 1
    refused(c, 3, "q = 3: must be 1 or 2")
    refused(c, 1.5, "q = 1.5: must be 1 or 2")
    assert P.one_of_int(2, 4, 8).bounds == (2, 8)
    refused(P.one_of_int(2, 4, 8), 3, "q = 3: must be 2 or 4 or 8")


def test_integer_in_a_range():
    c = P.integer(0, 5, "in 0..5")
    assert (c.kind, c.bounds, c.hi_open) == ("integer", (0, 5), False)
    assert c.apply("plant", "q", 0) == 0 and c.apply("plant", "q", 5.0) == 5
    for bad in (6, -1, 2.5):
        refused(c, bad, f"q = {bad!r}: must be in 0..5")


def test_positive_integer_with_and_without_a_maximum():
    c = P.positive_int(10)
    assert (c.kind, c.bounds) == ("positive_int", (1, 10))
    assert c.apply("plant", "q", 1) == 1 and c.apply("plant", "q", 10) == 10
    refused(c, 11, "q = 11: must be an integer <= 10")
    refused(c, 0, "q = 0: must be an integer >= 1")
    d = P.positive_int()
    assert d.bounds == (1, 2**31 - 1) and d.apply("plant", "q", 2**31 - 1) == 2**31 - 1
    refused(d, 2**31, f"q = {2**31}: must be an integer <= {2**31 - 1}")


def test_choice_of_names():
    c = P.choice("tanh", "printed")
    assert (c.kind, c.bounds, c.values) == ("choice", (None, None), ("tanh", "printed"))
    assert c.apply("plant", "q", "printed") == "printed"
    refused(c, "exp", "q = 'exp': must be one of tanh, printed")


def test_vector_of_checked_values():
    c = P.vector(2, P.positive, "x, y")
    assert (c.kind, c.bounds) == ("vector_positive", P.positive.bounds)
    assert c.apply("plant", "q", [1, 2]) == (1.0, 2.0)
    refused(c, (1.0,), "q = (1.0,): needs 2 values (x, y)")
    refused(c, 5, "q = 5: needs 2 values (x, y)")
    refused(c, (1.0, -1.0), "q[1] = -1.0: must be > 0")
    refused(c, (-1.0, 1.0), "q[0] = -1.0: must be > 0")
    refused(P.vector(3, P.finite), (1.0,), "q = (1.0,): needs 3 values")
    refused(P.vector(1, P.finite), 2.0, "q = 2.0: needs 1 values")      # not a sequence at all
    assert P.vector(1, P.finite).apply("plant", "q", [2]) == (2.0,)


def test_sign_and_the_named_ranges():
    assert (P.sign.bounds, P.sign.values) == ((-1.0, 1.0), (1.0, -1.0))
    assert P.sign.apply("plant", "q", -1) == -1.0
    refused(P.sign, 0, "q = 0: must be +1 or -1")
    assert P.positive.bounds == (P.DBL_MIN, P.DBL_MAX) and P.non_negative.bounds == (0.0, P.DBL_MAX)
    assert P.finite.bounds == (-P.DBL_MAX, P.DBL_MAX) and P.finite_or_inf.bounds == (-P.DBL_MAX, None)


def test_param_carries_its_facts_into_the_field():
    f = P.param(0.5, check=P.non_negative, doc="a time", unit="s", tunable=True)
    assert f.default == 0.5
    assert dict(f.metadata) == {"check": P.non_negative, "doc": "a time", "unit": "s", "tunable": True}
    g = P.param(False, check=P.boolean, doc="a flag")
    assert g.metadata["unit"] is None and g.metadata["tunable"] is False


def test_facts_of_a_class_and_of_an_instance():
    from wmr_cosim.components.plant import PlantParams

    f = P.facts(PlantParams)
    assert f["cF"] == {"check": P.positive, "doc": "slope cF of friction (36)", "unit": "s/rad", "tunable": False}
    assert f["foam_da1"]["tunable"] is True and list(f)[:3] == ["a1", "a2", "a3"]
    assert P.facts(PlantParams(a5=1.0)) == f
