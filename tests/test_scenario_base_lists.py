"""What a file takes from its ``base``: tables merge key by key; the lists of tables (connections,
requirements, runs, events) extend the base's, an entry with the key of one of the base's (a connection's
``to``, a requirement's or run's ``name``) replacing it in place; ``replace = [...]`` gives a list whole;
other arrays (record.variables) are values and replace.  ``check`` says what each file takes from its base
and which inputs nothing drives, so that a dropped connection is never silent."""
from __future__ import annotations

import numpy as np
import pytest

from reference_fmus import REF
from wmr_cosim import cosim, scenario_files
from wmr_cosim.cli import main
from wmr_cosim.cosim.messages.errors import ScenarioError

FT, DQ = REF / "fmi2" / "Feedthrough.fmu", REF / "fmi2" / "Dahlquist.fmu"
SHIPPED = scenario_files.folder()

#: Dahlquist (x' = -k x, x(0) = 1, k = 1; forward Euler at 0.1 s) into a chain of two Feedthroughs (a, then
#: b), 10 steps of 0.1 s,
#: a requirement, two runs, an event; what the tests' files are based on.
BASE = f"""
[experiment]
stop = 1.0
step = 0.1
order = ["d", "a", "b"]
[instances.d]
fmu = "{DQ}"
[instances.a]
fmu = "{FT}"
[instances.b]
fmu = "{FT}"
[[connections]]
from = "d.x"
to = "a.Float64_continuous_input"
[[connections]]
from = "a.Float64_continuous_output"
to = "b.Float64_continuous_input"
[record]
variables = ["d.x", "a.Float64_continuous_output", "b.Float64_continuous_output"]
[[requirements]]
name = "small"
formula = "always abs(d.x) <= 1"
[[runs]]
name = "first"
[[runs]]
name = "second"
parameters = {{ "d.k" = 2.0 }}
[[events]]
time = 0.5
variable = "a.Float64_discrete_input"
action = "override"
value = 1.0
"""


@pytest.fixture
def base(tmp_path):
    path = tmp_path / "base.toml"
    path.write_text(BASE)
    return path


def _file(tmp_path, text: str, name: str = "mine.toml"):
    path = tmp_path / name
    path.write_text('base = "base.toml"\n' + text)
    return path


def _load(path):
    return cosim.load(path, shipped=SHIPPED)


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_one_more_connection_keeps_the_base_ones(base, tmp_path):
    sc = _load(_file(tmp_path, '[[connections]]\nfrom = "a.Int32_output"\nto = "b.Int32_input"\n'))
    assert [(c.src, c.dst) for c in sc.connections] == [
        ("d.x", "a.Float64_continuous_input"), ("a.Float64_continuous_output", "b.Float64_continuous_input"),
        ("a.Int32_output", "b.Int32_input")]
    assert [c.index for c in sc.connections] == [0, 1, 2]


def test_a_connection_to_an_input_of_the_base_replaces_that_one_in_place(base, tmp_path, monkeypatch, capsys):
    """b's input from d directly, doubled: the chain's other link stays, and b's output is 2 x at every point
    (Gauss-Seidel: d, a, b), x_n = (1 - 0.1 k)^n."""
    path = _file(tmp_path, '[[connections]]\nfrom = "d.x"\nto = "b.Float64_continuous_input"\nfactor = 2.0\n')
    sc = _load(path)
    assert [(c.src, c.dst, c.factor) for c in sc.connections] == [
        ("d.x", "a.Float64_continuous_input", 1.0), ("d.x", "b.Float64_continuous_input", 2.0)]
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(path), "--out", "o", "--quiet"]) == 0, capsys.readouterr().err
    for run, k in (("first", 1.0), ("second", 2.0)):
        d = np.load(tmp_path / "o" / run / "signals.npy")
        assert np.allclose(d["d.x"], (1 - 0.1 * k) ** np.arange(11), rtol=1e-12, atol=0)
        assert np.array_equal(d["b.Float64_continuous_output"], 2 * d["d.x"])
        assert np.array_equal(d["a.Float64_continuous_output"], d["d.x"])


