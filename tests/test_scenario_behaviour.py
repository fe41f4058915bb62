"""The scenario parser's and the resolver's small contracts, one by one: counts, tables of parameters,
values given on the command line, condition variables, array sizes of FMI 3.0 models, the archive limits
of the command line.  Each message is compared in full: it is what the user reads."""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import pytest

from c_fmu_support import build_probe
from reference_fmus import REF
from wmr_cosim.cosim.model import archive
from wmr_cosim.cosim.messages.errors import CosimError, FmuLoadError, ScenarioError
from wmr_cosim.cosim.model.description import load_model
from wmr_cosim.cosim.scenario.document import parse, parse_set, parse_value
from wmr_cosim.cosim.plan.resolution import resolve
from wmr_cosim.exit_codes import for_error

FT = REF / "fmi2" / "Feedthrough.fmu"


def _doc(**extra: object) -> dict:
    doc = {"experiment": {"stop": 0.1, "step": 0.01}, "instances": {"a": {"fmu": str(FT)}}}
    doc.update(extra)
    return doc


def _refused(doc: dict) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        parse(doc, "s.toml")
    return info.value


# ---------------------------------------------------------------------------------- counts
@pytest.mark.parametrize("value", [0, -3, True, 1.5, "2"])
def test_a_count_below_one_or_not_an_integer_is_refused(value):
    err = _refused(_doc(experiment={"stop": 0.1, "step": 0.01, "max_steps": value}))
    assert str(err) == f"s.toml: experiment.max_steps: {value!r}: must be an integer >= 1"
    assert (err.file, err.field) == ("s.toml", "experiment.max_steps")


def test_a_count_of_one_is_accepted():
    sc = parse(_doc(experiment={"stop": 0.1, "step": 0.01, "max_steps": 1}, record={"max_bytes": 1}), "s.toml")
    assert sc.max_steps == 1 and sc.max_bytes == 1


# ---------------------------------------------------------------------------------- parameters of runs
def test_a_run_parameter_of_an_unknown_instance_names_its_field():
    err = _refused(_doc(runs=[{"name": "r", "parameters": {"b.k": 1.0}}]))
    assert str(err) == "s.toml: runs[0].parameters.b.k: unknown instance 'b'"


def test_a_run_parameter_without_an_instance_names_its_field():
    err = _refused(_doc(runs=[{"name": "r", "parameters": {"k": 1.0}}]))
    assert str(err) == "s.toml: runs[0].parameters.k: 'k' is not of the form \"instance.variable\""


def test_run_parameters_that_are_not_a_table_name_their_field():
    err = _refused(_doc(runs=[{"name": "r", "parameters": 3}]))
    assert str(err) == "s.toml: runs[0].parameters: must be a table"


# ---------------------------------------------------------------------------------- --set
def test_set_values_keep_everything_after_the_first_equals_sign():
    assert parse_set(["a.s=x=1", "a.t= true ", "a.u=[1, 2]", "a.v=\"q\""]) == {
        "a.s": "x=1", "a.t": True, "a.u": [1, 2], "a.v": "q"}


@pytest.mark.parametrize("item", ["a.b", "ab", "=1"])
def test_a_malformed_set_names_the_option_and_the_item(item):
    with pytest.raises(ScenarioError) as info:
        parse_set([item], form="I.P=V")
    assert str(info.value) == f"--set: {item}: expected I.P=V"
    assert (info.value.file, info.value.field) == ("--set", item)


@pytest.mark.parametrize("text, value", [("true", True), ("True", True), (" TRUE ", True), ("false", False),
                                         ("False", False), ("fAlSe", False), ("1e3", 1000.0), ("abc", "abc"),
                                         ("\"true\"", "true")])
def test_command_line_values_read_booleans_in_any_case(text, value):
    got = parse_value(text)
    assert got == value and type(got) is type(value)


# ---------------------------------------------------------------------------------- conditions
def _probe_with_dotted_names(tmp: Path) -> Path:
    """The C probe FMU with its local ``c`` renamed ``body.c`` (names with dots, as Modelica tools write)."""
    fmu = build_probe(tmp / "src")
    out = tmp / "Probe.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'name="c"', b'name="body.c"')
            dst.writestr(item, data)
    shutil.rmtree(tmp / "src")
    return out


