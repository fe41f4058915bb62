"""Experiment overrides of run and check: --start, --stop, --step (and FMPy's --start-time, --stop-time,
--output-interval), --record (--output-variables) and ``--set experiment.FIELD=VALUE``, for a scenario, a
protocol, an SSP archive and a single FMU alike, judged by the same checks as the file's own values."""
from __future__ import annotations

import re

import numpy as np
import pytest

from reference_fmus import REF
from wmr_cosim.cli import main

FT, DQ, BB = (REF / "fmi2" / f"{m}.fmu" for m in ("Feedthrough", "Dahlquist", "BouncingBall"))
#: Dahlquist and Feedthrough, 0.1 s of 0.01 s steps, d.x recorded, an event at 0.08 s.
SCENARIO = (f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances.d]\nfmu = "{DQ}"\n[instances.a]\nfmu = "{FT}"\n'
            '[record]\nvariables = ["d.x"]\n[[events]]\ntime = 0.08\nvariable = "a.Float64_continuous_input"\n'
            'value = 1.0\n')
PROTOCOL = SCENARIO + '[[runs]]\nname = "one"\n[[runs]]\nname = "two"\nparameters = { "d.k" = 2.0 }\n'


@pytest.fixture
def work(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(SCENARIO)
    (tmp_path / "p.toml").write_text(PROTOCOL)
    return tmp_path


def _steps(capsys, argv: list[str]) -> str:
    """What check says of the steps ("9 steps of 0.01 s"), after asserting it passed."""
    assert main(["check", *argv]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    return re.split(r" events?, ", out)[1].split(" (")[0]


def _refused(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("opts, steps", [
    (["--stop", "0.09"], "9 steps of 0.01 s"),
    (["--stop-time", "0.09"], "9 steps of 0.01 s"),
    (["--step", "0.005"], "20 steps of 0.005 s"),
    (["--output-interval", "0.005"], "20 steps of 0.005 s"),
    (["--start", "0.05"], "5 steps of 0.01 s"),
    (["--start-time", "0.02", "--stop", "0.09", "--step", "0.001"], "70 steps of 0.001 s"),
    (["--set", "experiment.stop=0.09"], "9 steps of 0.01 s"),
    (["--set", "experiment.step=0.02", "--set", "experiment.start=0.02"], "4 steps of 0.02 s"),
    (["--set", "experiment.stop=0.2", "--stop", "0.09"], "9 steps of 0.01 s"),   # the option is the last word
    (["--stop", "0.095"], "10 steps of 0.01 s"),   # the last one short, to the stop time
])
def test_check_of_a_scenario_takes_the_experiment_from_the_command_line(opts, steps, work, capsys):
    assert _steps(capsys, ["s.toml", *opts]) == steps


def test_run_of_a_scenario_is_shortened_regridded_and_recorded_as_told(work, capsys):
    assert main(["run", "s.toml", "--stop", "0.09", "--step", "0.005", "--record", "d.x",
                 "a.Float64_continuous_output", "--out", "o", "--quiet"]) == 0, capsys.readouterr().err
    d = np.load(work / "o" / "signals.npy")
    assert len(d) == 19 and d["time"][-1] == pytest.approx(0.09)
    assert d.dtype.names == ("time", "d.x", "a.Float64_continuous_output")


def test_the_scenario_may_follow_the_record_list(work, capsys):
    assert main(["run", "--record", "a.Float64_continuous_output", "s.toml", "--out", "o", "--quiet"]) == 0, \
        capsys.readouterr().err
    assert np.load(work / "o" / "signals.npy").dtype.names == ("time", "a.Float64_continuous_output")
    assert _steps(capsys, ["--output-variables", "d.x", "a.*", "s.toml"]) == "10 steps of 0.01 s"


@pytest.mark.parametrize("opts, words", [
    (["--stop", "0.05"], "s.toml: events[0].time: 0.08 is outside the run 0.0..0.05 s"),
    (["--start", "0.2"], "s.toml: experiment.stop: 0.1 is not after the start 0.2"),
    (["--set", "experiment.step=-0.01"], "s.toml: experiment.step: must be > 0, not -0.01"),
    (["--stop", "inf"], "s.toml: experiment.stop: must be finite, not inf"),
    (["--set", "experiment.stop=soon"], "s.toml: experiment.stop: must be a number, not 'soon'"),
    (["--set", "experiment.stpo=1"], "s.toml: --set experiment.stpo: unknown experiment field 'stpo' (allowed: "),
    (["--set", "experiment.stpo=1"], "(did you mean 'stop'?)"),
    (["--record", "d.nosuch"], "s.toml: record.variables[0]: d (Dahlquist.fmu) has no variable 'nosuch'"),
    (["--record", "x"], "record.variables[0]: 'x' is not of the form \"instance.variable\""),
])
@pytest.mark.parametrize("cmd", ["check", "run"])
def test_an_override_goes_through_the_checks_of_the_file(cmd, opts, words, work, capsys):
    argv = [cmd, "s.toml", *opts] + (["--out", "o", "--quiet"] if cmd == "run" else [])
    assert words in _refused(capsys, argv)
    assert not (work / "o").exists()


def test_every_run_of_a_protocol_takes_the_overrides(work, capsys):
    assert main(["run", "p.toml", "--stop", "0.09", "--record", "d.x", "a.Float64_continuous_output",
                 "--out", "o", "--quiet"]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "p.toml [one]: ok, 9 steps" in out and "p.toml [two]: ok, 9 steps" in out
    for run in ("one", "two"):
        assert np.load(work / "o" / run / "signals.npy").dtype.names == ("time", "d.x", "a.Float64_continuous_output")
    err = _refused(capsys, ["run", "p.toml", "--stop", "0.05", "--out", "o2", "--quiet"])
    assert "events[0].time: 0.08 is outside the run 0.0..0.05 s" in err and not (work / "o2").exists()
    assert "events[0].time: 0.08 is outside the run" in _refused(capsys, ["check", "p.toml", "--stop", "0.05"])


def test_a_single_fmu_takes_the_overrides_and_names_without_its_instance(work, capsys):
    assert _steps(capsys, [str(BB), "--start", "0.5", "--stop", "1", "--step", "0.05"]) == "10 steps of 0.05 s"
    assert main(["run", str(BB), "--stop", "0.5", "--record", "h", "--out", "o", "--quiet"]) == 0, \
        capsys.readouterr().err
    d = np.load(work / "o" / "signals.npy")
    assert d.dtype.names == ("time", "BouncingBall.h") and len(d) == 51
    assert _steps(capsys, [str(BB), "--step", "0.7"]) == "5 steps of 0.7 s"   # to 3 s: the last 0.2 s


def test_an_ssp_archive_takes_the_overrides(work, capsys):
    assert main(["export-ssp", "s.toml", "--out", "s.ssp"]) == 2   # (timed events cannot be exported)
    capsys.readouterr()
    (work / "q.toml").write_text(SCENARIO.split("[[events]]")[0])
    assert main(["export-ssp", "q.toml", "--out", "q.ssp"]) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert _steps(capsys, ["q.ssp", "--stop", "0.05"]) == "5 steps of 0.01 s"
    assert _steps(capsys, ["q.ssp", "--stop", "0.055"]) == "6 steps of 0.01 s"   # the last 0.005 s


def test_check_of_a_single_fmu_checks_its_input_table_as_run_does(work, capsys):
    (work / "in.csv").write_text("time,Float64_continuous_input\n0,1\n2,3\n")
    (work / "bad.csv").write_text("time,nothing\n0,1\n")
    assert _steps(capsys, [str(FT), "--input", "in.csv", "--stop", "1", "--step", "0.1"]) == "10 steps of 0.1 s"
    for cmd in ("check", "run"):
        err = _refused(capsys, [cmd, str(FT), "--input", "bad.csv"] + (["--out", "o"] if cmd == "run" else []))
        assert "bad.csv" in err and "no variable" in err, err
    assert "--input applies to a single FMU" in _refused(capsys, ["check", "s.toml", "--input", "in.csv"])