def test_requirements_runs_and_events_extend_the_base_ones(base, tmp_path):
    sc = _load(_file(tmp_path, '[[requirements]]\nname = "positive"\nformula = "always d.x > 0"\n'
                               '[[runs]]\nname = "third"\nparameters = { "d.k" = 3.0 }\n'
                               '[[events]]\ntime = 0.7\nvariable = "a.Float64_discrete_input"\naction = "reset"\n'))
    assert [r.name for r in sc.requirements] == ["small", "positive"]
    assert [r.name for r in sc.runs] == ["first", "second", "third"]
    assert [(e.time, e.action) for e in sc.events] == [(0.5, "override"), (0.7, "reset")]


def test_a_requirement_or_a_run_of_a_base_name_replaces_that_one_in_place(base, tmp_path):
    sc = _load(_file(tmp_path, '[[requirements]]\nname = "small"\nformula = "always abs(d.x) <= 0.5"\n'
                               '[[runs]]\nname = "first"\nparameters = { "d.k" = 5.0 }\n'))
    assert [(r.name, r.formula) for r in sc.requirements] == [("small", "always abs(d.x) <= 0.5")]
    assert [(r.name, r.parameters) for r in sc.runs] == [("first", {"d.k": 5.0}), ("second", {"d.k": 2.0})]


def test_a_name_given_twice_by_the_file_is_still_refused(base, tmp_path):
    path = _file(tmp_path, '[[runs]]\nname = "first"\n[[runs]]\nname = "first"\n')
    with pytest.raises(ScenarioError, match="'first': two runs with this name"):
        _load(path)


def test_replace_gives_the_named_lists_whole(base, tmp_path):
    sc = _load(_file(tmp_path, 'replace = ["connections", "runs", "events"]\n'
                               '[[connections]]\nfrom = "d.x"\nto = "b.Float64_continuous_input"\n'))
    assert [(c.src, c.dst) for c in sc.connections] == [("d.x", "b.Float64_continuous_input")]
    assert sc.runs == [] and sc.events == []
    assert [r.name for r in sc.requirements] == ["small"]              # (not named: extended)
    sc = _load(_file(tmp_path, 'replace = ["requirements"]\n'))
    assert sc.requirements == [] and len(sc.connections) == 2


def test_a_plain_array_still_replaces_and_tables_still_merge(base, tmp_path):
    sc = _load(_file(tmp_path, '[record]\nvariables = ["d.x"]\n[experiment]\nstop = 0.5\n'))
    assert sc.record == ["d.x"] and (sc.stop, sc.step) == (0.5, 0.1)