def test_a_condition_reads_a_variable_whose_name_has_dots(tmp_path):
    fmu = _probe_with_dotted_names(tmp_path)
    sc = parse({"experiment": {"stop": 0.1, "step": 0.01}, "instances": {"p": {"fmu": str(fmu)}},
                "events": [{"when": "p.body.c > 0.5", "action": "stop"}]}, "s.toml")
    plan = resolve(sc)
    (event,) = plan.conditions
    assert event.reads["p.body.c"][0] == "p" and event.reads["p.body.c"][1].name == "body.c"


def test_a_condition_on_an_array_or_on_time_is_refused_in_one_line():
    ss = REF / "fmi3" / "StateSpace.fmu"
    for when, reason in (("s.x > 1", "s.x is an array: a condition reads scalars"),
                         ("s.time > 1", "s.time is the independent variable: use t for the time")):
        sc = parse({"experiment": {"stop": 0.1, "step": 0.01}, "instances": {"s": {"fmu": str(ss)}},
                    "events": [{"when": when, "action": "stop"}]}, "s.toml")
        with pytest.raises(ScenarioError) as info:
            resolve(sc)
        assert str(info.value) == f"s.toml: events[0].when: {reason}"


# ---------------------------------------------------------------------------------- FMI 3.0 array sizes
def _with_description(src: Path, out: Path, edit) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = edit(data.decode()).encode()
            zout.writestr(item, data)
    return out


def test_array_sizes_come_from_fixed_dimensions_and_structural_parameters():
    model = load_model(REF / "fmi3" / "StateSpace.fmu")
    shapes = {name: v.shape for name, v in model.variables.items() if v.shape}
    assert shapes == {"A": (3, 3), "B": (3, 3), "C": (3, 3), "D": (3, 3), "x0": (3,), "u": (3,), "y": (3,),
                      "x": (3,), "der(x)": (3,)}


def test_a_dimension_whose_structural_parameter_has_no_start_is_refused(tmp_path):
    """StateSpace's arrays are sized by the structural parameter n (value reference 2); without its start
    value the size is unknown, and the load refuses the FMU rather than making an empty array."""
    n = 'name="n" valueReference="2" description="Number of states" causality="structuralParameter" ' \
        'variability="tunable" start="3"'

    def edit(xml: str) -> str:
        assert n in xml
        return xml.replace(n, n.replace(' start="3"', ""))

    fmu = _with_description(REF / "fmi3" / "StateSpace.fmu", tmp_path / "StateSpace.fmu", edit)
    with pytest.raises(FmuLoadError) as info:
        load_model(fmu)
    assert str(info.value).startswith(f"{fmu}: cannot read modelDescription.xml (")


# ---------------------------------------------------------------------------------- archive limits
def test_a_callers_limits_win_over_the_scenarios_one_by_one():
    assert archive.limit_overrides() == archive.LimitOverrides()
    over = archive.limit_overrides(max_size="2 KiB")
    assert over == archive.LimitOverrides(max_size=2048)
    assert over.over() == archive.ArchiveLimits(2048, archive.DEFAULT_MAX_RATIO)
    assert archive.limit_overrides(max_ratio=50).over(archive.ArchiveLimits(7, 3)) == archive.ArchiveLimits(7, 50.0)
    table = {"archive_size": "1 MiB", "archive_ratio": 20}
    assert archive.parse_limits("f.toml", table) == archive.ArchiveLimits(1024**2, 20.0)
    assert archive.parse_limits("f.toml", table, over) == archive.ArchiveLimits(2048, 20.0)
    assert archive.parse_limits("f.toml", None) == archive.DEFAULT_LIMITS


@pytest.mark.parametrize("kw, message", [
    ({"max_size": "lots"}, "--max-archive-size: 'lots' is not a size (a number of bytes, or e.g. '4 GiB', "
                           "'500 MB')"),
    ({"max_ratio": 0.5}, "--max-archive-ratio: 0.5: a ratio limit must be a number >= 1"),
])
def test_a_bad_command_line_limit_names_the_option(kw, message):
    with pytest.raises(CosimError) as info:
        archive.limit_overrides(**kw, names=("--max-archive-size", "--max-archive-ratio"))
    assert str(info.value) == message and for_error(info.value) == 2


