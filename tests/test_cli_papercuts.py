"""Command-line papercuts: ``--set`` one item per use (a positional argument after it stays the scenario),
a key without an instance for a scenario of one FMU, "did you mean" for near names, readable ``--help``,
``direct --stop``, and built FMUs that ship only the platforms that are built and tested (linux64, and
win64 for FMI 2.0 where MinGW-w64 is installed)."""
from __future__ import annotations

import zipfile

import pytest

from wmr_cosim.fmus.build import SLAVES, SLAVES3, build_all


def test_a_built_fmu_ships_only_the_tested_platforms(built_fmus):
    """linux64, and win64 (our loader and pythonfmu's DLL) where MinGW-w64 is installed: never pythonfmu's
    Windows DLL alone."""
    from wmr_cosim.fmus.build import REAL_BINARY_WINDOWS, windows_compiler

    for model, fmu in built_fmus.items():
        with zipfile.ZipFile(fmu) as zf:
            names = [n for n in zf.namelist() if n.startswith("binaries/") and n.count("/") >= 2]
        platforms = {n.split("/")[1] for n in names}
        assert platforms == ({"linux64", "win64"} if windows_compiler() else {"linux64"}), (model, platforms)
        if windows_compiler():
            assert sorted(n for n in names if "/win64/" in n) == sorted(
                [f"binaries/win64/{model}.dll", f"binaries/win64/{REAL_BINARY_WINDOWS}"])


def test_a_built_fmi3_fmu_ships_no_windows_binary(tmp_path):
    fmu = build_all(tmp_path, models=("WmrSensor3",))["WmrSensor3"]
    with zipfile.ZipFile(fmu) as zf:
        platforms = {n.split("/")[1] for n in zf.namelist() if n.startswith("binaries/") and n.count("/") >= 2}
    assert platforms == {"x86_64-linux"}


# ------------------------------------------------------------------------------------------- --set
from reference_fmus import REF  # noqa: E402
from wmr_cosim.cli import build_parser, main  # noqa: E402

FT, DQ, BB = (REF / "fmi2" / f"{m}.fmu" for m in ("Feedthrough", "Dahlquist", "BouncingBall"))


@pytest.fixture
def good(tmp_path, monkeypatch):
    """A scenario of two instances (a: Feedthrough, d: Dahlquist), 10 steps; the test runs in its folder."""
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "good.toml"
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances.a]\nfmu = "{FT}"\n[instances.d]\n'
                    f'fmu = "{DQ}"\n[record]\nvariables = ["d.k"]\n')
    return path


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_a_scenario_after_set_is_the_scenario_not_a_value(good, capsys):
    assert main(["check", "--set", "d.k=2.0", str(good)]) == 0, capsys.readouterr().err
    assert main(["run", "--set", "d.k=2.0", "--set", "a.Float64_tunable_parameter=3", str(good),
                 "--out", "o", "--quiet"]) == 0, capsys.readouterr().err
    import numpy as np
    assert np.load(good.parent / "o" / "signals.npy")["d.k"][0] == 2.0


def test_set_takes_one_item_per_use(good, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["check", str(good), "--set", "d.k=2.0", "a.Float64_tunable_parameter=3"])
    assert exc.value.code == 2 and "unrecognized arguments: a.Float64_tunable_parameter=3" in capsys.readouterr().err


def test_a_key_without_an_instance_is_the_variable_of_a_single_fmu(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["check", str(BB), "--set", "e=0.5"]) == 0, capsys.readouterr().err
    assert main(["check", str(BB), "--set", "e=2"]) == 2
    assert "instances.BouncingBall.parameters.e: value 2.0 is above the maximum 1.0" in _err(capsys)


def test_a_key_without_an_instance_is_refused_when_there_are_several(good, capsys):
    assert main(["check", str(good), "--set", "k=2"]) == 2
    assert _err(capsys).endswith("--set k: 'k' is not of the form \"instance.variable\"")