def test_a_chain_of_bases_extends_at_each_file(base, tmp_path, capsys):
    middle = _file(tmp_path, '[[connections]]\nfrom = "a.Int32_output"\nto = "b.Int32_input"\n', "middle.toml")
    top = tmp_path / "top.toml"
    top.write_text('base = "middle.toml"\nreplace = ["events"]\n'
                   '[[connections]]\nfrom = "a.Boolean_output"\nto = "b.Boolean_input"\n')
    sc = _load(top)
    assert [c.dst for c in sc.connections] == ["a.Float64_continuous_input", "b.Float64_continuous_input",
                                               "b.Int32_input", "b.Boolean_input"]
    assert sc.events == [] and [r.name for r in sc.runs] == ["first", "second"]
    assert main(["check", str(top)]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out.splitlines()
    assert out[1:3] == ["  base middle.toml: 3 connections, 1 requirement, 2 runs inherited; this file adds 1 "
                        "connection, drops the base's 1 event (replace)",
                        f"  base base.toml (of {middle}): 2 connections, 1 requirement, 2 runs, 1 event inherited; "
                        f"{middle} adds 1 connection"]


@pytest.mark.parametrize("text, reason", [
    ('replace = ["connection"]', "'connection' is not a list a base gives: allowed: connections, requirements, "
                                 "runs, events (did you mean 'connections'?)"),
    ('replace = "runs"', 'must be an array of the lists this file gives whole (replace = ["runs"]'),
    ("replace = [1]", "[1]: must be an array of the lists this file gives whole"),
    ("replace = true", "True: must be an array"),
    ('replace = ["record"]', "'record' is not a list of tables"),
    ('replace = ["record.variables"]', "'record.variables' is not a list of tables"),
])
def test_a_bad_replace_is_refused_in_one_line(base, tmp_path, capsys, text, reason):
    path = _file(tmp_path, text + "\n")
    with pytest.raises(ScenarioError) as exc:
        _load(path)
    assert exc.value.field == "replace" and reason in exc.value.reason, exc.value.reason
    assert main(["check", str(path)]) == 2
    err = _err(capsys)
    assert "mine.toml: replace: " in err and reason in err


def test_replace_without_a_base_is_refused(tmp_path, capsys):
    path = tmp_path / "alone.toml"
    path.write_text('replace = ["runs"]\n' + BASE)
    assert main(["check", str(path)]) == 2
    assert "alone.toml: replace: this file has no base" in _err(capsys)


def test_an_empty_array_is_refused_since_it_would_add_nothing(base, tmp_path, capsys):
    path = _file(tmp_path, "requirements = []\n")
    assert main(["check", str(path)]) == 2
    assert ("mine.toml: requirements: an empty array adds nothing to the base's 1 requirement (a base's lists are "
            'extended): to drop them, write replace = ["requirements"]') in _err(capsys)


def test_check_says_what_a_file_takes_from_its_base(base, tmp_path, capsys):
    path = _file(tmp_path, '[[connections]]\nfrom = "d.x"\nto = "b.Float64_continuous_input"\n'
                           '[[connections]]\nfrom = "a.Int32_output"\nto = "b.Int32_input"\n'
                           '[record]\nvariables = ["d.x"]\n')
    assert main(["check", str(path)]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"{path}: ok: 3 instances (d, a, b), 3 connections")
    assert out[1] == ("  base base.toml: 1 connection, 1 requirement, 2 runs, 1 event inherited; this file adds 1 "
                      "connection, replaces the connection to b.Float64_continuous_input, replaces record.variables")


def test_check_names_the_inputs_nothing_drives_with_their_start_values(base, tmp_path, capsys):
    path = _file(tmp_path, 'replace = ["connections"]\n[instances.a.parameters]\nFloat64_discrete_input = 4.5\n')
    assert main(["check", str(path)]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert ("  base base.toml: 1 requirement, 2 runs, 1 event inherited; this file drops the base's 2 connections "
            "(replace)\n") in out
    line = next(x for x in out.splitlines() if "not connected" in x)
    assert line.startswith("  12 inputs not connected (nor in an input table), held at their start values: "
                           "a.Float64_continuous_input = 0, a.Float64_discrete_input = 4.5 (and events[0]), a.Int32_input = 0, "
                           "a.Boolean_input = false, a.String_input = 'Set me!', a.Enumeration_input = 1, "
                           "b.Float64_continuous_input = 0, "), line


def test_g1_plus_one_connection_keeps_g1s_eleven(tmp_path, capsys):
    """The shipped G1 (11 connections; the disturbance torques tau_d1, tau_d2 left at 0) with one more
    connection: 12, and only tau_d2 left."""
    path = tmp_path / "g1_more.toml"
    path.write_text('base = "g1_learn.toml"\n[[connections]]\nfrom = "controller.u1"\nto = "plant.tau_d1"\n'
                    'factor = 0.1\n')
    assert main(["check", str(path)]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out.splitlines()
    assert "11 connections" not in out[0] and ", 12 connections, " in out[0], out[0]
    assert out[1] == "  base g1_learn.toml: 11 connections inherited; this file adds 1 connection"
    assert "  1 input not connected (nor in an input table), held at its start value: plant.tau_d2 = 0" in out
