"""The execution as a user sees it: the status, message, steps and files of a run that ends at its stop
time, is interrupted (Ctrl-C), fails (a status, a non-finite input, an FMU's process dying) or is ended
by its FMU; the event log; values read and set between steps through the Python API.

The FMUs are the C probe (tests/c_fmus/probe.c: y = p u + c, c and n count the steps) compiled with a
few extra behaviours inserted here, and the Reference FMU Feedthrough."""
from __future__ import annotations

import hashlib
import json
import math
import shutil
import subprocess
import tempfile
import time as _time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from c_fmu_support import MODEL_DESCRIPTION, SRC
from reference_fmus import REF
from wmr_cosim import Simulation
from wmr_cosim.cosim.runtime import execution
from wmr_cosim.cosim.runtime import startup
from wmr_cosim.cosim.runtime.interrupt import Interrupt
from wmr_cosim.cosim.runtime.observers import progress_bar
from wmr_cosim.cosim.instances.failure import Call, Failure
from wmr_cosim.cosim.messages.errors import CosimError, RunError
from wmr_cosim.exit_codes import for_status

FEEDTHROUGH = REF / "fmi2" / "Feedthrough.fmu"

#: Behaviours added to the probe, each compiled in with -D<NAME>=<value>: (function, code).
HOOKS = {
    "SIGINT_AT": ("fmi2DoStep", "if (t > SIGINT_AT - 1e-6 && t < SIGINT_AT + 1e-6) raise(SIGINT);"),
    "GET_FAILS_AT": ("fmi2GetReal", "if (s->time >= GET_FAILS_AT - 1e-9) return fmi2Error;"),
    "GET_FAILS_TERMINATED": ("fmi2GetReal", "if (s->terminated) return fmi2Error;"),
    "TOL_TO_P": ("fmi2SetupExperiment", "s->p = tolDef ? tol : -1.0;"),
    "NO_LAST_TIME": ("fmi2GetRealStatus", "return fmi2Error;"),
    "ENDS_HALFWAY_AT": ("fmi2DoStep", "if (t >= ENDS_HALFWAY_AT - 1e-9) { s->terminated = 1; s->n += 1; "
                                      "s->time = s->last_ok = t + h / 2; return fmi2Discard; }"),
    "ENDS_10NS_INTO_AT": ("fmi2DoStep", "if (t >= ENDS_10NS_INTO_AT - 1e-9) { s->terminated = 1; s->n += 1; "
                                        "s->time = s->last_ok = t + 1e-8; return fmi2Discard; }"),
}


def _source() -> str:
    """probe.c with every hook inserted at the top of its function, each inside #ifdef NAME."""
    src = SRC.read_text()
    for name, (fn, code) in HOOKS.items():
        head = src.index(f"fmi2Status {fn}(")
        at = src.index("Probe *s = (Probe *)c;\n", head) + len("Probe *s = (Probe *)c;\n")
        src = src[:at] + f"#ifdef {name}\n    {code}\n#endif\n" + src[at:]
    return src


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    """probe(**defines) -> the probe FMU compiled with those defines (once per set of defines)."""
    import fmpy

    from cosim_support import fmu_cache_dir

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    folder = fmu_cache_dir("execution-probes") or tmp_path_factory.mktemp("probes")
    src = _source()

    def build(*, aliased: bool = False, **defines: object) -> Path:
        """``aliased``: the model description gives the Boolean input b the value reference of the Real
        input u (FMI 2.0 numbers value references per type)."""
        flags = sorted(f"-D{k}" if v is True else f"-D{k}={v}" for k, v in defines.items())
        md = MODEL_DESCRIPTION.format(name="Probe")
        if aliased:
            md = md.replace('name="b" valueReference="4"', 'name="b" valueReference="1"')
        key = hashlib.sha256((src + md + " ".join(flags)).encode()).hexdigest()[:16]
        fmu = folder / f"Probe-{key}.fmu"
        if fmu.is_file():
            return fmu
        work = Path(tempfile.mkdtemp(dir=folder))
        try:
            (work / "probe.c").write_text(src)
            so = work / "Probe.so"
            p = subprocess.run([cc, "-shared", "-fPIC", "-O1", f"-I{Path(fmpy.__file__).parent / 'c-code'}", *flags,
                                str(work / "probe.c"), "-o", str(so)], capture_output=True, text=True)
            assert p.returncode == 0, p.stderr
            with zipfile.ZipFile(work / "Probe.fmu", "w") as zf:
                zf.writestr("modelDescription.xml", md)
                zf.write(so, "binaries/linux64/Probe.so")
            (work / "Probe.fmu").replace(fmu)
        finally:
            shutil.rmtree(work, ignore_errors=True)
        return fmu
    return build


def _sim(fmu: Path, start: float = 0.0, stop: float = 0.5, step: float = 0.01, record=("probe.y",),
         **parameters) -> Simulation:
    sim = Simulation(file="t.toml").experiment(start=start, stop=stop, step=step)
    sim.instance("probe", fmu, **parameters)
    return sim.record(*record, csv=False)


def _run(sim: Simulation, out: Path | None, **kw) -> execution.RunResult:
    return execution.run(sim.check(), out, progress=False, **kw)


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def _scenario_fields(events: list[dict]) -> list[dict]:
    """The entries of the event table without the fields every entry has (source, kind, what)."""
    return [{k: v for k, v in e.items() if k not in ("source", "kind", "what")} for e in events]


