"""What a new user on a fresh clone met: ``--set`` of a key of a nested table
(``experiment.iteration.method``), ``check`` taking the options of ``run`` that change its verdict
(``--isolate``, ``--real-time``, ``--variant``), a table the algorithm does not read after switching
algorithms (accepted, with a note), where a failed run's rows are, the paper job's exit code, Roberts as
co-simulation pointing at its Model Exchange interface, "1 instance", grid times in signals.csv, and the
paper job saying that it builds the FMUs.  (The benchmarks' extra: tests/test_bench_extra.py.)"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from reference_fmus import REF
from wmr_cosim.cli import main

FT, DQ = (REF / "fmi2" / f"{m}.fmu" for m in ("Feedthrough", "Dahlquist"))
OUT, IN = "Float64_continuous_output", "Float64_continuous_input"
#: The ring B.u = 2 A.y + 1, A.u = 0.8 B.y - 3 (|ac| = 1.6: the fixed point diverges, Newton solves it).
A, B, C, D = 2.0, 1.0, 0.8, -3.0
Y_A = (C * B + D) / (1.0 - A * C)


def _ring(folder: Path, algorithm: str = "iterated", table: str = "[experiment.iteration]\n"
          "method = \"fixed-point\"\nmax_iterations = 40\n") -> Path:
    """A scenario of two Feedthrough FMUs in an algebraic loop, 10 steps of 10 ms (its name, relative to
    ``folder``: the current folder)."""
    path = folder / "ring.toml"
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\nalgorithm = "{algorithm}"\n{table}'
                    f'[instances.A]\nfmu = "{FT}"\n[instances.B]\nfmu = "{FT}"\n'
                    f'[[connections]]\nfrom = "A.{OUT}"\nto = "B.{IN}"\nfactor = {A}\noffset = {B}\n'
                    f'[[connections]]\nfrom = "B.{OUT}"\nto = "A.{IN}"\nfactor = {C}\noffset = {D}\n'
                    f'[record]\nvariables = ["A.{OUT}", "B.{OUT}"]\n')
    return Path(path.name)


@pytest.fixture
def work(tmp_path, monkeypatch) -> Path:
    """The test runs in a folder of its own."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ------------------------------------------------------------------ --set of a key of a nested table
def test_set_reaches_a_key_of_experiment_iteration(work, capsys):
    """The fixed point cannot solve the ring; ``--set experiment.iteration.method=newton`` makes the run
    Newton's, which meets the closed form; the resolved scenario says so."""
    ring = _ring(work)
    code, _, err = _run(capsys, "run", str(ring), "--out", "fp", "--quiet")
    assert code == 1 and "did not converge at initialisation" in err
    code, _, err = _run(capsys, "run", str(ring), "--out", "nw", "--quiet", "--set", "experiment.iteration.method=newton")
    assert code == 0, err
    sig = np.load(work / "nw" / "signals.npy")
    assert np.max(np.abs(sig[f"A.{OUT}"] - Y_A)) < 1e-9
    iteration = json.loads((work / "nw" / "scenario.json").read_text())["experiment"]["iteration"]
    assert (iteration["method"], iteration["max_iterations"]) == ("newton", 40)


def test_set_makes_the_nested_table_when_the_file_has_none(work, capsys):
    ring = _ring(work, table="")
    code, out, err = _run(capsys, "check", str(ring), "--set", "experiment.iteration.max_iterations=3",
                          "--set", "experiment.iteration.method=fixed-point")
    assert code == 0, err
    assert "  iterated: fixed-point, relaxation 1, tolerance 1e-10, at most 3 iterations, inputs hold" in out