@pytest.mark.parametrize("item, words", [
    ("d.kk=1", "d (Dahlquist.fmu) has no variable 'kk' (did you mean 'k'?)"),
    ("dd.k=1", "--set dd.k: unknown instance 'dd' (did you mean 'd'?)"),
    ("d.zzz=1", "has no variable 'zzz'"),
])
def test_a_near_name_is_suggested(item, words, good, capsys):
    assert main(["check", str(good), "--set", item]) == 2
    err = _err(capsys)
    assert err.endswith(words) or words in err, err
    if "zzz" in item:
        assert "did you mean" not in err


def test_direct_suggests_a_near_parameter(capsys):
    assert main(["direct", "G1", "--set", "controller.gama=8"]) == 2
    assert _err(capsys).endswith("controller has no parameter 'gama' (did you mean 'gamma'?)")
    assert main(["direct", "G1", "--set", "contoller.gamma=8"]) == 2
    assert _err(capsys).endswith("(did you mean 'controller'?)")


# ------------------------------------------------------------------------------------------- --help
def _help(capsys, *argv: str) -> str:
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--help"])
    assert exc.value.code == 0
    return capsys.readouterr().out


def test_help_shows_no_restructured_text_and_run_takes_ssp_and_fmu(capsys):
    top = _help(capsys)
    assert "``" not in top and "The wmr-cosim command line." in top
    run = " ".join(top[top.index("\n    run "):top.index("\n    check ")].split())   # (the line may wrap)
    assert run == "run run a scenario (.toml), SSP archive (.ssp) or FMU (.fmu)", run
    for cmd in ("direct", "build", "run", "check", "export-ssp", "info", "paper", "sweep", "gamma-search"):
        assert "``" not in _help(capsys, cmd), cmd


def test_every_option_of_every_command_has_a_help():
    import argparse

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = [(name, a.option_strings or a.dest) for name, p in sub.choices.items() for a in p._actions
               if a.help is None]
    assert missing == []


def test_direct_takes_stop_as_run_does_and_t_stop_still_works(capsys):
    import json

    assert main(["direct", "G1", "--stop", "0.01", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["steps"] == 5
    assert main(["direct", "G1", "--t-stop", "0.02", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["steps"] == 10
    h = _help(capsys, "direct")
    assert "--stop" in h and "--t-stop" not in h


def test_output_into_a_closed_pipe_ends_quietly(built_fmus):
    """`wmr-cosim info X.fmu | head -1`: a reader that closes the pipe early ends the command with the
    shell's status for SIGPIPE (141) and no traceback."""
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-c", "from wmr_cosim.cli import entry; entry()", "info",
                          str(built_fmus["WmrController"])], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()                    # the reader is gone before the command writes
    err = p.stderr.read().decode()
    p.stderr.close()
    assert p.wait(timeout=60) == 141, err
    assert "Traceback" not in err and "BrokenPipeError" not in err, err


def test_archive_limits_of_the_command_line_are_passed_down_not_kept(tmp_path, capsys, monkeypatch):
    """--max-archive-size reaches the run's checks as an argument: nothing is left in the environment (the
    commands whose runs happen in worker processes send the limits with the work: tests/test_security.py)."""
    import os

    for name in ("WMR_COSIM_MAX_ARCHIVE_SIZE", "WMR_COSIM_MAX_ARCHIVE_RATIO"):
        monkeypatch.delenv(name, raising=False)
    assert main(["--max-archive-size", "1 KiB", "check", str(DQ)]) == 2
    assert "more than the limit of 1 KiB" in capsys.readouterr().err
    assert not {"WMR_COSIM_MAX_ARCHIVE_SIZE", "WMR_COSIM_MAX_ARCHIVE_RATIO"} & set(os.environ)
    assert main(["check", str(DQ)]) == 0          # the next command has the defaults again
    capsys.readouterr()
