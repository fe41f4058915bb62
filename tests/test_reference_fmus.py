"""The master on FMUs from other tools: the Modelica Association's Reference FMUs (FMI 2.0, linux64, in
tests/data/reference-fmus) against FMPy's simulate_fmu with the same step and against their reference
results, and the FMU behaviours of other exporters (call order, initialisation, names, start values,
tabulated inputs, types, missing binaries, logging)."""
from __future__ import annotations

import csv
import re
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from wmr_cosim.exit_codes import for_status
from fmpy import read_csv, simulate_fmu

from cosim_support import build_test_fmu, write_scenario
from wmr_cosim import cosim
from wmr_cosim.cosim.scenario import document as scenario
from wmr_cosim.cosim.messages.errors import ScenarioError
from wmr_cosim.cosim.model.description import load_model
from wmr_cosim.runner import fmu_plan

from reference_fmus import REF
FMI2 = REF / "fmi2"


def _cli(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", *map(str, args)], capture_output=True, text=True)


def _ours(fmu: Path, tmp: Path, **kw) -> np.ndarray:
    res = cosim.run(fmu_plan(fmu, **kw), tmp / "out", progress=False)
    assert res.status in ("ok", "terminated"), res.message
    return np.load(tmp / "out" / "signals.npy")


def _fmpy(fmu: Path, step: float, **kw) -> np.ndarray:
    return simulate_fmu(str(fmu), output_interval=step, **kw)


@pytest.mark.parametrize("model", ["BouncingBall", "Dahlquist", "Resource", "Stair", "VanDerPol"])
def test_reference_fmu_equals_fmpy_and_its_reference(model, tmp_path):
    fmu = FMI2 / f"{model}.fmu"
    plan = fmu_plan(fmu)
    ours = _ours(fmu, tmp_path)
    theirs = _fmpy(fmu, plan.scenario.step, stop_time=plan.scenario.stop)
    assert len(ours) == len(theirs), (len(ours), len(theirs))
    np.testing.assert_allclose(ours["time"], theirs["time"], rtol=0, atol=1e-12)
    for name in theirs.dtype.names[1:]:
        col = f"{model}.{name}"
        assert col in ours.dtype.names, col
        np.testing.assert_allclose(ours[col].astype(float), theirs[name].astype(float), rtol=0, atol=1e-12,
                                   err_msg=col)
    ref = read_csv(str(FMI2 / f"{model}_ref.csv"))
    for name in ref.dtype.names[1:]:  # the reference result, at the times both have
        t_ours = np.round(ours["time"], 9)
        for t, v in zip(np.round(ref["time"], 9), ref[name]):
            hit = np.flatnonzero(t_ours == t)
            if hit.size:
                assert abs(float(ours[f"{model}.{name}"][hit[-1]]) - float(v)) < 1e-6, (name, t)


def test_an_fmu_that_ends_the_simulation_ends_the_run_cleanly(tmp_path):
    """Stair returns Discard with fmi2Terminated at t = 9 s: status terminated, last row at 9 s, exit 0."""
    p = _cli("run", FMI2 / "Stair.fmu", "--out", tmp_path / "out", "--quiet")
    assert p.returncode == 0, p.stderr
    assert "terminated by FMU Stair at t = 9 s" in p.stdout
    data = np.load(tmp_path / "out" / "signals.npy")
    assert data["time"][-1] == pytest.approx(9.0) and data["Stair.counter"][-1] == 10
    assert data["Stair.counter"].dtype == np.int32   # Integer recorded as an integer


def _feedthrough_chain(tmp: Path, algorithm: str, factor: float = 1.0, offset: float = 0.0) -> Path:
    fmu = FMI2 / "Feedthrough.fmu"
    return write_scenario(tmp / f"chain_{algorithm}.toml", f'''
[experiment]
stop = 0.1
step = 0.01
algorithm = "{algorithm}"
order = ["b", "a"]          # against the flow: a feeds b
[instances.a]
fmu = "{fmu}"
parameters = {{ Float64_continuous_input = 3.0, Int32_input = 7, Boolean_input = true }}
[instances.b]
fmu = "{fmu}"
[[connections]]
from = "a.Float64_continuous_output"
to = "b.Float64_continuous_input"
factor = {factor}
offset = {offset}
[[connections]]
from = "a.Int32_output"
to = "b.Int32_input"
[[connections]]
from = "a.Boolean_output"
to = "b.Boolean_input"
[[connections]]
from = "a.Enumeration_output"
to = "b.Enumeration_input"
[record]
variables = ["*.Float64_continuous_output", "*.Int32_output", "*.Boolean_output", "*.Enumeration_output"]
''')


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_initialisation_exchanges_outputs_to_inputs_against_the_order(algorithm, tmp_path):
    """The row at the start time shows the initialised system: b gets a's output although b comes first
    (never 0.0), through the connection's linear transform, for every type."""
    for factor, offset in ((1.0, 0.0), (2.0, 1.0)):
        plan = cosim.resolve(scenario.load(_feedthrough_chain(tmp_path, algorithm, factor, offset)))
        res = cosim.run(plan, tmp_path / "out", progress=False)
        assert res.status == "ok", res.message
        d = np.load(tmp_path / "out" / "signals.npy")
        assert d["a.Float64_continuous_output"][0] == 3.0
        assert d["b.Float64_continuous_output"][0] == 3.0 * factor + offset
        assert d["b.Int32_output"][0] == 7 and d["b.Boolean_output"][0]
        assert d["b.Int32_output"].dtype == np.int32 and d["b.Boolean_output"].dtype == np.bool_
        assert np.all(d["b.Float64_continuous_output"] == 3.0 * factor + offset)


def test_parameters_survive_an_fmu_that_resets_them_in_setup_experiment(tmp_path):
    fmu = build_test_fmu("resetter.py", tmp_path / "fmu")
    path = write_scenario(tmp_path / "r.toml", f'''
[experiment]
stop = 0.01
step = 0.001
[instances.r]
fmu = "{fmu}"
parameters = {{ p = 5.0 }}
''')
    res = cosim.run(cosim.resolve(scenario.load(path)), tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    assert np.all(d["r.y"] == 5.0)


@pytest.mark.parametrize("level, kept", [("warning", 0), ("info", 10), ("all", 10)])
def test_log_level_filters_a_verbose_fmu(level, kept, tmp_path):
    fmu = build_test_fmu("resetter.py", tmp_path / "fmu")
    path = write_scenario(tmp_path / "r.toml", f'''
[experiment]
stop = 0.01
step = 0.001
[instances.r]
fmu = "{fmu}"
logging = "{level}"
''')
    res = cosim.run(cosim.resolve(scenario.load(path)), tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    lines = (tmp_path / "out" / "logs" / "r.log").read_text().splitlines()
    assert sum("step at t" in ln for ln in lines) == kept


def test_fmi_names_are_exact_and_patterns_only_where_written(tmp_path):
    """der(x0) and a name map to x[1]: exact names always work; '[1]' is not a character class."""
    fmu = FMI2 / "VanDerPol.fmu"
    path = write_scenario(tmp_path / "v.toml", f'''
[experiment]
stop = 1.0
step = 0.01
[instances.vdp]
fmu = "{fmu}"
names = {{ x1 = "x[1]" }}
[record]
variables = ["vdp.x[1]", "vdp.der(x0)", "vdp.x?"]
''')
    plan = cosim.resolve(scenario.load(path))
    assert [r.column for r in plan.record] == ["vdp.x[1]", "vdp.der(x0)", "vdp.x0"]
    res = cosim.run(plan, tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    ref = _fmpy(fmu, 0.01, stop_time=1.0, output=["x0", "x1"])
    np.testing.assert_allclose(d["vdp.x[1]"], ref["x1"], rtol=0, atol=1e-12)


def test_start_values_of_states_follow_the_initial_rules(tmp_path):
    fmu = FMI2 / "VanDerPol.fmu"
    ours = _ours(fmu, tmp_path, overrides={"VanDerPol.x0": 3.0, "VanDerPol.mu": 0.5}, stop=2.0)
    assert ours["VanDerPol.x0"][0] == 3.0
    theirs = _fmpy(fmu, 0.01, stop_time=2.0, start_values={"x0": 3.0, "mu": 0.5})
    np.testing.assert_allclose(ours["VanDerPol.x0"], theirs["x0"], rtol=0, atol=1e-12)
    with pytest.raises(ScenarioError, match="initial=\"calculated\""):   # a derivative cannot be set
        fmu_plan(fmu, overrides={"VanDerPol.der(x0)": 1.0})


def _ft_inputs(path: Path) -> Path:
    """Feedthrough's shipped input file (its Int32 column, extremes included), with a Real, a Boolean and
    an Enumeration column, a step (a repeated time) and a ramp."""
    with open(REF / "Feedthrough_in.csv") as fh:
        rows = list(csv.DictReader(fh))
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time", "Float64_continuous_input", "Float64_discrete_input", "Int32_input", "Boolean_input",
                    "Enumeration_input"])
        w.writerow([0.0, 0.0, 0.0, rows[0]["Int32_input"], 0, 1])
        w.writerow([0.5, 1.0, 1.0, rows[0]["Int32_input"], 1, 2])
        w.writerow([0.5, 3.0, 3.0, rows[1]["Int32_input"], 1, 2])
        w.writerow([1.0, 5.0, 4.0, rows[1]["Int32_input"], 0, 1])
    return path


def test_tabulated_inputs_match_fmpy_on_feedthrough(tmp_path):
    fmu = FMI2 / "Feedthrough.fmu"
    table = _ft_inputs(tmp_path / "in.csv")
    ours = _ours(fmu, tmp_path, inputs=table, stop=1.5, step=0.1)
    theirs = _fmpy(fmu, 0.1, stop_time=1.5, input=read_csv(str(table)))
    assert len(ours) == len(theirs)
    for name in ("Float64_continuous_output", "Float64_discrete_output", "Int32_output", "Boolean_output",
                 "Enumeration_output"):
        np.testing.assert_allclose(ours[f"Feedthrough.{name}"].astype(float), theirs[name].astype(float),
                                   rtol=0, atol=1e-12, err_msg=name)
    assert ours["Feedthrough.Int32_output"].max() == 2 ** 31 - 1 and ours["Feedthrough.Int32_output"].min() == -2 ** 31
    # set before the step from t_k, seen in the row of t_k+1: at 0.5 s the value after the step in the
    # table (3, not 1), at 0.6 s linear between (0.5, 3) and (1, 5)
    i = int(np.flatnonzero(np.isclose(ours["time"], 0.5))[0])
    out = ours["Feedthrough.Float64_continuous_output"]
    assert out[i + 1] == 3.0 and out[i + 2] == pytest.approx(3.4, abs=1e-12)


def test_a_string_output_is_reported_not_silently_dropped(tmp_path):
    p = _cli("check", FMI2 / "Feedthrough.fmu")
    assert p.returncode == 0 and "String outputs are not recorded: Feedthrough.String_output" in p.stdout, p


def _rebinary(src: Path, dst: Path, rename) -> Path:
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w") as zo:
        for info in zi.infolist():
            data = zi.read(info)
            info.filename = rename(info.filename)
            zo.writestr(info, data)
    return dst


@pytest.mark.parametrize("kind, reason", [("win64", "no binary for this platform"),
                                          ("renamed", "must be named after the model identifier")])
def test_a_missing_binary_is_found_by_check(kind, reason, tmp_path):
    src = FMI2 / "Dahlquist.fmu"
    fmu = _rebinary(src, tmp_path / "D.fmu", (lambda n: n.replace("linux64", "win64").replace(".so", ".dll"))
                    if kind == "win64" else (lambda n: n.replace("Dahlquist.so", "libdahlquist.so")))
    for cmd in ("check", "run"):
        p = _cli(cmd, fmu, "--out", tmp_path / "o") if cmd == "run" else _cli(cmd, fmu)
        assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1 and reason in p.stderr, p.stderr


@pytest.mark.parametrize("rename, platforms", [
    (lambda n: n.replace("linux64", "win64").replace(".so", ".dll"), "win64"),
    (lambda n: n.replace("binaries/linux64/", "sources/"), "no platform")])
def test_an_fmu_without_a_binary_for_this_platform_names_the_ones_it_has(rename, platforms, tmp_path):
    from wmr_cosim.cosim.messages.errors import FmuLoadError
    from wmr_cosim.cosim.model.description import load_model

    fmu = _rebinary(FMI2 / "Dahlquist.fmu", tmp_path / "D.fmu", rename)
    with pytest.raises(FmuLoadError) as err:
        load_model(fmu)
    assert str(err.value) == (f"{fmu}: no binary for this platform (linux64): the FMU has binaries for {platforms} "
                              "(a source-only or other-platform FMU cannot run here)")


def test_defaults_come_from_the_fmus_and_must_agree(tmp_path):
    a, b = FMI2 / "Dahlquist.fmu", FMI2 / "VanDerPol.fmu"
    path = write_scenario(tmp_path / "d.toml", f'[instances.a]\nfmu = "{a}"\n[instances.b]\nfmu = "{b}"\n')
    with pytest.raises(ScenarioError, match="default experiments disagree") as exc:
        cosim.resolve(scenario.load(path))
    assert exc.value.field == "experiment.stop"
    path.write_text(path.read_text() + "[experiment]\nstop = 1.0\nstep = 0.1\ntolerance = 1e-6\n")
    plan = cosim.resolve(scenario.load(path))
    assert (plan.scenario.start, plan.scenario.tolerance, plan.n_steps) == (0.0, 1e-6, 10)
    one = fmu_plan(a)
    assert (one.scenario.stop, one.scenario.step) == (10.0, 0.1)


def test_each_fmu_gets_its_own_default_tolerance_unless_the_scenario_gives_one(tmp_path):
    """A tolerance is each FMU's own solver setting: FMUs whose default experiments give different ones
    run together, each set up with its own; the experiment's tolerance sets all, an instance's its own."""
    import zipfile

    def with_tolerance(src: Path, dst: Path, tol: str) -> Path:
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
            for item in zin.infolist():
                data = zin.read(item)
                if item.filename == "modelDescription.xml":
                    data = re.sub(rb'<DefaultExperiment[^>]*/>', b'<DefaultExperiment startTime="0" stopTime="1" '
                                  b'stepSize="0.1" tolerance="' + tol.encode() + b'"/>', data)
                zout.writestr(item, data)
        return dst
    a = with_tolerance(FMI2 / "Dahlquist.fmu", tmp_path / "A.fmu", "1e-08")
    b = with_tolerance(FMI2 / "VanDerPol.fmu", tmp_path / "B.fmu", "1e-06")
    head = "[experiment]\nstop = 1.0\nstep = 0.1\n"
    path = write_scenario(tmp_path / "d.toml", f'{head}[instances.a]\nfmu = "{a}"\n[instances.b]\nfmu = "{b}"\n')
    plan = cosim.resolve(scenario.load(path))
    assert (plan.instances["a"].tolerance, plan.instances["b"].tolerance) == (1e-8, 1e-6)
    path.write_text(path.read_text().replace(head, head + "tolerance = 1e-5\n"))
    plan = cosim.resolve(scenario.load(path))
    assert (plan.instances["a"].tolerance, plan.instances["b"].tolerance) == (1e-5, 1e-5)
    path.write_text(path.read_text() + "tolerance = 1e-3\n")     # on instance b
    plan = cosim.resolve(scenario.load(path))
    assert (plan.instances["a"].tolerance, plan.instances["b"].tolerance) == (1e-5, 1e-3)
    res = cosim.run(plan, tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    resolved = json.loads((tmp_path / "out" / "scenario.json").read_text())
    assert [resolved["instances"][n]["tolerance"] for n in "ab"] == [1e-5, 1e-3]


# ------------------------------------------------------------------------------- C FMUs of other exporters
def _probe_run(fmu: Path, tmp: Path, extra: str = "", name: str = "Probe") -> tuple[cosim.RunResult, Path]:
    path = write_scenario(tmp / "probe.toml", f'''
[experiment]
stop = 0.5
step = 0.01
[instances.{name.lower()}]
fmu = "{fmu}"
{extra}
''')
    out = tmp / "out"
    return cosim.run(cosim.resolve(scenario.load(path)), out, progress=False), out


def test_c_fmu_resetting_its_parameters_in_setup_experiment_gets_the_scenarios_values(tmp_path):
    from c_fmu_support import build_probe

    fmu = build_probe(tmp_path / "fmu", RESET_IN_SETUP=True)
    res, out = _probe_run(fmu, tmp_path, 'parameters = { p = 3.0, u = 2.0 }\n[record]\nvariables = ["probe.p", "probe.y"]')
    assert res.status == "ok", res.message
    d = np.load(out / "signals.npy")
    assert np.all(d["probe.p"] == 3.0) and d["probe.y"][0] == 6.0


@pytest.mark.parametrize("level, lines", [("warning", 0), ("all", 51)])
def test_c_fmu_logging_with_a_foreign_environment_and_a_verbose_fmu(level, lines, tmp_path):
    """A verbose FMU (a message at every step) that passes back a componentEnvironment of its own: at the
    default level fmi2SetDebugLogging stops it at the source; at "all" every message reaches this
    instance's log, routed by the instance name."""
    from c_fmu_support import build_probe

    fmu = build_probe(tmp_path / "fmu", VERBOSE=True, FOREIGN_ENV=True)
    res, out = _probe_run(fmu, tmp_path, f'logging = "{level}"')
    assert res.status == "ok", res.message
    log = (out / "logs" / "probe.log").read_text().splitlines()
    assert len(log) == lines and sum("a message at every step" in ln for ln in log) == max(0, lines - 1), log[:3]
    summary = json.loads((out / "summary.json").read_text())["instances"]["probe"]
    assert summary["log_lines"] == len(log)
    assert summary["log_received"] == (1 if level == "warning" else lines)  # only the message of instantiation


def test_c_fmu_ending_the_simulation_with_discard_and_terminated(tmp_path):
    from c_fmu_support import build_probe

    fmu = build_probe(tmp_path / "fmu", TERMINATE_AT=0.25)
    res, out = _probe_run(fmu, tmp_path, '[record]\nvariables = ["probe.n"]')
    assert res.status == "terminated" and for_status(res.status) == 0 and "probe at t = 0.25 s" in res.message
    d = np.load(out / "signals.npy")
    assert d["time"][-1] == pytest.approx(0.25) and d["probe.n"][-1] == 25


def test_events_on_discrete_inputs_and_converting_connections(tmp_path):
    """Events set Integer/Boolean inputs (override, bias, reset); Boolean -> Real and Real -> Boolean
    connections convert where asked; a String connection copies its text."""
    fmu = FMI2 / "Feedthrough.fmu"
    path = write_scenario(tmp_path / "ev.toml", f'''
[experiment]
stop = 0.2
step = 0.01
[instances.a]
fmu = "{fmu}"
parameters = {{ Int32_input = 1, Float64_continuous_input = 1.0 }}
[instances.b]
fmu = "{fmu}"
[[connections]]
from = "a.Boolean_output"
to = "b.Float64_continuous_input"
convert = true
factor = 2.0
offset = 0.5
[[connections]]
from = "a.Float64_continuous_output"
to = "b.Boolean_input"
convert = true
threshold = 1.5
[[connections]]
from = "a.String_output"
to = "b.String_input"
[[events]]
time = 0.05
variable = "a.Int32_input"
value = 5
[[events]]
time = 0.08
variable = "a.Int32_input"
action = "bias"
value = 2
[[events]]
time = 0.1
variable = "a.Int32_input"
action = "reset"
[[events]]
time = 0.03
variable = "a.Boolean_input"
value = true
[[events]]
time = 0.12
variable = "a.Float64_continuous_input"
value = 2.0
[record]
variables = ["a.Int32_output", "a.Boolean_output", "b.Float64_continuous_output", "b.Boolean_output"]
''')
    res = cosim.run(cosim.resolve(scenario.load(path)), tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    t = np.round(d["time"], 9)

    def at(col, time):  # the output in the row after the step from `time`
        return d[col][np.flatnonzero(t == round(time + 0.01, 9))[0]]
    assert [at("a.Int32_output", x) for x in (0.04, 0.05, 0.07, 0.08, 0.1)] == [1, 5, 5, 7, 1]
    assert not at("a.Boolean_output", 0.02) and at("a.Boolean_output", 0.03)
    assert at("b.Float64_continuous_output", 0.01) == 0.5 and at("b.Float64_continuous_output", 0.05) == 2.5
    assert not at("b.Boolean_output", 0.11) and at("b.Boolean_output", 0.13)


@pytest.mark.parametrize("text, reason", [
    ('[[connections]]\nfrom = "a.Boolean_output"\nto = "b.Float64_continuous_input"\n', "convert = true converts"),
    ('[[connections]]\nfrom = "a.Int32_output"\nto = "b.Float64_continuous_input"\nconvert = true\n',
     "converts Boolean <-> Real only"),
    ('[[events]]\ntime = 0.1\nvariable = "b.Boolean_input"\nvalue = true\n[[connections]]\nfrom = "a.Boolean_output"\n'
     'to = "b.Boolean_input"\n', "no connection or table drives"),
    ('[[events]]\ntime = 0.1\nvariable = "b.Boolean_input"\naction = "bias"\nvalue = 1\n', "a bias needs"),
])
def test_type_rules_of_connections_and_events(text, reason, tmp_path):
    fmu = FMI2 / "Feedthrough.fmu"
    path = write_scenario(tmp_path / "bad.toml", f'[experiment]\nstop = 0.2\nstep = 0.01\n[instances.a]\nfmu = "{fmu}"\n'
                                                 f'[instances.b]\nfmu = "{fmu}"\n{text}')
    with pytest.raises(ScenarioError, match=reason.replace("(", r"\(")):
        cosim.resolve(scenario.load(path))


def test_a_real_to_boolean_connection_with_a_factor_is_named_in_one_line(tmp_path):
    fmu = FMI2 / "Feedthrough.fmu"
    path = write_scenario(tmp_path / "bad.toml", f'[experiment]\nstop = 0.2\nstep = 0.01\n[instances.a]\nfmu = "{fmu}"\n'
                          f'[instances.b]\nfmu = "{fmu}"\n[[connections]]\nfrom = "a.Float64_continuous_output"\n'
                          'to = "b.Boolean_input"\nconvert = true\nfactor = 2.0\n')
    with pytest.raises(ScenarioError) as err:
        cosim.resolve(scenario.load(path))
    assert str(err.value) == (f"{path}: connections[0]: a Real -> Boolean conversion takes a threshold, not a "
                              "factor or offset")


def test_an_array_parameter_given_a_scalar_is_named_in_one_line(tmp_path):
    fmu = REF / "fmi3" / "StateSpace.fmu"
    path = write_scenario(tmp_path / "bad.toml", f'[experiment]\nstop = 0.2\nstep = 0.01\n[instances.s]\nfmu = "{fmu}"\n'
                          '[instances.s.parameters]\nx0 = 1.0\n')
    with pytest.raises(ScenarioError) as err:
        cosim.resolve(scenario.load(path))
    assert str(err.value) == f"{path}: instances.s.parameters.x0: x0 is an array of 3 values (3,): give a list of 3"


def test_a_ctrl_c_after_the_last_step_interrupts_nothing(tmp_path, monkeypatch):
    import os
    import signal

    from wmr_cosim.cosim.stepping.generated import GaussSeidel

    class SignalAfterTheLastStep(GaussSeidel):   # Ctrl-C once every step has run
        def advance(self, k0, k1):
            r = super().advance(k0, k1)
            if k1 == self.clock.n_steps:
                os.kill(os.getpid(), signal.SIGINT)
            return r
    res = cosim.run(fmu_plan(FMI2 / "Dahlquist.fmu"), tmp_path / "out", progress=False,
                        algorithm=SignalAfterTheLastStep())
    assert res.status == "ok" and res.steps == 100, res.message


def test_the_direct_loop_reports_a_non_finite_state_as_diverged():
    from wmr_cosim.components.direct_loop import run_direct

    r = run_direct(t_stop=2.0, disturbance=lambda t: (float("nan"), 0.0) if t > 1.0 else (0.0, 0.0))
    assert r.status == "diverged" and "no longer finite at t = 1.004 s" in r.message


def test_a_bias_adds_to_the_value_and_an_override_replaces_it(tmp_path):
    """A Real input at 1.0 (its start value): a bias of +2 gives 3 (an override would give 2); a bias on an
    output acts before the connection's factor; reset restores the source."""
    fmu = FMI2 / "Feedthrough.fmu"
    path = write_scenario(tmp_path / "bias.toml", f'''
[experiment]
stop = 0.1
step = 0.01
[instances.a]
fmu = "{fmu}"
parameters = {{ Float64_continuous_input = 1.0 }}
[instances.b]
fmu = "{fmu}"
[[connections]]
from = "a.Float64_continuous_output"
to = "b.Float64_continuous_input"
factor = 10.0
[[events]]
time = 0.02
variable = "a.Float64_continuous_input"
action = "bias"
value = 2.0
[[events]]
time = 0.05
variable = "a.Float64_continuous_output"
action = "bias"
value = 0.5
[[events]]
time = 0.08
variable = "a.Float64_continuous_output"
action = "reset"
[record]
variables = ["a.Float64_continuous_output", "b.Float64_continuous_output"]
''')
    res = cosim.run(cosim.resolve(scenario.load(path)), tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    a, b = d["a.Float64_continuous_output"], d["b.Float64_continuous_output"]
    assert a[2] == 1.0 and a[3] == 3.0                  # the row after the step from 0.02 s
    assert b[5] == 30.0 and b[6] == 35.0 and b[8] == 35.0 and b[9] == 30.0   # 10 * (3 + 0.5), then reset


def test_a_run_whose_fmu_would_take_too_many_internal_steps_is_refused_at_check(tmp_path, capsys):
    """The Reference FMU Roberts declares a fixed internal step of 1 ms and a default experiment of 1e8 s:
    1e11 internal steps, a run that would not finish.  check refuses it in one line; a stop the FMU can
    reach passes and says how many internal steps it takes."""
    from wmr_cosim.cli import main

    roberts = REF / "fmi3" / "Roberts.fmu"
    if not roberts.is_file():
        pytest.skip("no Reference FMU Roberts")
    assert main(["check", str(roberts)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "experiment.stop: Roberts (Roberts.fmu) takes fixed internal steps of 0.001 s: 1e+11" in err
    assert "more than max_internal_steps = 1000000000" in err
    plan = fmu_plan(roberts, stop=10.0)
    assert plan.internal_steps == {"Roberts": round((10.0 - plan.scenario.start) / 1e-3)}
    assert main(["check", str(roberts), "--stop", "10"]) == 0
    assert "note: Roberts takes fixed internal steps of 0.001 s: about 1e+04 over the run" in capsys.readouterr().out
    assert fmu_plan(roberts, force=True).internal_steps["Roberts"] > 10 ** 10


def test_resolve_leaves_the_scenario_it_is_given_as_it_is(tmp_path):
    """The times a scenario leaves open come from the FMU's default experiment into the plan's copy; the
    scenario given to resolve is not changed (so one Scenario resolves the same way twice)."""
    path = write_scenario(tmp_path / "d.toml", f'[instances.a]\nfmu = "{FMI2 / "Dahlquist.fmu"}"\n')
    sc = scenario.load(path)
    plan = cosim.resolve(sc, force=True)
    assert (plan.scenario.stop, plan.scenario.step, plan.scenario.force) == (10.0, 0.1, True)
    assert (sc.stop, sc.step, sc.force) == (None, None, False)
    assert cosim.resolve(sc).n_steps == plan.n_steps == 100