# ---------------------------------------------------------------------- runs that end early
def test_ctrl_c_ends_the_run_at_the_next_segment_with_the_steps_done(probe, tmp_path):
    """The first SIGINT (here raised inside an FMU's step at t = 1.25 s) only sets a flag; the run stops
    where the segment that was running ends (2500 steps from the start: t = 3.5 s), interrupted, and
    keeps every row up to there."""
    res = _run(_sim(probe(SIGINT_AT=1.25), start=1.0, stop=3.6, step=0.001), tmp_path / "out")
    assert (res.status, res.message) == ("interrupted", "interrupted by the user at t = 3.5 s")
    assert for_status(res.status) == 130 and res.steps == 2500 and res.t_end == pytest.approx(3.5)
    d = np.load(tmp_path / "out" / "signals.npy")
    assert len(d) == 2501 and d["time"][-1] == pytest.approx(3.5)
    assert _summary(tmp_path / "out")["status"] == "interrupted"


def test_a_failed_get_after_a_step_names_its_time_and_keeps_the_steps_recorded(probe, tmp_path):
    """fmi2GetReal fails after the step to t = 1.3 s: that step's row is not recorded, so the run did 29
    steps (rows from 1.0 to 1.29 s), and the message names the call and the time it failed at."""
    res = _run(_sim(probe(GET_FAILS_AT=1.3), start=1.0, stop=1.5), tmp_path / "out")
    assert res.status == "failed" and for_status(res.status) == 1
    assert res.message == "probe: fmi2GetReal returned Error at t = 1.3 s; last log: (the FMU logged nothing)"
    assert res.steps == 29 and res.t_end == pytest.approx(1.29)
    d = np.load(tmp_path / "out" / "signals.npy")
    assert len(d) == 30 and d["time"][-1] == pytest.approx(1.29)
    s = _summary(tmp_path / "out")
    assert (s["status"], s["steps"], s["message"]) == ("failed", 29, res.message)


def test_a_failed_get_before_the_first_step_names_the_start_time(probe, tmp_path):
    res = _run(_sim(probe(GET_FAILS_AT=1.0), start=1.0, stop=1.5), tmp_path / "out")
    assert res.status == "failed" and res.steps == 0
    assert res.message == "probe: get outputs returned Error at t = 1 s; last log: (the FMU logged nothing)"


@pytest.mark.parametrize("tolerance, own, seen", [(1e-5, None, 1e-5), (None, None, -1.0), (1e-5, 1e-4, 1e-4)])
def test_the_experiment_tolerance_reaches_the_fmu(probe, tmp_path, tolerance, own, seen):
    """fmi2SetupExperiment gets the instance's tolerance, else the scenario's (toleranceDefined false
    without one); the probe copies what it got into p."""
    sim = _sim(probe(TOL_TO_P=True), stop=0.02, record=("probe.p",))
    if tolerance is not None:
        sim.experiment(tolerance=tolerance)
    if own is not None:
        sim.document["instances"]["probe"]["tolerance"] = own
    res = _run(sim, tmp_path / "out")
    assert res.status == "ok", res.message
    assert np.load(tmp_path / "out" / "signals.npy")["probe.p"][0] == seen


@pytest.mark.parametrize("last_time", [True, False])
def test_an_fmu_ending_the_simulation_ends_the_run_at_its_time(probe, tmp_path, last_time):
    """Discard with fmi2Terminated from the step at t = 1.25 s: terminated (not failed) at 1.25 s, 25 steps,
    the row at 1.25 s recorded; when the FMU cannot say its last successful time, the time of the step."""
    fmu = probe(TERMINATE_AT=1.25) if last_time else probe(TERMINATE_AT=1.25, NO_LAST_TIME=True)
    res = _run(_sim(fmu, start=1.0, stop=1.5, record=("probe.y", "probe.n")), tmp_path / "out")
    assert (res.status, res.message) == ("terminated", "terminated by FMU probe at t = 1.25 s")
    assert res.events == [{"time": 1.25, "source": "probe", "kind": "terminate", "what": "the FMU ended the simulation"}]
    assert for_status(res.status) == 0 and res.steps == 25 and res.t_end == 1.25
    d = np.load(tmp_path / "out" / "signals.npy")   # the row at 1.25 s once
    assert len(d) == 26 and d["time"][-1] == 1.25 and d["probe.n"][-1] == 25 and np.all(np.diff(d["time"]) > 0)


def test_an_fmu_ending_the_simulation_inside_a_step_adds_the_row_at_its_time(probe, tmp_path):
    """The step from 1.25 s ends the simulation halfway, at 1.255 s: 25 steps done, and a last row at the
    FMU's time with its outputs there."""
    res = _run(_sim(probe(ENDS_HALFWAY_AT=1.25), start=1.0, stop=1.5, record=("probe.n",)), tmp_path / "out")
    assert (res.status, res.message) == ("terminated", "terminated by FMU probe at t = 1.255 s")
    assert res.steps == 25 and res.t_end == 1.255 and res.final == {"time": 1.255, "probe.n": 26}
    d = np.load(tmp_path / "out" / "signals.npy")
    assert len(d) == 27 and d["time"][-2:].tolist() == [1.25, 1.255] and d["probe.n"][-2:].tolist() == [25, 26]