@pytest.mark.parametrize("item, words", [
    ("experiment.iteration.metod=newton",
     "ring.toml: --set experiment.iteration.metod: unknown experiment.iteration field 'metod' (allowed: inputs, "
     "jacobian, max_iterations, method, relaxation, tolerance) (did you mean 'method'?)"),
    ("experiment.adaptive.tolerance=1e-3",
     "ring.toml: --set experiment.adaptive.tolerance: unknown experiment.adaptive field 'tolerance' (allowed: "
     "atol, coupling, initial_step, max_step, min_step, rtol)"),
    ("experiment.iteration.tolerance=-1", "ring.toml: experiment.iteration.tolerance: -1: must be a number > 0"),
    ("experiment.iteration.method=broyden",
     "ring.toml: experiment.iteration.method: 'broyden': must be one of fixed-point, newton"),
])
def test_a_bad_nested_key_or_value_is_one_line_exit_2(work, capsys, item, words):
    for command in ("check", "run"):
        code, _, err = _run(capsys, command, str(_ring(work)), "--set", item,
                            *(["--out", "o", "--quiet"] if command == "run" else []))
        assert code == 2 and _one_line(err) == f"wmr-cosim: error: {words}", (command, err)
    assert not (work / "o").exists()


# ------------------------------------------------------------------ check takes run's options
def test_check_isolate_checks_what_run_isolate_would_run(work, capsys):
    """Jacobi with workers: under --isolate both instances step at once, without it none is isolated."""
    ring = _ring(work, "jacobi", table="")
    code, out, err = _run(capsys, "check", str(ring), "--workers", "2", "--isolate")
    assert code == 0, err
    assert "note: workers = 2: A, B (isolated) step at once, up to 2 together" in out
    code, out, _ = _run(capsys, "check", str(ring), "--workers", "2")
    assert code == 0 and ("note: workers = 2: no instance is isolated; A, B (C FMUs in this process) in 2 lanes, "
                          "the master's thread and 1 thread") in out
    code, out, err = _run(capsys, "check", str(DQ), "--isolate")
    assert code == 0 and ": ok: 1 instance (Dahlquist)" in out, err


def _protocol(folder: Path, runs: bool = True) -> Path:
    path = folder / ("proto.toml" if runs else "single.toml")
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances.d]\nfmu = "{DQ}"\n[record]\n'
                    f'variables = ["d.x"]\n[variants.slow.parameters]\n"d.k" = 0.5\n'
                    + ('[[runs]]\nname = "a"\n[[runs]]\nname = "b"\n' if runs else ""))
    return Path(path.name)


@pytest.mark.parametrize("options, words", [
    (("--real-time",), "--real-time paces a single run, not a protocol's runs"),
    (("--real-time", "2"), "--real-time paces a single run, not a protocol's runs"),
])
def test_check_refuses_what_run_refuses_of_a_protocol(work, capsys, options, words):
    proto = _protocol(work)
    assert main(["check", str(proto)]) == 0
    capsys.readouterr()
    for command in ("check", "run"):
        code, _, err = _run(capsys, command, str(proto), *options,
                            *(["--out", "o", "--quiet"] if command == "run" else []))
        assert code == 2 and _one_line(err) == f"wmr-cosim: error: {words}", (command, err)


def test_check_refuses_a_variant_where_run_does(work, capsys):
    """A single run that declares variants but no runs, an FMU: --variant is refused by both commands."""
    single = _protocol(work, runs=False)
    for target, words in ((single, f"--variant slow: {single} declares no runs"),
                          (DQ, "--variant slow: only a scenario file (.toml) declares variants")):
        for command in ("check", "run"):
            code, _, err = _run(capsys, command, str(target), "--variant", "slow",
                                *(["--out", "o", "--quiet"] if command == "run" else []))
            assert code == 2 and _one_line(err) == f"wmr-cosim: error: {words}", (command, err)
    code, out, err = _run(capsys, "check", str(_protocol(work)), "--variant", "slow", "--isolate")
    assert code == 0 and "run b: ok: 10 steps, 1 recorded variable" in out, err


