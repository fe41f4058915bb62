"""Protocols (several runs in one scenario file): which runs run, in which order, into which folders, with
which parameters (variants, carried values, overrides), and the exact one-line errors of a bad protocol.
The FMU is the Reference FMUs' Dahlquist (dx/dt = -k x, x(0) = 1)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from cosim_support import write_scenario
from reference_fmus import REF as _REF
from wmr_cosim.cosim.messages.errors import RunError, ScenarioError
from wmr_cosim.cosim.runtime.protocol import check_protocol, plan_runs, run_protocol
from wmr_cosim.exit_codes import RUN_FAILED, for_error

DAHLQUIST = _REF / "fmi2" / "Dahlquist.fmu"


def _protocol(tmp: Path, runs: str = "", extra: str = "", isolate: bool = False, name: str = "protocol") -> Path:
    return write_scenario(tmp / f"{name}.toml", f'''
[experiment]
stop = 0.1
step = 0.05
{extra}
[instances.d]
fmu = "{DAHLQUIST}"
isolate = {"true" if isolate else "false"}
[record]
variables = ["d.x", "d.k"]
{runs}''')


RUNS = '''
[variants.slow]
parameters = { "d.k" = 0.5 }
[variants.fast]
parameters = { "d.k" = 4.0 }
[[runs]]
name = "a"
parameters = { "d.k" = 2.0 }
[[runs]]
name = "b"
carry = { "d.k" = "a.d.x" }
[[runs]]
name = "c"
'''


def test_a_file_without_runs_is_one_run_named_run(tmp_path):
    path = _protocol(tmp_path)
    _, runs, vparams = plan_runs(path)
    assert [r.name for r in runs] == ["run"] and vparams == {}
    results = run_protocol(path, tmp_path / "out", progress=False)
    assert list(results) == ["run"] and results["run"].status == "ok"
    assert (tmp_path / "out" / "run" / "signals.npy").is_file()


def test_an_unknown_variant_names_the_file_and_the_declared_ones(tmp_path):
    path = _protocol(tmp_path, RUNS)
    with pytest.raises(ScenarioError) as exc:
        plan_runs(path, None, "nope")
    assert str(exc.value) == f"{path}: --variant nope: not declared by this file (declared: slow, fast)"
    bare = _protocol(tmp_path, name="bare")
    with pytest.raises(ScenarioError) as exc:
        plan_runs(bare, None, "nope")
    assert str(exc.value) == f"{bare}: --variant nope: not declared by this file (declared: none)"
    assert plan_runs(path, None, "fast")[2] == {"d.k": 4.0}


def test_runs_in_order_with_variant_carry_and_overrides(tmp_path):
    """The variant sets every run's parameters, a run's own parameters win over it, a carried value is the
    source run's final recorded value, and overrides win over all; each run in its own folder."""
    path = _protocol(tmp_path, RUNS)
    seen: list[tuple[str, str]] = []
    results = run_protocol(path, tmp_path / "out", variant="slow", progress=False,
                           on_run=lambda name, res: seen.append((name, res.status)))
    assert list(results) == ["a", "b", "c"]
    assert seen == [("a", "ok"), ("b", "ok"), ("c", "ok")]
    k = {n: results[n].final["d.k"] for n in results}
    assert k["a"] == 2.0 and k["c"] == 0.5                    # the run's own value; the variant's
    assert k["b"] == results["a"].final["d.x"] and 0.5 < k["b"] < 1.0   # carried from run a
    for n in "abc":
        d = np.load(tmp_path / "out" / n / "signals.npy")
        assert d["d.k"][-1] == k[n] and d["d.x"][-1] == results[n].final["d.x"]
    over = run_protocol(path, tmp_path / "over", variant="slow", overrides={"d.k": 3.0}, progress=False)
    assert {n: r.final["d.k"] for n, r in over.items()} == {"a": 3.0, "b": 3.0, "c": 3.0}


def test_on_run_gets_each_runs_name_and_result(tmp_path):
    path = _protocol(tmp_path, RUNS)
    seen: dict[str, object] = {}
    results = run_protocol(path, tmp_path / "out", progress=False, on_run=seen.__setitem__)
    assert seen == results and all(r.out_dir == tmp_path / "out" / n for n, r in seen.items())


def test_only_runs_the_named_runs(tmp_path):
    path = _protocol(tmp_path, RUNS)
    results = run_protocol(path, tmp_path / "out", progress=False, only=["c"])
    assert list(results) == ["c"] and not (tmp_path / "out" / "a").exists()
    results = run_protocol(path, tmp_path / "out2", progress=False, only=["a", "c"])
    assert list(results) == ["a", "c"] and not (tmp_path / "out2" / "b").exists()