def test_an_fmu_ending_the_simulation_10_ns_into_a_step_gets_a_row_of_its_own(probe, tmp_path):
    """An end 10 ns after the communication point at 1.25 s (an event a hair past it) is a time of its own:
    the row there is added after the row at 1.25 s (only an end within a billionth of a step of the last
    row is that row)."""
    res = _run(_sim(probe(ENDS_10NS_INTO_AT=1.25), start=1.0, stop=1.5, step=0.01, record=("probe.n",)),
               tmp_path / "out")
    assert res.status == "terminated" and res.steps == 25 and res.t_end == 1.25 + 1e-8
    d = np.load(tmp_path / "out" / "signals.npy")
    assert len(d) == 27 and d["time"][-1] == 1.25 + 1e-8 and d["probe.n"][-2:].tolist() == [25, 26]


def test_an_fmu_that_ends_and_then_fails_to_give_its_outputs_is_a_failure(probe, tmp_path):
    res = _run(_sim(probe(ENDS_HALFWAY_AT=1.25, GET_FAILS_TERMINATED=True), start=1.0, stop=1.5), tmp_path / "out")
    assert res.status == "failed" and for_status(res.status) == 1
    assert res.message == "probe: get outputs returned Error at t = 1.255 s; last log: (the FMU logged nothing)"
    assert _summary(tmp_path / "out")["message"] == res.message


def test_an_isolated_fmu_dying_mid_run_keeps_the_steps_before_it(probe, tmp_path):
    sim = _sim(probe(SEGFAULT_AT=1.25), start=1.0, stop=1.5)
    sim.document["instances"]["probe"]["isolate"] = True
    res = _run(sim, tmp_path / "out")
    assert res.status == "failed" and res.steps == 25 and res.t_end == pytest.approx(1.25)
    assert "killed by SIGSEGV during fmi2DoStep at t = 1.25 s" in res.message, res.message
    assert len(np.load(tmp_path / "out" / "signals.npy")) == 26


@pytest.mark.parametrize("call, fmi, label, steps", [
    (Call.GET_REAL, 2, "fmi2GetReal", 6), (Call.GET_REAL, 3, "fmi3GetFloat64", 6),
    (Call.GET_RECORDED, 2, "fmi2Get (recorded)", 6), (Call.GET_RECORDED, 3, "fmi3Get (recorded)", 6),
    (Call.DO_STEP, 2, "fmi2DoStep", 7), (Call.DO_STEP, 3, "fmi3DoStep", 7), (Call.SET_REAL, 2, "fmi2SetReal", 7),
    (Call.SET_REAL, 3, "fmi3SetFloat64", 7), (Call.CONNECTION, 2, "fmi2Get/Set (a connection)", 7)])
def test_a_failure_reported_by_the_loop_counts_the_steps_whose_rows_are_recorded(probe, tmp_path, call, fmi, label,
                                                                                 steps):
    """The loop reports a failure at step k = 7 (t = 1.07 s): a get after the step to t_7 means 6 steps
    done (the row at t_7 is missing); a failure before or in the step from t_7 means 7 (rows up to t_7).
    The message names the call as its FMI version does, its status and t_7."""
    run = _sim(probe(), start=1.0, stop=1.5).start(tmp_path / "out")
    try:
        ex = run.execution
        ex.instances["probe"].fmi_version = fmi          # the call named as that FMI version names it
        with pytest.raises(RunError) as err:
            ex._failed(Failure(7, "probe", call, 3))
        assert ex.k_done == steps
        assert str(err.value) == f"probe: {label} returned Error at t = 1.07 s; last log: (the FMU logged nothing)"
    finally:
        run.close()


def test_an_fmi3_fmu_ending_the_simulation_in_a_step_ends_the_run_after_that_steps_row(probe, tmp_path):
    """The loop reports fmi3Terminated at k = 7 after recording the row at t_7: the run ends there,
    terminated by that FMU, with 7 steps and no row added."""
    run = _sim(probe(), start=1.0, stop=1.5).start(tmp_path / "out")
    try:
        ex = run.execution
        with pytest.raises(execution.FmuEnded) as stop:
            ex._failed(Failure(7, "probe", Call.TERMINATED, 0))
        assert (stop.value.name, stop.value.t, stop.value.recorded) == ("probe", 1.07, True)
        rows = ex._recorder.rows
        n = len(rows) + rows.recorder.rows
        ex._end_by(stop.value)
        assert (ex.status, ex.message, ex.k_done) == ("terminated", "terminated by FMU probe at t = 1.07 s", 7)
        assert len(np.load(tmp_path / "out" / "signals.npy")) == n
    finally:
        run.close()


# ---------------------------------------------------------------------- non-finite inputs
def _pair(fmu: Path, u: float, factor: float = 1e300, **event) -> Simulation:
    """a.y = a.u + c feeds b.u through ``factor``; only a.y is recorded."""
    sim = Simulation(file="t.toml").experiment(start=1.0, stop=1.2, step=0.01)
    sim.instance("a", fmu, u=u).instance("b", fmu).connect("a.y", "b.u", factor=factor)
    if event:
        sim.event(**event)
    return sim.record("a.y", csv=False)


def test_a_non_finite_input_at_the_start_fails_before_anything_is_recorded(probe, tmp_path):
    res = _run(_pair(probe(), 1e300), tmp_path / "out")
    assert (res.status, res.steps) == ("failed", 0)
    assert res.message == "a.y produced 1e+300; b.u would receive the non-finite value inf at t = 1 s"
    summary = _summary(tmp_path / "out")
    assert not (tmp_path / "out" / "signals.npy").exists() and (summary["rows"], summary["us_per_step"]) == (0, None)