# ------------------------------------------------------------------ a table the algorithm does not read
def test_switching_to_gauss_seidel_with_an_iteration_table_is_accepted_with_a_note(work, capsys):
    ring = _ring(work)
    note = ("[experiment.iteration] is not read under algorithm = 'gauss-seidel' (it is read by \"iterated\", and "
            "by \"adaptive\" with coupling = \"iterated\")")
    code, out, err = _run(capsys, "check", str(ring), "--set", "experiment.algorithm=gauss-seidel")
    assert code == 0, err
    assert f"note: {note}" in out.splitlines() and "(gauss-seidel)" in out
    code, out, err = _run(capsys, "run", str(ring), "--set", "experiment.algorithm=gauss-seidel", "--out", "gs",
                          "--quiet")
    assert code == 0 and err.strip() == f"wmr-cosim: note: {note}", err
    resolved = json.loads((work / "gs" / "scenario.json").read_text())["experiment"]
    assert resolved["algorithm"] == "gauss-seidel" and "iteration" not in resolved
    sig = np.load(work / "gs" / "signals.npy")
    assert abs(sig[f"A.{OUT}"][-1] - Y_A) > 1.0      # one pass per step: not the loop's solution
    # the table is still checked as the file's own values are
    code, _, err = _run(capsys, "check", str(ring), "--set", "experiment.algorithm=jacobi",
                        "--set", "experiment.iteration.relaxation=2")
    assert code == 2 and _one_line(err).endswith("ring.toml: experiment.iteration.relaxation: 2.0: must be in (0, 1]")


def test_an_adaptive_table_under_another_algorithm_is_accepted_with_a_note(work, capsys):
    ring = _ring(work, table="[experiment.adaptive]\nrtol = 1e-3\n")
    code, out, err = _run(capsys, "check", str(ring))
    assert code == 0, err
    assert "note: [experiment.adaptive] is not read under algorithm = 'iterated' (it is read by \"adaptive\")" in out


def test_a_protocol_run_prints_the_note_once(work, capsys):
    proto = _protocol(work)
    proto.write_text(proto.read_text().replace("[instances.d]", "[experiment.iteration]\n[instances.d]"))
    code, _, err = _run(capsys, "run", str(proto), "--out", "o", "--quiet")
    assert code == 0 and err.count("wmr-cosim: note: [experiment.iteration] is not read") == 1, err


# ------------------------------------------------------------------ where a failed run's rows are
def test_a_run_that_fails_at_initialisation_says_nothing_was_recorded(work, capsys):
    code, _, err = _run(capsys, "run", str(_ring(work)), "--out", "o", "--quiet")
    assert code == 1
    lines = err.strip().splitlines()
    assert lines[-1] == "ring.toml: failed after 0 steps (t = 0 s); nothing was recorded (its logs are in o/logs)"
    assert not (work / "o" / "signals.npy").exists() and (work / "o" / "logs").is_dir()


def test_a_run_that_fails_mid_run_says_where_its_rows_are(work, capsys):
    """a.y = a.u feeds b.u with a factor of 1e300; at 0.05 s a.u becomes 1e10: b.u would be inf."""
    path = work / "mid.toml"
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances.a]\nfmu = "{FT}"\n[instances.b]\n'
                    f'fmu = "{FT}"\n[[connections]]\nfrom = "a.{OUT}"\nto = "b.{IN}"\nfactor = 1e300\n'
                    f'[[events]]\ntime = 0.05\nvariable = "a.{IN}"\nvalue = 1e10\n[record]\nvariables = ["a.{OUT}"]\n')
    code, _, err = _run(capsys, "run", path.name, "--out", "o", "--quiet")
    assert code == 1
    assert err.strip().splitlines()[-1] == ("mid.toml: failed after 5 steps (t = 0.05 s); what was recorded "
                                            "(6 rows, to t = 0.05 s) is in o")
    assert len(np.load(work / "o" / "signals.npy")) == 6


# ------------------------------------------------------------------ the paper job's exit code
def _metrics(diverged: dict[str, str]) -> dict:
    """One variant's metrics (the parts exit_code reads): every run ok but those in ``diverged``
    ({"G1.frozen": status})."""
    from wmr_cosim.paper.analysis import RUNS

    tasks = {t: {r: {"status": diverged.get(f"{t}.{r}", "ok"), "diverged": f"{t}.{r}" in diverged} for r in RUNS}
             for t in ("G1", "G2")}
    return {"tasks": tasks, "diverged_runs": sorted(diverged)}


