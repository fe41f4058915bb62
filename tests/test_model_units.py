"""Units of FMI variables (cosim/model/units.py): the conversions between convertible units agree with the physical
definitions of the units, incompatible or unknown units are refused with one line naming both, and the
units an FMU defines (UnitDefinitions, FMI 2.0 section 2.2.2) take precedence over the common ones."""
from __future__ import annotations

import math

import pytest
from fmpy import read_model_description

from reference_fmus import REF
from wmr_cosim.cosim.messages.errors import CosimError
from wmr_cosim.cosim.model.units import KNOWN, Unit, conversion, lookup, unit, units_of


def _convert(src: str, dst: str, x: float, defined: dict[str, Unit] | None = None) -> float:
    f, o = conversion(lookup(src, defined or {}), lookup(dst, defined or {}))
    return f * x + o


@pytest.mark.parametrize("src, dst, x, expected", [
    ("km/h", "m/s", 36.0, 10.0), ("m/s", "km/h", 10.0, 36.0), ("mm/s", "m/s", 250.0, 0.25),
    ("rpm", "rad/s", 60.0, 2 * math.pi), ("deg/s", "rad/s", 180.0, math.pi), ("rev", "deg", 1.0, 360.0),
    ("deg/s2", "rad/s^2", 90.0, math.pi / 2), ("rad/s2", "rad/s^2", 3.0, 3.0),
    ("h", "s", 1.0, 3600.0), ("min", "ms", 1.0, 60000.0), ("Hz", "1/s", 50.0, 50.0),
    ("mm", "km", 1e6, 1.0), ("cm", "m", 250.0, 2.5), ("g", "kg", 1500.0, 1.5),
    ("mN.m", "N.m", 1500.0, 1.5), ("Nm", "N*m", 2.0, 2.0), ("kg.m2", "kg.m^2", 0.5, 0.5),
    ("degC", "K", 0.0, 273.15), ("K", "degC", 373.15, 100.0), ("1", "-", 0.3, 0.3),
])
def test_common_units_convert_by_their_definitions(src, dst, x, expected):
    assert _convert(src, dst, x) == pytest.approx(expected, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("src, dst", [("N", "N.m"), ("N.m", "W"), ("W", "V"), ("V", "A"), ("A", "K"),
                                      ("N.m.s/rad", "N.m"), ("s/rad", "s"), ("rad", "1"), ("kg", "g.m"),
                                      ("m/s2", "rad/s2")])
def test_units_of_other_dimensions_are_refused(src, dst):
    if dst == "g.m":   # not a common unit: unknown base
        with pytest.raises(CosimError, match=r"^unit 'kg' is not convertible to 'g.m' \(unknown unit\)$"):
            conversion(lookup(src, {}), lookup(dst, {}))
        return
    with pytest.raises(CosimError) as exc:
        conversion(lookup(src, {}), lookup(dst, {}))
    assert str(exc.value) == f"unit '{src}' is incompatible with '{dst}'"


def test_unknown_units_match_only_themselves():
    assert conversion(lookup("furlong", {}), lookup("furlong", {})) == (1.0, 0.0)
    with pytest.raises(CosimError, match=r"^unit 'furlong' is not convertible to 'm' \(unknown unit\)$"):
        conversion(lookup("furlong", {}), lookup("m", {}))
    with pytest.raises(CosimError, match=r"^unit 'm' is not convertible to 'furlong' \(unknown unit\)$"):
        conversion(lookup("m", {}), lookup("furlong", {}))


def test_no_unit_is_compatible_with_anything():
    assert lookup(None, {}) is None and lookup("", {}) is None
    assert conversion(None, KNOWN["degC"]) == (1.0, 0.0)
    assert conversion(KNOWN["degC"], None) == (1.0, 0.0)
    assert conversion(None, None) == (1.0, 0.0)


def test_unit_takes_exponents_by_base_name():
    assert unit("N", kg=1, m=1, s=-2) == Unit("N", (1, 1, -2, 0, 0, 0, 0, 0), 1.0, 0.0)
    assert unit("x", 2.0, 3.0, rad=1, cd=2, mol=3, K=4, A=5) == Unit("x", (0, 0, 0, 5, 4, 3, 2, 1), 2.0, 3.0)
    assert unit("1") == Unit("1", (0,) * 8, 1.0, 0.0)


def test_an_fmus_own_definition_wins_over_the_common_table(tmp_path):
    # an FMU whose "deg" means something else than the common degree (a deliberately odd definition)
    odd = {"deg": unit("deg", 0.5, rad=1)}
    assert _convert("deg", "rad", 2.0, odd) == 1.0
    assert _convert("deg", "rad", 180.0) == pytest.approx(math.pi)


_MD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="u" guid="{{u}}">
  <CoSimulation modelIdentifier="u"/>
  <UnitDefinitions>
    <Unit name="furlong"/>
    <Unit name="degF"><BaseUnit K="1" factor="{f}" offset="{o}"/></Unit>
    <Unit name="N.m"><BaseUnit kg="1" m="2" s="-2"/></Unit>
    <Unit name="mol/cd/A"><BaseUnit mol="1" cd="-1" A="-1" rad="2"/></Unit>
    <Unit name="deg"/>
  </UnitDefinitions>
  <ModelVariables>
    <ScalarVariable name="T" valueReference="0" causality="output"><Real unit="degF"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1"/></Outputs></ModelStructure>
</fmiModelDescription>
"""


def test_units_of_reads_the_unit_definitions(tmp_path):
    xml = tmp_path / "modelDescription.xml"
    xml.write_text(_MD.format(f=5 / 9, o=273.15 - 32 * 5 / 9), encoding="utf-8")
    defined = units_of(read_model_description(str(xml), validate=False))
    # a unit without BaseUnit: the common one of that name, else left out (unknown, compared by name only)
    assert sorted(defined) == ["N.m", "deg", "degF", "mol/cd/A"]
    assert defined["deg"] == KNOWN["deg"]
    assert defined["mol/cd/A"] == Unit("mol/cd/A", (0, 0, 0, -1, 0, 1, -1, 2), 1.0, 0.0)
    assert defined["N.m"] == KNOWN["N.m"]
    assert _convert("degF", "degC", 212.0, defined) == pytest.approx(100.0, abs=1e-9)
    assert _convert("degF", "K", 32.0, defined) == pytest.approx(273.15, abs=1e-9)
    assert _convert("K", "degF", 373.15, defined) == pytest.approx(212.0, abs=1e-9)
    assert _convert("degC", "degF", -40.0, defined) == pytest.approx(-40.0, abs=1e-9)
    assert lookup("furlong", defined) == Unit("furlong", (), 1.0, 0.0)


def test_units_of_a_real_fmu_and_of_one_without_definitions():
    md = read_model_description(str(REF / "fmi2" / "BouncingBall.fmu"), validate=False)
    defined = units_of(md)
    assert sorted(defined) == ["m", "m/s", "m/s2"]
    assert defined["m/s2"].exps == KNOWN["m/s2"].exps and defined["m/s2"].factor == 1.0
    md.unitDefinitions = []
    assert units_of(md) == {}


@pytest.mark.parametrize("fmi_type, value, reason", [
    ("Int8", 128, "value 128 does not fit the Int8 range -128..127"),
    ("UInt16", -1, "value -1 does not fit the UInt16 range 0..65535"),
    ("", 2 ** 31, "value 2147483648 does not fit the Integer range -2147483648..2147483647"),
    ("Int64", 2 ** 40, None)])
def test_an_integer_out_of_the_range_of_its_fmi_type_is_named(fmi_type, value, reason):
    """The range is the declared FMI type's (an FMI 3.0 Int8 is an Integer of 8 bits); a variable without
    one (FMI 2.0, or made by hand) has its type's."""
    from wmr_cosim.cosim.model.description import Variable

    v = Variable("n", 1, "Integer", "parameter", "tunable", None, None, None, 0, fmi_type=fmi_type)
    assert v.fmi_type == (fmi_type or "Integer")
    assert v.check_range(value) == reason


@pytest.mark.parametrize("text, kind, value", [
    ("3", "Integer", 3), ("2", "Enumeration", 2), ("1.5", "Real", 1.5), ("x", "Real", None), ("x", "Integer", None),
    ("true", "Boolean", True), ("1", "Boolean", True), ("false", "Boolean", False), ("0", "Boolean", False),
    ("abc", "String", "abc")])
def test_a_start_value_is_read_as_its_type(text, kind, value):
    from wmr_cosim.cosim.model.description import _scalar

    got = _scalar(text, kind)
    assert got == value and type(got) is type(value)


@pytest.mark.parametrize("causality, variability, initial, start, want", [
    ("parameter", "fixed", None, "1", "exact"), ("local", "constant", None, "1", "exact"),
    ("calculatedParameter", "fixed", None, None, "calculated"), ("output", "continuous", None, None, "calculated"),
    ("output", "continuous", None, "0", "exact"), ("local", "continuous", None, None, "calculated"),
    ("local", "discrete", None, "2", "exact"), ("input", "continuous", None, "0", None),
    ("independent", "continuous", None, None, None), ("output", "continuous", "approx", "0", "approx")])
def test_the_default_initial_of_fmi2_follows_causality_and_variability(causality, variability, initial, start, want):
    """FMI 2.0 (2.2.7): an explicit initial stands; else parameters and constants are exact, calculated
    parameters calculated, outputs and locals exact with a start value and calculated without."""
    from types import SimpleNamespace

    from wmr_cosim.cosim.model.description import _initial

    v = SimpleNamespace(causality=causality, variability=variability, initial=initial, start=start)
    assert _initial(v) == want