def test_a_non_finite_input_mid_run_stops_at_the_step_it_would_enter(probe, tmp_path):
    res = _run(_pair(probe(), 1.0, time=1.05, variable="a.u", action="override", value=1e300), tmp_path / "out")
    assert (res.status, res.steps) == ("failed", 5)
    assert res.message == "a.y produced 1e+300; b.u would receive the non-finite value inf at t = 1.05 s"
    assert len(np.load(tmp_path / "out" / "signals.npy")) == 6


def test_without_input_checks_non_finite_inputs_reach_the_fmu(probe, tmp_path):
    for sim in (_pair(probe(), 1e300), _pair(probe(), 1.0, time=1.05, variable="a.u", action="override",
                                              value=1e300)):
        res = _run(sim, tmp_path / "out", check_inputs=False)
        assert (res.status, res.steps) == ("ok", 20), res.message


# ---------------------------------------------------------------------- options of run()
def test_timing_measures_the_time_inside_the_fmi_calls(probe, tmp_path):
    sim = _sim(probe(), stop=0.2)
    assert _run(sim, tmp_path / "a").fmi_s is None                 # not measured by default
    res = _run(sim, tmp_path / "b", timing=True)
    assert isinstance(res.fmi_s, float) and 0.0 < res.fmi_s <= res.wall_s


def test_timed_calls_add_up_each_calls_duration(monkeypatch):
    clock = iter(range(100))
    monkeypatch.setattr(startup._time, "perf_counter", lambda: float(next(clock)))
    acc = [0.5]
    fn = startup.timed(lambda *a: sum(a), acc)
    assert [fn(1, 2), fn(3), fn()] == [3, 3, 0]
    assert acc == [3.5]                  # three calls of one tick each, added to what was there


def test_set_up_time_is_measured_from_load_to_initialised(probe, tmp_path):
    t0 = _time.perf_counter()
    res = _run(_sim(probe()), tmp_path / "out")
    elapsed = _time.perf_counter() - t0
    assert 0.0 < res.setup_s < elapsed and 0.0 < res.wall_s < elapsed
    assert _summary(tmp_path / "out")["setup_s"] == round(res.setup_s, 6)


def test_progress_bar_only_when_asked(probe, tmp_path, capsys):
    pytest.importorskip("tqdm")
    sim = _sim(probe(), stop=0.2)
    execution.run(sim.check(), tmp_path / "a", progress=True)
    err = capsys.readouterr().err
    assert " of 0.2 s" in err and not err.endswith("\n")   # simulated seconds; cleared at the end
    execution.run(sim.check(), tmp_path / "b")                     # default: only on a terminal, long runs
    execution.run(sim.check(), tmp_path / "c", progress=False)
    assert capsys.readouterr().err == ""