@pytest.mark.parametrize("freeze, printed, code", [
    ({}, {}, 0),
    ({}, {"G1.frozen": "diverged", "G1.foam": "diverged", "G2.frozen": "diverged"}, 0),   # the known result
    ({"G2.foam": "diverged"}, {}, 1),                       # the variant asked for diverged
    ({"G2.learn": "failed"}, {}, 1),
    ({}, {"G1.learn": "failed"}, 1),                        # an error is an error in any variant
    ({}, {"G1.learn": "interrupted"}, 1),
])
def test_the_paper_job_exits_1_for_its_own_variant_and_for_errors_only(freeze, printed, code):
    from wmr_cosim.paper.job import exit_code

    variants = {"freeze": _metrics(freeze), "printed": _metrics(printed)}
    assert exit_code(variants, "freeze") == code
    del variants["printed"]["tasks"]["G2"]["foam"]        # a run the job never reported: missing
    assert exit_code(variants, "freeze") == 1
    assert exit_code({"printed": _metrics(printed)}, "printed") == (1 if printed else 0)   # asked for: judged


# ------------------------------------------------------------------ Roberts: its Model Exchange interface
def _without_model_exchange(fmu: Path, dest: Path) -> Path:
    """A copy of ``fmu`` whose model description declares co-simulation only."""
    import re

    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as out:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb"<ModelExchange[^>]*?(/>|>.*?</ModelExchange>)", b"", data, flags=re.DOTALL)
            out.writestr(item, data)
    return dest


def test_roberts_as_co_simulation_points_at_its_model_exchange_interface(work, capsys):
    roberts = REF / "fmi3" / "Roberts.fmu"
    code, _, err = _run(capsys, "check", str(roberts))
    line = _one_line(err)
    assert code == 2 and "takes fixed internal steps of 0.001 s" in line
    assert ("(it also has a Model Exchange interface, which the master integrates with steps of its own: "
            "--solver cvode; or a shorter run: experiment.stop or --stop;") in line
    code, out, err = _run(capsys, "run", str(roberts), "--solver", "cvode", "--out", "o", "--quiet")
    assert code == 0, err                                   # what the line suggests runs
    scenario = work / "rob.toml"
    for extra, how in (("", 'instances.r.solver = "cvode"'),
                       ('interface = "co-simulation"\n', 'instances.r.interface = "model-exchange" and solver = "cvode"')):
        scenario.write_text(f'[experiment]\nstep = 200000.0\n[instances.r]\nfmu = "{roberts}"\n{extra}')
        code, _, err = _run(capsys, "check", str(scenario))
        assert code == 2 and f"with steps of its own: {how}; or a shorter run" in _one_line(err)
    cs_only = _without_model_exchange(roberts, work / "Roberts.fmu")
    code, _, err = _run(capsys, "check", str(cs_only))
    line = _one_line(err)
    assert code == 2 and "takes fixed internal steps" in line and "Model Exchange" not in line and "cvode" not in line
    assert "more than max_internal_steps = 1000000000 (a shorter run: experiment.stop or --stop;" in line


# ------------------------------------------------------------------ singular and plural
def test_counts_of_one_are_singular(work, capsys):
    code, out, err = _run(capsys, "check", str(DQ))
    assert code == 0, err
    assert ": ok: 1 instance (Dahlquist), 0 connections, 1 recorded variable, 0 events, 100 steps of 0.1 s" in out
    code, out, err = _run(capsys, "run", str(DQ), "--stop", "0.1", "--out", "o", "--quiet")
    assert code == 0 and ": ok, 1 step to t = 0.1 s in " in out, err
    code, out, err = _run(capsys, "check", str(_protocol(work)), "--stop", "0.01")
    assert code == 0 and "  run a: ok: 1 step, 1 recorded variable" in out, err
    code, out, err = _run(capsys, "check", str(_ring(work, table="[experiment.iteration]\nmax_iterations = 1\n")))
    assert code == 0 and "at most 1 iteration, inputs hold" in out, err


def test_count_words():
    from wmr_cosim.cosim.messages.words import count
    from wmr_cosim.cosim.stepping.settings import IterationSpec

    assert [count(n, "instance") for n in (0, 1, 2)] == ["0 instances", "1 instance", "2 instances"]
    assert count(1, "recorded variable") == "1 recorded variable" and count(2, "entry", "entries") == "2 entries"
    assert "at most 1 iteration," in IterationSpec(max_iterations=1).describe()
    assert "at most 20 iterations," in IterationSpec().describe()