@pytest.mark.parametrize("n, text", [(0, "0 B"), (1023, "1023 B"), (1023.7, "1023 B"), (1024, "1 KiB"),
                                     (1536, "1.5 KiB"), (5 * 1024**2, "5 MiB"), (2 * 1024**3, "2 GiB"),
                                     (3 * 1024**4, "3 TiB"), (1024**5, "1024 TiB")])
def test_sizes_are_printed_with_binary_units(n, text):
    assert archive.fmt_size(n) == text


# ---------------------------------------------------------------------------------- the resolver's messages
FT3 = REF / "fmi3" / "Feedthrough.fmu"


def _unresolved(doc: dict) -> str:
    with pytest.raises(ScenarioError) as info:
        resolve(parse(doc, "s.toml"))
    return str(info.value)


def test_a_step_no_one_gives_is_named():
    """The Feedthrough FMU's default experiment has a stop time but no step."""
    assert resolve(parse({"experiment": {"step": 0.01}, "instances": {"a": {"fmu": str(FT)}}}, "s.toml")).scenario.stop == 2.0
    assert _unresolved({"experiment": {"stop": 0.1}, "instances": {"a": {"fmu": str(FT)}}}) == \
        "s.toml: experiment.step: not given, and no FMU's default experiment gives one"


def test_a_binary_variable_cannot_be_recorded():
    doc = _doc(instances={"a": {"fmu": str(FT3)}}, record={"variables": ["a.Binary_output"]})
    assert _unresolved(doc) == ("s.toml: record.variables[0]: a.Binary_output is Binary: Binary variables cannot "
                                "be recorded")


def test_a_connection_to_an_unknown_variable_names_its_end():
    doc = _doc(instances={"a": {"fmu": str(FT)}, "b": {"fmu": str(FT)}},
               connections=[{"from": "a.Float64_continuous_output", "to": "b.nope"}])
    assert _unresolved(doc) == "s.toml: connections[0].to: b (Feedthrough.fmu) has no variable 'nope'"


def test_an_input_table_column_of_an_unknown_variable_names_the_file_and_column(tmp_path):
    table = tmp_path / "in.csv"
    table.write_text("time,a.nope\n0,1\n1,2\n")
    assert _unresolved(_doc(inputs={"file": str(table)})) == \
        f"s.toml: inputs.a.nope: a (Feedthrough.fmu) has no variable 'nope' (a column of {table})"


def test_an_event_keeps_the_type_of_its_variable():
    """An Integer set to 3 is set to the integer 3; a Real's bias is a float, and a value that is not a
    number names the variable."""
    plan = resolve(parse(_doc(events=[{"time": 0.05, "variable": "a.Int32_input", "value": 3},
                                      {"time": 0.05, "variable": "a.Int32_input", "action": "bias", "value": 1},
                                      {"time": 0.05, "variable": "a.Float64_continuous_input", "action": "bias",
                                       "value": 2}]), "s.toml"))
    assert [(e.value, type(e.value)) for e in plan.events] == [(3, int), (1, int), (2.0, float)]
    doc = _doc(events=[{"time": 0.05, "variable": "a.Float64_continuous_input", "action": "bias", "value": "x"}])
    assert _unresolved(doc) == "s.toml: events[0].value: type mismatch: Float64_continuous_input is Real, got str 'x'"


@pytest.mark.parametrize("conn, message", [
    ({"from": "s.y[1]", "to": "t.u"}, "s.y[1] -> t.u: an element of a Float64 array goes to a scalar"),
    ({"from": "s.y", "to": "f.Float64_continuous_input"},
     "s.y has 3 values, f.Float64_continuous_input 1: arrays connect whole, of one size (or one element to a scalar)")])
def test_an_array_connection_of_the_wrong_shape_is_named(conn, message):
    ss = REF / "fmi3" / "StateSpace.fmu"
    doc = _doc(instances={"s": {"fmu": str(ss)}, "t": {"fmu": str(ss)}, "f": {"fmu": str(FT3)}}, connections=[conn])
    assert _unresolved(doc) == f"s.toml: connections[0]: {message}"