def test_a_run_without_a_results_folder_is_kept_in_memory(probe, tmp_path, monkeypatch):
    """``out=None``: no results folder at all (while it runs, the temporary folder holds only the FMUs'
    work folder, removed at the end; nothing is written as results), and the result says what a run into a
    folder says: the same final values, signals, summary and scenario as resolved."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    written = []
    monkeypatch.setattr(execution, "write_results", lambda *a: written.append(a))
    during: list[list[str]] = []
    sim = _sim(probe(), stop=0.1)
    ex = execution.Execution(sim.check(), None, progress=False, keep_signals=True)
    ex.on_step(lambda: during.append(sorted(p.name.rsplit("-", 1)[0] for p in tmp.iterdir())))
    ex.initialize()
    ex.simulate_until()
    res = ex.close()
    assert res.status == "ok" and res.out_dir is None and res.final["probe.y"] == 10.0
    assert written == [] and during and set(map(tuple, during)) == {("wmr-cosim-fmus",)}
    assert list(tmp.iterdir()) == []
    monkeypatch.undo()
    on_disk = execution.run(_sim(probe(), stop=0.1).check(), tmp_path / "out", progress=False)
    assert res.final == on_disk.final and res.scenario == on_disk.scenario
    assert res.signals.tobytes() == np.load(tmp_path / "out" / "signals.npy").tobytes()
    timing = {"wall_s", "setup_s", "us_per_step"}
    assert {k: v for k, v in res.summary.items() if k not in timing} == \
        {k: v for k, v in json.loads((tmp_path / "out" / "summary.json").read_text()).items() if k not in timing}


# ---------------------------------------------------------------------- the event log
def test_the_event_log_names_variable_and_value_when_the_event_has_them(probe, tmp_path):
    sim = _sim(probe(), start=1.0, stop=1.5)
    sim.event(time=1.1, variable="probe.u", action="override", value=2.0)
    sim.event(time=1.2, variable="probe.u", action="reset")
    sim.event(time=1.3, action="stop")
    res = _run(sim, tmp_path / "out")
    assert (res.status, res.message, res.steps, for_status(res.status)) == ("stopped", "stopped by events[2] at t = 1.3 s", 30, 0)
    assert [(e["source"], e["kind"], e["what"]) for e in res.events] == [
        ("events[0]", "scenario", "override probe.u = 2.0"), ("events[1]", "scenario", "reset probe.u"),
        ("events[2]", "scenario", "stop")]
    assert _scenario_fields(res.events) == [{"time": pytest.approx(1.1), "event": 0, "action": "override", "variable": "probe.u",
                           "value": 2.0},
                          {"time": pytest.approx(1.2), "event": 1, "action": "reset", "variable": "probe.u"},
                          {"time": pytest.approx(1.3), "event": 2, "action": "stop"}]
    assert _summary(tmp_path / "out")["events"] == res.events


# ---------------------------------------------------------------------- events on discrete inputs
def test_events_on_integer_enumeration_and_boolean_inputs(tmp_path):
    """Override, bias and reset on non-Real inputs act before the step from their time: a bias adds to
    the value in force (an earlier event's, else the start value: the scenario's parameter or the
    declared start), a reset restores the start value, each input keeps its own value."""
    sim = Simulation(file="t.toml").experiment(start=0.0, stop=0.1, step=0.01)
    sim.instance("a", FEEDTHROUGH, Int32_input=5, Float64_continuous_input=1.5).instance("b", FEEDTHROUGH)
    sim.record("a.Int32_output", "a.Enumeration_output", "b.Int32_output", "b.Boolean_output", csv=False)
    for t, ref, action, value in [(0.01, "b.Boolean_input", "reset", None),      # never set: to its start
                                  (0.02, "a.Int32_input", "bias", 2), (0.02, "b.Int32_input", "bias", 2),
                                  (0.03, "a.Enumeration_input", "override", 2),
                                  (0.04, "a.Int32_input", "bias", 3), (0.04, "b.Boolean_input", "override", True),
                                  (0.05, "a.Int32_input", "reset", None), (0.05, "a.Enumeration_input", "reset", None),
                                  (0.05, "b.Int32_input", "reset", None),
                                  (0.06, "a.Int32_input", "bias", 1)]:
        sim.event(time=t, variable=ref, action=action, **({} if value is None else {"value": value}))
    res = _run(sim, tmp_path / "out")
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    assert d["a.Int32_output"].tolist() == [5, 5, 5, 7, 7, 10, 5, 6, 6, 6, 6]
    assert d["a.Enumeration_output"].tolist() == [1, 1, 1, 1, 2, 2, 1, 1, 1, 1, 1]
    assert d["b.Int32_output"].tolist() == [0, 0, 0, 2, 2, 2, 0, 0, 0, 0, 0]
    assert d["b.Boolean_output"].tolist() == [False] * 5 + [True] * 6


# ---------------------------------------------------------------------- the Python API between steps
@pytest.fixture()
def pair(tmp_path):
    """Feedthrough a feeds b (a Real and an Integer connection); a table drives a.Boolean_input."""
    (tmp_path / "in.csv").write_text("time,a.Boolean_input\n0.0,0\n1.0,1\n")
    sim = Simulation(file=str(tmp_path / "t.toml")).experiment(start=0.0, stop=0.1, step=0.01)
    sim.instance("a", FEEDTHROUGH, Float64_continuous_input=1.5).instance("b", FEEDTHROUGH)
    sim.connect("a.Float64_continuous_output", "b.Float64_continuous_input")
    sim.connect("a.Int32_output", "b.Int32_input")
    sim.document["inputs"] = {"file": str(tmp_path / "in.csv")}
    return sim.record("b.Float64_continuous_output", "a.Int32_output", "b.Boolean_output", csv=False)


def test_set_refuses_what_cannot_change_during_a_run_in_one_line(pair):
    with pair.start() as run:
        run.step_to(0.02)
        for ref, value, message in [
                ("a.Float64_fixed_parameter", 1.0, "a.Float64_fixed_parameter is a fixed parameter: only tunable "
                                                   "parameters change during a run"),
                ("b.Int32_input", 3, "b.Int32_input is driven by a connection or a table: it cannot be set"),
                ("a.Boolean_input", True, "a.Boolean_input is driven by a connection or a table: it cannot be set"),
                ("b.Float64_continuous_output", 1.0, "b.Float64_continuous_output is an output that feeds no "
                                                     "connection: setting it would change nothing"),
                ("a.time", 1.0, "a.time is independent: only inputs, outputs feeding connections and tunable "
                                "parameters can be set between steps")]:
            with pytest.raises(CosimError) as err:
                run.set(ref, value)
            assert str(err.value) == message
        res = run.finish()
    assert res.status == "ok"


def test_get_reads_outputs_from_the_last_communication_point_and_other_variables_from_the_fmu(pair):
    """A recorded Float64 output is read from the row of the last communication point; a recorded input
    (or anything else) through an FMI get, so a value set between steps reads back at once. (The
    feedthrough FMU's output would already follow the new input: the row keeps the step's value.)"""
    pair.record("a.Float64_continuous_input", "a.Float64_continuous_output")
    with pair.start() as run:
        run.step_to(0.02)
        run.set("a.Float64_continuous_input", 4.0)
        assert run.get("a.Float64_continuous_input") == 4.0
        assert run.get("a.Float64_continuous_output") == 1.5
        run.step()
        assert run.get("a.Float64_continuous_output") == 4.0
        res = run.finish()
    assert res.status == "ok", res.message


def test_a_real_connection_listed_after_an_integer_one_is_made(tmp_path):
    sim = Simulation(file=str(tmp_path / "t.toml")).experiment(start=0.0, stop=0.03, step=0.01)
    sim.instance("a", FEEDTHROUGH, Float64_continuous_input=2.5, Int32_input=3).instance("b", FEEDTHROUGH)
    sim.connect("a.Int32_output", "b.Int32_input")
    sim.connect("a.Float64_continuous_output", "b.Float64_continuous_input")
    res = sim.record("b.Float64_continuous_output", "b.Int32_output", csv=False).run()
    assert res["b.Float64_continuous_output"].tolist()[1:] == [2.5] * 3
    assert res["b.Int32_output"].tolist()[1:] == [3] * 3


def test_set_and_release_between_steps(pair):
    """An override of a connected input or of an output feeding one acts from the next step until it
    is released; an input nothing drives is set on the FMU and held (an event's bias adds to it)."""
    pair.event(time=0.08, variable="a.Int32_input", action="bias", value=1)
    with pair.start() as run:
        run.step_to(0.02)
        run.set("a.Int32_input", 4)                  # drives b.Int32_input through the connection
        run.set("b.Boolean_input", True)             # the table drives a's, not b's
        run.set("a.Float64_tunable_parameter", 2.0)
        run.set("b.Float64_continuous_input", 7.0)
        run.step()
        assert run.get("b.Float64_continuous_output") == 7.0
        run.release("b.Float64_continuous_input")
        run.step()
        assert run.get("b.Float64_continuous_output") == 1.5
        run.set("a.Float64_continuous_output", 9.0)
        run.step()
        assert run.get("b.Float64_continuous_output") == 9.0
        run.release("a.Float64_continuous_output")
        run.step()
        assert run.get("a.Float64_discrete_output") == 0.0      # not in the row: read from the FMU
        assert run.get("a.Float64_tunable_parameter") == 2.0
        res = run.finish()
    assert res.status == "ok", res.message
    assert res["b.Float64_continuous_output"].tolist() == [1.5] * 3 + [7.0, 1.5, 9.0] + [1.5] * 5
    assert res["a.Int32_output"].tolist() == [0] * 3 + [4] * 6 + [5] * 2
    assert res["b.Boolean_output"].tolist() == [False] * 3 + [True] * 8


# ---------------------------------------------------------------------- the results folder
def _feedthrough_pair(csv: bool) -> Simulation:
    sim = Simulation(file="t.toml").experiment(start=1.0, stop=1.1, step=0.02)
    sim.instance("a", FEEDTHROUGH, Float64_continuous_input=1.5).instance("b", FEEDTHROUGH)
    sim.connect("a.Float64_continuous_output", "b.Float64_continuous_input", factor=2.0, offset=0.5)
    sim.record("b.Float64_continuous_output", "a.Int32_output", csv=csv)
    sim.event(time=1.04, variable="a.Int32_input", action="override", value=3)
    sim.event(when="b.Float64_continuous_output > 3", delay=0.02, variable="a.Int32_input", action="bias", value=1)
    return sim


def test_scenario_and_summary_files_of_a_run(tmp_path):
    out = tmp_path / "out"
    res = _run(_feedthrough_pair(True), out)
    fmu = str(FEEDTHROUGH)
    scen = json.loads((out / "scenario.json").read_text())
    assert scen.pop("document")["events"][1] == {"when": "b.Float64_continuous_output > 3", "delay": 0.02,
                                                 "variable": "a.Int32_input", "action": "bias", "value": 1}
    inst = {"fmu": fmu, "model": "Feedthrough", "names": {}, "units": {}, "logging": "warning", "tolerance": None,
            "interface": "co-simulation"}
    columns = {"time": {"unit": "s", "instance": None, "fmu": None, "variable": "time"},
               "b.Float64_continuous_output": {"unit": None, "instance": "b", "fmu": "Feedthrough.fmu",
                                               "variable": "Float64_continuous_output"},
               "a.Int32_output": {"unit": None, "instance": "a", "fmu": "Feedthrough.fmu", "variable": "Int32_output"}}
    assert scen.pop("columns") == columns
    assert scen == {
        "file": "t.toml",
        "experiment": {"start": 1.0, "stop": 1.1, "step": 0.02, "algorithm": "gauss-seidel", "order": ["a", "b"], "workers": 1,
                       "tolerance": None},
        "instances": {"a": {**inst, "parameters": {"Float64_continuous_input": 1.5}}, "b": {**inst, "parameters": {}}},
        "connections": [{"from": "a.Float64_continuous_output", "to": "b.Float64_continuous_input", "factor": 2.0,
                         "offset": 0.5}],
        "record": ["b.Float64_continuous_output", "a.Int32_output"], "decimation": 1,
        "events": [{"time": 1.04, "variable": "a.Int32_input", "action": "override", "value": 3},
                   {"time": None, "variable": "a.Int32_input", "action": "bias", "value": 1,
                    "when": "b.Float64_continuous_output > 3", "trigger": "once", "delay": 0.02}]}
    summary = json.loads((out / "summary.json").read_text())
    assert summary.pop("columns") == columns
    wall, setup, per_step = summary.pop("wall_s"), summary.pop("setup_s"), summary.pop("us_per_step")
    from wmr_cosim.cosim.stepping import native
    stepping = summary.pop("stepping")   # which loop ran: the compiled one where a C compiler is at hand
    lib, why = native.library()
    assert stepping == {"algorithm": "gauss-seidel",
                        "loop": native.NATIVE if lib is not None else f"{native.PYTHON} ({why})"}
    assert wall == round(res.wall_s, 6) and setup == round(res.setup_s, 6)
    assert per_step == round(res.wall_s / 5 * 1e6, 3) and per_step > 0
    events = [{"time": 1.02, "source": "events[1]", "kind": "condition", "event": 1, "action": "bias",
               "variable": "a.Int32_input", "value": 1, "when": "b.Float64_continuous_output > 3",
               "condition_time": 1.0,
               "what": "bias a.Int32_input = 1 (when b.Float64_continuous_output > 3: true at t = 1 s)"},
              {"time": 1.04, "source": "events[0]", "kind": "scenario", "event": 0, "action": "override",
               "variable": "a.Int32_input", "value": 3, "what": "override a.Int32_input = 3"}]
    final = {"time": 1.1, "b.Float64_continuous_output": 3.5, "a.Int32_output": 3}
    counts = {"fmu": fmu, "model": "Feedthrough", "interface": "co-simulation", "log_lines": 0, "log_received": 0}
    assert summary == {"status": "ok", "message": "", "steps": 5, "n_steps": 5, "t_end": 1.1, "step": 0.02,
                       "algorithm": "gauss-seidel", "rows": 6, "instances": {"a": counts, "b": counts},
                       "final": final, "not_recorded": [], "events": events}
    assert (res.status, res.steps, res.t_end, res.final, res.events, res.out_dir) == ("ok", 5, 1.1, final, events, out)
    assert res.columns == ["time", "b.Float64_continuous_output", "a.Int32_output"] and res.real_time is None
    assert (out / "signals.csv").read_text().splitlines()[-1] == "1.1,3.5,3"


def test_a_second_run_into_a_folder_leaves_nothing_of_the_first(tmp_path):
    out = tmp_path / "out"
    _run(_feedthrough_pair(True), out)
    (out / "logs" / "old.log").write_text("from an earlier run\n")
    (out / "mine.txt").write_text("kept\n")
    res = _run(_feedthrough_pair(False), out)
    assert res.status == "ok"
    assert sorted(p.name for p in out.iterdir()) == ["logs", "mine.txt", "scenario.json", "signals.npy",
                                                     "summary.json"]
    assert sorted(p.name for p in (out / "logs").iterdir()) == ["a.log", "b.log"]


# ---------------------------------------------------------------------- non-finite outputs, Ctrl-C, progress
def test_a_non_finite_recorded_output_fails_the_run_at_its_time(probe, tmp_path):
    """y = 10 u + c with u overridden to 1e308 from t = 1.05 s: y is inf at 1.06 s; the run fails there
    (6 steps), the rows up to and with the non-finite value are on disk."""
    sim = _sim(probe(), start=1.0, stop=1.2, p=10.0)
    sim.event(time=1.05, variable="probe.u", action="override", value=1e308)
    res = _run(sim, tmp_path / "out")
    assert (res.status, res.steps, for_status(res.status)) == ("failed", 6, 1)
    assert res.message == "probe.y is inf at t = 1.06 s (a non-finite output)"
    d = np.load(tmp_path / "out" / "signals.npy")
    assert len(d) == 7 and d["probe.y"][-1] == math.inf and np.all(np.isfinite(d["probe.y"][:-1]))


def test_ctrl_c_handling_sets_a_flag_first_and_interrupts_at_the_second():
    import signal

    before = signal.getsignal(signal.SIGINT)
    stop = Interrupt()
    try:
        assert signal.getsignal(signal.SIGINT) == stop._handler
        stop.check()                                   # nothing pending
        stop._handler(signal.SIGINT, None)             # the first: only noted
        with pytest.raises(KeyboardInterrupt):
            stop.check()
        with pytest.raises(KeyboardInterrupt):
            stop._handler(signal.SIGINT, None)         # the second: at once
    finally:
        stop.restore()
    assert signal.getsignal(signal.SIGINT) == before
    stop.restore()                                     # a second restore changes nothing
    assert signal.getsignal(signal.SIGINT) == before


def test_the_default_progress_bar_is_for_long_runs_on_a_terminal(monkeypatch):
    pytest.importorskip("tqdm")
    import sys

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert progress_bar(None, 5000, 0.002) is None
    bar = progress_bar(None, 5001, 0.002)
    try:
        assert bar is not None and bar.total == 5001 * 0.002     # in simulated seconds
    finally:
        bar.close()
    assert progress_bar(False, 10 ** 6, 0.002) is None
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert progress_bar(None, 10 ** 6, 0.002) is None
    bar = progress_bar(True, 3, 0.5, internal=3000)
    try:
        assert bar is not None and bar.total == 1.5
        assert "(3e+03 internal steps)" in str(bar)
    finally:
        bar.close()


def test_the_initial_exchange_settles_a_chain_against_its_order(probe, tmp_path):
    """a -> b -> c stepped in the order c, b, a: at the start time every input already has the value of
    the output feeding it (the exchange repeats until nothing changes), so the first row is the fixed
    point: y = p u (c = 0)."""
    sim = Simulation(file="t.toml").experiment(start=0.0, stop=0.02, step=0.01, order=["c", "b", "a"])
    fmu = probe()
    sim.instance("a", fmu, u=2.0, p=3.0).instance("b", fmu, p=2.0).instance("c", fmu, p=0.5)
    sim.connect("a.y", "b.u").connect("b.y", "c.u")
    res = _run(sim.record("a.y", "b.y", "c.y", csv=False), tmp_path / "out")
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    assert (d["a.y"][0], d["b.y"][0], d["c.y"][0]) == (6.0, 12.0, 6.0)


def test_release_ends_the_override_of_that_variable_only(probe, tmp_path):
    """b.b (Boolean) and b.u (Real) share a value reference: releasing b.b leaves b.u's override alone."""
    sim = Simulation(file="t.toml").experiment(start=0.0, stop=0.05, step=0.01)
    sim.instance("a", probe(), u=1.0).instance("b", probe(aliased=True)).connect("a.y", "b.u")
    with sim.record("b.y", csv=False).start(tmp_path / "out") as run:
        run.set("b.u", 100.0)
        run.step()
        run.release("b.b")
        run.step()
        run.release("b.u")
        run.step()
        res = run.finish()
    assert res["b.y"].tolist() == [1.0, 101.0, 102.0, 7.0, 9.0, 11.0]   # b.y = b.u + steps; b.u = a.y = 1 + steps


def test_a_non_finite_output_before_a_stop_event_fails_the_run(probe, tmp_path):
    """The recording is checked when it is flushed: a stop event at 1.1 s ends the run, and the flush
    that follows finds y = inf at 1.06 s: the run failed there, not stopped."""
    sim = _sim(probe(), start=1.0, stop=1.2, p=10.0)
    sim.event(time=1.05, variable="probe.u", action="override", value=1e308)
    sim.event(time=1.1, action="stop")
    res = _run(sim, tmp_path / "out")
    assert (res.status, res.steps, res.message) == ("failed", 6, "probe.y is inf at t = 1.06 s (a non-finite output)")
    assert len(np.load(tmp_path / "out" / "signals.npy")) == 7


# ---------------------------------------------------------------------- events on conditions
def test_condition_events_fire_on_rising_edges_with_their_delay(probe, tmp_path):
    """a.u is switched 1, 0, 1 by timed events; conditions are evaluated after every step (and at the
    start): 'each' acts at every rising edge, 'once' at the first only, a delay acts at the first
    communication point at or after it, a condition true at the start acts before the first step, and
    an action due after the last step never acts."""
    fmu = probe()
    sim = Simulation(file="t.toml").experiment(start=1.0, stop=1.1, step=0.01)
    sim.instance("a", fmu).instance("b", fmu)
    for t, v in ((1.02, 1.0), (1.04, 0.0), (1.06, 1.0)):
        sim.event(time=t, variable="a.u", action="override", value=v)
    sim.event(when="a.u > 0.5", trigger="each", variable="b.u", action="bias", value=1.0)
    sim.event(when="a.u > 0.5", trigger="once", delay=0.015, variable="b.u", action="bias", value=10.0)
    sim.event(when="t >= 1.0", variable="b.u", action="bias", value=100.0)
    sim.event(when="t > 1.085", delay=0.01, variable="b.u", action="bias", value=1000.0)
    res = _run(sim.record("b.y", csv=False), tmp_path / "out")
    assert res.status == "ok", res.message
    assert np.load(tmp_path / "out" / "signals.npy")["b.y"].tolist() == [0.0, 101.0, 102.0, 103.0, 105.0, 106.0,
                                                                         117.0, 118.0, 120.0, 121.0, 122.0]
    bias = {"action": "bias", "variable": "b.u"}
    assert {e["kind"] for e in res.events if "when" in e} == {"condition"}
    assert _scenario_fields(res.events) == [
        {"time": 1.0, "event": 5, **bias, "value": 100.0, "when": "t >= 1.0", "condition_time": 1.0},
        {"time": 1.02, "event": 0, "action": "override", "variable": "a.u", "value": 1.0},
        {"time": 1.03, "event": 3, **bias, "value": 1.0, "when": "a.u > 0.5", "condition_time": 1.03},
        {"time": 1.04, "event": 1, "action": "override", "variable": "a.u", "value": 0.0},
        {"time": 1.05, "event": 4, **bias, "value": 10.0, "when": "a.u > 0.5", "condition_time": 1.03},
        {"time": 1.06, "event": 2, "action": "override", "variable": "a.u", "value": 1.0},
        {"time": 1.07, "event": 3, **bias, "value": 1.0, "when": "a.u > 0.5", "condition_time": 1.07}]


def test_decimation_records_every_nth_step_and_the_last(probe, tmp_path):
    sim = _sim(probe(), start=1.0, stop=1.1, record=("probe.n",))
    sim.document["record"]["decimation"] = 3
    res = _run(sim, tmp_path / "out")
    d = np.load(tmp_path / "out" / "signals.npy")
    assert d["probe.n"].tolist() == [0, 3, 6, 9, 10] and res.steps == 10
    assert _summary(tmp_path / "out")["rows"] == 5


def test_real_time_pacing_reports_its_figures(probe, tmp_path):
    res = _run(_sim(probe(), stop=0.05), tmp_path / "out", real_time=1000.0)
    assert res.status == "ok" and res.real_time is not None and res.real_time["factor"] == 1000.0
    assert res.real_time["steps"] == 5
    assert _summary(tmp_path / "out")["real_time"] == res.real_time
    assert _run(_sim(probe(), stop=0.05), tmp_path / "b").real_time is None      # not paced by default
    assert "real_time" not in _summary(tmp_path / "b")