# ------------------------------------------------------------------ signals.csv: the grid's times
def test_signals_csv_writes_the_grid_times_and_npy_keeps_its_values(work, capsys):
    path = work / "dq.toml"
    path.write_text(f'[experiment]\nstop = 1.0\nstep = 0.1\n[instances.d]\nfmu = "{DQ}"\n[record]\nvariables = ["d.x"]\n')
    assert main(["run", str(path), "--out", "o", "--quiet"]) == 0
    capsys.readouterr()
    times = [line.split(",")[0] for line in (work / "o" / "signals.csv").read_text().splitlines()[1:]]
    assert times == ["0.0", "0.1", "0.2", "0.3", "0.4", "0.5", "0.6", "0.7", "0.8", "0.9", "1.0"]
    npy = np.load(work / "o" / "signals.npy")["time"]
    assert npy[3] == 3 * 0.1 == 0.30000000000000004      # the values as computed stay in signals.npy
    assert [float(t) for t in times] == [round(t, 1) for t in npy]


def test_grid_times_round_only_points_of_the_grid():
    from wmr_cosim.cosim.results.recording import grid_times

    t = np.array([0.0, 0.30000000000000004, 0.6000000000000001, 1.0734, 1.07000000000001])
    assert grid_times(t, 0.0, 0.002).tolist() == [0.0, 0.3, 0.6, 1.0734, 1.07]
    start = np.array([1.0 + k * 0.1 for k in range(4)])     # 1.2000000000000002, 1.3000000000000003
    assert grid_times(start, 1.0, 0.1).tolist() == [1.0, 1.1, 1.2, 1.3]
    third = np.array([1 / 3, 2 / 3])                         # a step whose decimals a float cannot hold
    assert grid_times(third, 0.0, 1 / 3).tolist() == third.tolist()
    assert grid_times(np.array([2.5e-05]), 0.0, 1e-05).tolist() == [2.5e-05]   # off the grid


# ------------------------------------------------------------------ the paper job says it builds
def test_the_paper_job_says_when_it_builds_the_fmus(tmp_path, built_fmus, monkeypatch, capsys):
    from wmr_cosim.paper import job as paper_job
    from wmr_cosim.fmus import build

    calls = []
    monkeypatch.setattr(build, "build_all", lambda out, models: calls.append((out, models)) or {})
    fresh = tmp_path / "fmus"
    paper_job.build_fmus(2, fresh)
    assert capsys.readouterr().err == (f"wmr-cosim paper: building the FMUs (first run): WmrPlant, WmrSensor, "
                                       f"WmrController into {fresh}\n")
    paper_job.build_fmus(3, fresh, progress=False)
    assert capsys.readouterr().err == ""
    built = built_fmus["WmrPlant"].parent                    # built and current: nothing to say
    paper_job.build_fmus(2, built)
    assert capsys.readouterr().err == ""
    assert [models for _, models in calls] == [("WmrPlant", "WmrSensor", "WmrController"),
                                               ("WmrPlant3", "WmrSensor3", "WmrController3"),
                                               ("WmrPlant", "WmrSensor", "WmrController")]


def test_the_paper_job_builds_through_build_fmus_before_its_workers(tmp_path, monkeypatch):
    from wmr_cosim.paper import job as paper_job

    class Built(Exception):
        pass

    def stop(fmi: int, progress: bool = True) -> None:
        raise Built(fmi, progress)

    monkeypatch.setattr(paper_job, "build_fmus", stop)
    with pytest.raises(Built) as exc:
        paper_job.run_paper(tmp_path / "paper", fmi=3, progress=False)
    assert exc.value.args == (3, False)