def test_a_carry_from_a_run_that_was_left_out(tmp_path):
    path = _protocol(tmp_path, RUNS)
    with pytest.raises(ScenarioError) as exc:
        run_protocol(path, tmp_path / "out", progress=False, only=["b"])
    assert str(exc.value) == f"{path}: runs.b.carry.d.k: run 'a' has not been run"
    assert exc.value.file == str(path) and exc.value.field == "runs.b.carry.d.k"


def test_a_carry_of_a_value_that_was_not_recorded(tmp_path):
    path = _protocol(tmp_path, RUNS.replace('"a.d.x"', '"a.d.der(x)"'))
    with pytest.raises(ScenarioError) as exc:
        run_protocol(path, tmp_path / "out", progress=False)
    assert str(exc.value) == f"{path}: runs.b.carry.d.k: 'a.d.der(x)' was not recorded by run 'a'"
    assert not (tmp_path / "out").exists()      # refused before the first run started


def test_a_later_run_that_cannot_work_stops_the_protocol_before_the_first_run(tmp_path):
    path = _protocol(tmp_path, RUNS + 'parameters = { "d.kk" = 3.0 }\n')
    with pytest.raises(ScenarioError) as exc:
        run_protocol(path, tmp_path / "out", progress=False)
    assert exc.value.field == "runs.c: instances.d.parameters.kk" and "has no variable 'kk'" in exc.value.reason
    assert not (tmp_path / "out").exists()


def test_a_carry_into_a_variable_that_cannot_take_it_is_refused_before_any_run(tmp_path):
    path = _protocol(tmp_path, RUNS.replace('"d.k" = "a.d.x"', '"d.der(x)" = "a.d.x"'))
    with pytest.raises(ScenarioError) as exc:
        check_protocol(path)
    assert exc.value.field == "runs.b.carry.d.der(x)" and "der(x)" in exc.value.reason
    assert not (tmp_path / "out").exists()


def test_a_carry_function_replaces_the_lookup(tmp_path):
    path = _protocol(tmp_path, RUNS.replace('"a.d.x"', '"a.d.der(x)"'))
    calls = []

    def carry(spec, finals):
        calls.append((dict(spec), sorted(finals)))
        return {ref: 1.5 for ref in spec}
    results = run_protocol(path, tmp_path / "out", progress=False, carry=carry)
    assert results["b"].final["d.k"] == 1.5
    # called once by the check before any run starts, once as the runs go
    assert calls == [({}, []), ({"d.k": "a.d.der(x)"}, ["a"]), ({}, ["a", "b"])] * 2


def test_force_lifts_the_step_limit(tmp_path):
    path = _protocol(tmp_path, extra="max_steps = 1")
    with pytest.raises(ScenarioError, match="more than max_steps = 1"):
        run_protocol(path, tmp_path / "out", progress=False)
    assert run_protocol(path, tmp_path / "forced", progress=False, force=True)["run"].steps == 2


def test_the_progress_bar_is_passed_on(tmp_path, capfd):
    path = _protocol(tmp_path)
    run_protocol(path, tmp_path / "quiet", progress=False)
    assert capfd.readouterr().err == ""
    run_protocol(path, tmp_path / "bar", progress=True)
    assert " of 0.1 s" in capfd.readouterr().err


def test_isolate_hosts_every_instance_in_a_child_process(tmp_path):
    """isolate=True isolates every instance; isolate=False leaves a scenario's own isolate = true."""
    path = _protocol(tmp_path)
    run_protocol(path, tmp_path / "plain", progress=False)
    assert not (tmp_path / "plain" / "run" / "logs" / "d.log.stdout").exists()
    run_protocol(path, tmp_path / "iso", progress=False, isolate=True)
    assert (tmp_path / "iso" / "run" / "logs" / "d.log.stdout").exists()
    own = _protocol(tmp_path, isolate=True, name="own")
    run_protocol(own, tmp_path / "own", progress=False, isolate=False)
    assert (tmp_path / "own" / "run" / "logs" / "d.log.stdout").exists()


def test_a_run_error_without_an_instance():
    """A RunError not tied to an instance (the API's failed run) has no instance and no time."""
    err = RunError("the run  failed\n at the end")
    assert (str(err), err.instance, err.time, for_error(err)) == ("the run failed at the end", "", None,
                                                                  RUN_FAILED)


