"""Tabulated inputs (cosim.scenario.inputs) without FMUs: read_inputs on small CSV files with a fake resolver, against
the module's stated contract: the one-line errors naming the scenario, the field and the reason; the type of
each column's values; linear interpolation and hold, at steps, before the first and after the last row."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wmr_cosim.cosim.messages.errors import ScenarioError
from wmr_cosim.cosim.scenario.inputs import read_inputs, sample_hold, sample_linear
from wmr_cosim.cosim.model.description import Variable

WHERE = "scen.toml"


def _var(name: str, type_: str = "Real", variability: str | None = None, fmi_type: str = "") -> Variable:
    if variability is None:
        variability = "continuous" if type_ == "Real" else "discrete"
    return Variable(name=name, vr=1, type=type_, causality="input", variability=variability, unit=None,
                    min=None, max=None, start=None, fmi_type=fmi_type or type_)


def _read(tmp_path: Path, text: str | bytes, variables: dict[str, Variable], grid=(0.0,),
          interpolation: dict[str, str] | None = None):
    file = tmp_path / "in.csv"
    if isinstance(text, bytes):
        file.write_bytes(text)
    else:
        file.write_bytes(text.encode("utf-8"))

    def resolve(col: str):
        return "plant", variables[col]

    return file, read_inputs(file, WHERE, interpolation or {}, resolve, np.asarray(grid, dtype=float))


def _error(tmp_path: Path, text: str | bytes, variables: dict[str, Variable] | None = None,
           interpolation: dict[str, str] | None = None) -> str:
    with pytest.raises(ScenarioError) as info:
        _read(tmp_path, text, variables or {"u": _var("u")}, interpolation=interpolation)
    return str(info.value)


# --- the errors the user sees --------------------------------------------------------------------------

def test_a_missing_file_is_named(tmp_path):
    file = tmp_path / "nowhere.csv"
    with pytest.raises(ScenarioError) as info:
        read_inputs(file, WHERE, {}, lambda c: None, np.zeros(1))
    msg = str(info.value)
    assert msg.startswith(f"{WHERE}: inputs.file: cannot read {file}: ")
    assert "No such file" in msg


def test_a_file_that_is_not_utf8_cannot_be_read(tmp_path):
    msg = _error(tmp_path, b"time,u\n0,\xff\xfe\n")
    assert msg.startswith(f"{WHERE}: inputs.file: cannot read {tmp_path / 'in.csv'}: ")
    assert "utf-8" in msg


def test_a_header_alone_is_refused(tmp_path):
    assert _error(tmp_path, "time,u\n\n") == \
        f"{WHERE}: inputs.file: {tmp_path / 'in.csv'}: needs a header row and at least one row of values"


def test_a_short_row_is_named_by_its_line_number(tmp_path):
    # line 1 is the header; the blank line is skipped and not counted
    assert _error(tmp_path, "time,u\n0,1\n\n5\n") == \
        f"{WHERE}: inputs.file: {tmp_path / 'in.csv'}: line 3 has 1 values for 2 columns"
    assert _error(tmp_path, "time,u\n0,1,2\n") == \
        f"{WHERE}: inputs.file: {tmp_path / 'in.csv'}: line 2 has 3 values for 2 columns"


def test_a_time_that_is_not_a_number_is_refused(tmp_path):
    assert _error(tmp_path, "time,u\nzero,1\n") == \
        (f"{WHERE}: inputs.file: {tmp_path / 'in.csv'}: the time column must hold numbers "
         "(could not convert string to float: 'zero')")
    # a row with an empty time cell is a row (only a wholly blank line is skipped)
    assert "the time column must hold numbers" in _error(tmp_path, "time,u\n0,1\n ,2\n")


@pytest.mark.parametrize("times", ["0,1\n2,1\n1,1", "0,1\nnan,1", "0,1\ninf,1"])
def test_times_must_be_finite_and_not_decreasing(tmp_path, times):
    assert _error(tmp_path, "time,u\n" + times + "\n") == \
        f"{WHERE}: inputs.file: {tmp_path / 'in.csv'}: the times must be finite and not decreasing"


def test_interpolation_of_a_column_that_is_not_there(tmp_path):
    assert _error(tmp_path, "time,u\n0,1\n", interpolation={"v": "hold"}) == \
        f"{WHERE}: inputs.interpolation.v: no column 'v' in {tmp_path / 'in.csv'}"
    # the time column is not an input column
    assert _error(tmp_path, "time,u\n0,1\n", interpolation={"time": "hold"}) == \
        f"{WHERE}: inputs.interpolation.time: no column 'time' in {tmp_path / 'in.csv'}"


def test_an_unknown_interpolation_is_refused(tmp_path):
    assert _error(tmp_path, "time,u\n0,1\n", interpolation={"u": "cubic"}) == \
        f"{WHERE}: inputs.interpolation.u: 'cubic': must be linear or hold"


def test_only_real_inputs_interpolate(tmp_path):
    assert _error(tmp_path, "time,n\n0,1\n", {"n": _var("n", "Integer")}, interpolation={"n": "linear"}) == \
        f"{WHERE}: inputs.interpolation.n: Integer inputs always hold their value"


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_real_values_must_be_finite(tmp_path, value):
    assert _error(tmp_path, f"time,u\n0,1\n1,{value}\n") == f"{WHERE}: inputs.u: values must be finite"


@pytest.mark.parametrize("type_, value", [("Real", "fast"), ("Integer", "1.5"), ("Enumeration", "two"),
                                          ("Boolean", "yes"), ("Boolean", "2")])
def test_a_value_that_is_not_of_the_type_is_named(tmp_path, type_, value):
    assert _error(tmp_path, f"time,x\n0, {value} \n", {"x": _var("x", type_)}) == \
        f"{WHERE}: inputs.x: '{value}' is not a valid {type_}"


@pytest.mark.parametrize("type_, fmi_type, value, lo, hi", [
    ("Integer", "Integer", "2147483648", -2 ** 31, 2 ** 31 - 1),
    ("Enumeration", "Enumeration", "-2147483649", -2 ** 31, 2 ** 31 - 1),
    ("Integer", "UInt8", "256", 0, 255)])
def test_an_integer_out_of_range_is_named(tmp_path, type_, fmi_type, value, lo, hi):
    assert _error(tmp_path, f"time,x\n0,{value}\n", {"x": _var("x", type_, fmi_type=fmi_type)}) == \
        f"{WHERE}: inputs.x: {value} does not fit the {fmi_type} x ({lo}..{hi})"


# --- what is read ------------------------------------------------------------------------------------------

def test_values_keep_their_type(tmp_path):
    variables = {"r": _var("r"), "n": _var("n", "Integer"), "e": _var("e", "Enumeration"),
                 "b": _var("b", "Boolean"), "s": _var("s", "String"), "w": _var("w", "Integer", fmi_type="UInt64")}
    text = ("time,r,n,e,b,s,w\n"
            "0,0.5,-3,2,True,go,18446744073709551615\n"
            "1,1.5,7,3,false,\" stop\",1\n"
            "2,2.5,9,1,1,x,2\n"
            "3,3.5,9,1,0,y,3\n"
            "4,4.5,9,1,TRUE,z,4\n"
            "5,5.5,9,1,FALSE,z,5\n")
    _, plans = _read(tmp_path, text, variables, grid=[0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    by = {p.column: p for p in plans}
    assert [p.column for p in plans] == ["r", "n", "e", "b", "s", "w"]
    assert all(p.instance == "plant" for p in plans)
    assert by["r"].var is variables["r"]
    assert by["r"].values.dtype == np.float64 and by["r"].values.tolist() == [0.5, 1.5, 2.5, 3.5, 4.5, 5.5]
    assert by["n"].values.dtype == np.int64 and by["n"].values.tolist() == [-3, 7, 9, 9, 9, 9]
    assert by["e"].values.dtype == np.int64 and by["e"].values.tolist() == [2, 3, 1, 1, 1, 1]
    assert by["b"].values.dtype == bool and by["b"].values.tolist() == [True, False, True, False, True, False]
    # String: the text as written (not stripped), as Python strings
    assert by["s"].values.dtype == object and by["s"].values.tolist() == ["go", " stop", "x", "y", "z", "z"]
    # UInt64: exact above 2**63 (never through a float or an int64)
    assert by["w"].values.dtype == np.uint64 and int(by["w"].values[0]) == 2 ** 64 - 1
    assert by["r"].mode == "linear"
    assert {p.mode for p in plans if p.column != "r"} == {"hold"}


def test_a_string_keeps_a_line_break_inside_quotes(tmp_path):
    _, (plan,) = _read(tmp_path, b'time,s\r\n0,"a\r\nb"\r\n', {"s": _var("s", "String")})
    assert plan.values.tolist() == ["a\r\nb"]


def test_blank_lines_are_skipped(tmp_path):
    _, (plan,) = _read(tmp_path, "\ntime,u\n\n0,1\n   \n1,3\n\n", {"u": _var("u")}, grid=[0.0, 0.5, 1.0])
    assert plan.values.tolist() == [1.0, 2.0, 3.0]


def test_a_table_of_times_alone_drives_nothing(tmp_path):
    _, plans = _read(tmp_path, "time\n0\n1\n", {})
    assert plans == []


def test_interpolation_can_be_set_per_column(tmp_path):
    variables = {"u": _var("u"), "v": _var("v"), "d": _var("d", variability="discrete")}
    text = "time,u,v,d\n0,0,0,0\n1,10,10,10\n"
    _, plans = _read(tmp_path, text, variables, grid=[0.0, 0.25, 1.0], interpolation={"u": "hold", "d": "linear"})
    by = {p.column: p for p in plans}
    assert (by["u"].mode, by["v"].mode, by["d"].mode) == ("hold", "linear", "linear")
    assert by["u"].values.tolist() == [0.0, 0.0, 10.0]       # held, though continuous
    assert by["v"].values.tolist() == [0.0, 2.5, 10.0]       # linear by default
    assert by["d"].values.tolist() == [0.0, 2.5, 10.0]       # discrete Real, interpolated on request


# --- sampling ----------------------------------------------------------------------------------------------

def test_linear_takes_the_value_after_a_step_even_at_the_last_row():
    t = np.array([0.0, 1.0, 1.0])
    v = np.array([0.0, 5.0, 7.0])
    assert sample_linear(t, v, np.array([-1.0, 0.5, 1.0, 2.0])).tolist() == [0.0, 2.5, 7.0, 7.0]


def test_linear_and_hold_compare_times_with_a_relative_tolerance():
    t = np.array([0.0, 0.3, 0.6])
    v = np.array([0.0, 3.0, 6.0])
    grid = np.array([0.1 + 0.2, 0.6 * (1 - 5e-8), 0.6 * (1 - 5e-10)])   # 0.30000000000000004, ...
    assert sample_hold(t, v, grid).tolist() == [3.0, 3.0, 6.0]
    lin = sample_linear(t, v, grid)
    assert lin[0] == pytest.approx(3.0, rel=1e-12) and lin[1] == pytest.approx(6.0 * (1 - 5e-8), rel=1e-12) and lin[2] == 6.0


def test_two_columns_driving_one_input_are_refused(tmp_path):
    u = _var("u")
    # "u" and "plant.u" name the same input (the resolver maps both), as would a column named twice
    assert _error(tmp_path, "time,u,v,plant.u\n0,1,2,3\n", {"u": u, "v": _var("v"), "plant.u": u}) == \
        f"{WHERE}: inputs.plant.u: {tmp_path / 'in.csv'}: column 'plant.u' drives plant.u, as column 'u' does"
    assert "column 'u' drives plant.u, as column 'u' does" in _error(tmp_path, "time,u,u\n0,1,2\n", {"u": u})