# ------------------------------------------------------------------ an experiment field given as an option
@pytest.mark.parametrize("argv, words", [
    (["run", "--algorithm", "jacobi", "ring.toml"],
     "run --algorithm: not an option; experiment.algorithm is set with --set experiment.algorithm=jacobi"),
    (["run", "ring.toml", "--algorithm=jacobi", "--out", "o"],
     "run --algorithm: not an option; experiment.algorithm is set with --set experiment.algorithm=jacobi"),
    (["check", "ring.toml", "--tolerance", "1e-6"],
     "check --tolerance: not an option; experiment.tolerance is set with --set experiment.tolerance=1e-6"),
    (["check", "--order", "B", "A", "ring.toml"],
     "check --order: not an option; experiment.order is set with --set experiment.order='[\"B\", \"A\"]'"),
    (["check", "ring.toml", "--max-steps", "5"],
     "check --max-steps: not an option; experiment.max_steps is set with --set experiment.max_steps=5"),
    (["check", "ring.toml", "--max-iterations"],
     "check --max-iterations: not an option; experiment.iteration.max_iterations is set with --set "
     "experiment.iteration.max_iterations=VALUE"),
    (["run", "ring.toml", "--decimation", "2"],
     "run --decimation: not an option; record.decimation is set with --set record.decimation=2"),
])
def test_an_experiment_field_given_as_an_option_gets_the_set_that_sets_it(work, capsys, argv, words):
    _ring(work)
    code, out, err = _run(capsys, *argv)
    assert code == 2 and _one_line(err) == f"wmr-cosim: error: {words} (docs/scenarios.md)", err
    assert not (work / "o").exists()


def test_any_other_unknown_option_is_refused_in_one_line(work, capsys):
    """argparse's refusals (an unknown option, a value of the wrong type, a missing argument) are one line and
    exit code 2 like every other refusal; the usage is what -h prints."""
    _ring(work)
    for argv, words in ((["run", "ring.toml", "--frobnicate", "1"], "unrecognized arguments: --frobnicate 1"),
                        (["run", "ring.toml", "--stop", "abc"], "argument --stop/--stop-time: invalid float value"),
                        (["linearize"], "wmr-cosim linearize: error: the following arguments are required: target"),
                        (["frobnicate"], "invalid choice: 'frobnicate'")):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        err = capsys.readouterr().err
        assert exc.value.code == 2 and err.count("\n") == 1 and words in err, err
        assert err.rstrip().endswith("-h lists the options)") and "usage:" not in err, err


# ------------------------------------------------------------------ run --workers where nothing steps at once
def test_run_with_workers_says_when_nothing_steps_in_parallel(work, capsys):
    """Model Exchange instances (the master's integrator in Python) step one at a time: run says so on
    stderr (a note; the run as without workers); C FMUs under Jacobi step at once: no such note; Gauss-
    Seidel's levels of one instance each: said too."""
    me = _ring(work, "jacobi", table="")
    text = me.read_text().replace(f'fmu = "{FT}"\n', f'fmu = "{FT}"\n', 1)
    Path("me.toml").write_text(text.replace('[instances.A]\n', '[instances.A]\nsolver = "euler"\n')
                               .replace('[instances.B]\n', '[instances.B]\nsolver = "euler"\n'))
    code, _, err = _run(capsys, "run", "me.toml", "--workers", "2", "--out", "me", "--quiet")
    assert code == 0 and _one_line(err) == (
        "wmr-cosim: note: workers = 2, but nothing steps in parallel: A, B on the master's thread alone (a Model "
        "Exchange instance: its integrator runs in Python, which holds the GIL (isolate = true steps it in a "
        "process of its own))"), err
    code, _, err = _run(capsys, "run", "me.toml", "--out", "me1", "--quiet")
    assert code == 0 and err == ""
    assert np.array_equal(np.load(work / "me" / "signals.npy"), np.load(work / "me1" / "signals.npy"))
    code, _, err = _run(capsys, "run", "ring.toml", "--workers", "2", "--out", "c", "--quiet")
    assert code == 0 and "nothing steps in parallel" not in err, err
    Path("chain.toml").write_text(me.read_text().replace('algorithm = "jacobi"', 'algorithm = "gauss-seidel"')
                                  .split("[[connections]]")[0] + f'[[connections]]\nfrom = "A.{OUT}"\nto = "B.{IN}"\n'
                                  f'[record]\nvariables = ["B.{OUT}"]\n')
    code, _, err = _run(capsys, "run", "chain.toml", "--workers", "2", "--out", "g", "--quiet")
    assert code == 0 and _one_line(err) == (
        "wmr-cosim: note: workers = 2, but nothing steps in parallel: under Gauss-Seidel the instances of a level "
        "step at once, and no level has two that can: A | B"), err