def test_a_protocol_file_is_read_once_per_command(tmp_path, monkeypatch, capsys):
    """check and run of a protocol read and parse the file once (every run's scenario is made from the
    document read), also through the command line."""
    from wmr_cosim.cli import main
    from wmr_cosim.cosim.scenario import document

    path = _protocol(tmp_path, RUNS)
    reads: list[str] = []
    real = document.read_document

    def counted(p, *args, **kw):
        if not args:                      # (the file itself, not a base it names)
            reads.append(str(p))
        return real(p, *args, **kw)

    monkeypatch.setattr(document, "read_document", counted)
    assert main(["check", str(path), "--variant", "slow"]) == 0
    assert "run c: ok" in capsys.readouterr().out and reads == [str(path)]
    reads.clear()
    assert main(["run", str(path), "--quiet", "--out", str(tmp_path / "out")]) == 0
    assert reads == [str(path)] and (tmp_path / "out" / "c" / "signals.npy").is_file()


def test_isolate_is_part_of_the_plan_and_leaves_the_scenario_as_it_is(tmp_path):
    """resolve(isolate_all=True) isolates every instance of the plan; the scenario given keeps its own flags
    (and every other field), and a later plan of it without isolate_all is not isolated."""
    import copy

    from wmr_cosim import cosim

    sc = cosim.load(_protocol(tmp_path))
    before = copy.deepcopy(sc)
    plan = cosim.resolve(sc, force=True, isolate_all=True)
    assert [ip.spec.isolate for ip in plan.instances.values()] == [True]
    assert plan.scenario.instances["d"].isolate and plan.scenario.force
    assert sc == before and not sc.instances["d"].isolate and sc.start is None and not sc.force
    assert not cosim.resolve(sc).instances["d"].spec.isolate


def test_a_change_to_a_plan_leaves_its_scenario_as_it_is(tmp_path):
    from wmr_cosim import cosim

    sc = cosim.load(_protocol(tmp_path))
    plan = cosim.resolve(sc)
    plan.instances["d"].spec.isolate = True
    assert not sc.instances["d"].isolate and not cosim.resolve(sc).instances["d"].spec.isolate


def test_every_variable_the_runs_name_and_the_fmu_lacks_is_listed_in_one_line(tmp_path, capsys):
    """check stops at no first missing variable: every one of them, run by run (a variable only some runs
    name says which), in one line, exit 2; one missing variable alone keeps its own message."""
    from wmr_cosim.cli import main

    path = _protocol(tmp_path, RUNS.replace('name = "b"', 'name = "b"\nparameters = { "d.kk" = 1.0 }')
                     + 'parameters = { "d.kk" = 3.0, "d.zz" = 1.0 }\n'
                     + '[[requirements]]\nname = "r"\nformula = "always d.y < 2"\n[[events]]\ntime = 0.05\n'
                       'variable = "d.u"\nvalue = 1.0\n')
    path.write_text(path.read_text().replace('variables = ["d.x", "d.k"]', 'variables = ["d.x", "d.xx", "d.k"]'))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err == (f"wmr-cosim: error: {path}: 5 variables missing from their FMUs: "
                   "d.xx (record.variables[1]; did you mean 'x'?), d.u (events[0].variable), "
                   "d.y (requirements[0].formula), d.kk (runs.b.parameters and 1 more; runs b, c; did you mean 'k'?), "
                   "d.zz (runs.c.parameters)"), err
    path.write_text(_protocol(tmp_path, RUNS + 'parameters = { "d.kk" = 3.0 }\n', name="one").read_text())
    assert main(["check", str(path)]) == 2
    assert "runs.c: instances.d.parameters.kk: d (Dahlquist.fmu) has no variable 'kk' (did you mean 'k'?)" \
        in capsys.readouterr().err


def test_a_single_run_lists_every_missing_variable_too(tmp_path):
    from wmr_cosim import cosim

    path = _protocol(tmp_path, extra="", runs='[[connections]]\nfrom = "d.x"\nto = "d.in"\n')
    path.write_text(path.read_text().replace('variables = ["d.x", "d.k"]', 'variables = ["d.x", "d.kk"]'))
    with pytest.raises(ScenarioError) as exc:
        cosim.resolve(cosim.load(path))
    assert str(exc.value) == (f"{path}: 2 variables missing from their FMUs: d.in (connections[0].to), "
                              "d.kk (record.variables[1]; did you mean 'k'?)")