@pytest.mark.parametrize("error, reason", [(PermissionError(13, "Permission denied"), "Permission denied"),
                                           (OSError("the disk went away"), "the disk went away")])
def test_a_scenario_file_that_cannot_be_read_is_named(tmp_path, monkeypatch, error, reason):
    from wmr_cosim import cosim

    path = tmp_path / "s.toml"
    path.write_text("[experiment]\nstop = 1\n")

    def refuse(self, *a, **k):
        raise error
    monkeypatch.setattr(Path, "open", refuse)
    with pytest.raises(ScenarioError) as info:
        cosim.load(path)
    assert str(info.value) == f"{path}: cannot be read ({reason})"


# ---------------------------------------------------------------------------------- the parser's fields
@pytest.mark.parametrize("extra, message", [
    ({"events": [3]}, "events[0]: must be a table"),
    ({"events": [{"time": 0.1, "value": 1}]}, "events[0].variable: missing"),
    ({"instances": 3}, "instances: must be a table"),
    ({"limits": 3}, "limits: must be a table (archive_size, archive_ratio)"),
    ({"instances": {"a": {"fmu": str(FT), "isolate": "yes"}}}, "instances.a.isolate: 'yes': must be true or false"),
    ({"record": {"variables": ["a.y"], "colour": 1}},
     "record.colour: unknown key (allowed: csv, decimation, event_rows, mat, max_bytes, variables)")])
def test_a_malformed_table_is_named_by_its_field(extra, message):
    assert str(_refused(_doc(**extra))) == f"s.toml: {message}"


def test_the_interpolation_of_input_columns_is_linear_or_hold(tmp_path):
    table = tmp_path / "in.csv"
    table.write_text("time,a.u\n0,1\n")
    sc = parse(_doc(inputs={"file": str(table), "interpolation": {"a.u": "linear", "a.v": "hold"}}), "s.toml")
    assert sc.interpolation == {"a.u": "linear", "a.v": "hold"}
    assert str(_refused(_doc(inputs={"file": str(table), "interpolation": 3}))) == \
        "s.toml: inputs.interpolation: must be a table"
    assert str(_refused(_doc(inputs={"file": str(table), "interpolation": {"a.u": "Linear"}}))) == \
        "s.toml: inputs.interpolation.a.u: 'Linear': must be linear or hold"


def test_a_value_given_on_the_command_line_names_its_option():
    from wmr_cosim.cosim.scenario.document import apply_overrides

    two = _doc(instances={"a": {"fmu": str(FT)}, "b": {"fmu": str(FT)}})
    with pytest.raises(ScenarioError) as info:
        apply_overrides(two, {"nodot": 1}, "s.toml")
    assert str(info.value) == 's.toml: --set nodot: \'nodot\' is not of the form "instance.variable"'
    # with one instance, a name alone is that instance's variable
    assert apply_overrides(_doc(), {"nodot": 1}, "s.toml")["instances"]["a"]["parameters"] == {"nodot": 1}


@pytest.mark.parametrize("key, kind, hint", [
    ("tasks", "a paper manifest", "run it with `wmr-cosim paper --manifest FILE`"),
    ("grid", "a sweep file", "run it with `wmr-cosim sweep FILE`")])
def test_another_kind_of_file_is_named_by_the_master_and_the_command_line_says_how_to_run_it(
        tmp_path, capsys, key, kind, hint):
    """The master names what the file is and no command; the command line adds the command that takes it."""
    from wmr_cosim.cli import main
    from wmr_cosim.cosim.messages.errors import OtherFileError
    from wmr_cosim.cosim.scenario.document import load

    path = tmp_path / "other.toml"
    path.write_text(f"[{key}]\n")
    with pytest.raises(OtherFileError) as info:
        load(path)
    assert str(info.value) == f"{path}: not a scenario but {kind}" and info.value.kind == kind
    assert main(["check", str(path)]) == 2
    assert capsys.readouterr().err == f"wmr-cosim: error: {path}: not a scenario but {kind}: {hint}\n"
