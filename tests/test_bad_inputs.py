"""A corpus of bad inputs (scenario files, command lines, output folders, archives): each gets exit code 2
(or 1 for a run that fails), one line on stderr naming the file or option, the field and the reason, no
traceback, and nothing left in the temporary folder or outside --out."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

from c_fmu_support import build_probe
from wmr_cosim.cli import main

from reference_fmus import REF
FT, DQ = REF / "fmi2" / "Feedthrough.fmu", REF / "fmi2" / "Dahlquist.fmu"

HEAD = f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances.a]\nfmu = "{FT}"\n[instances.d]\nfmu = "{DQ}"\n'
CONN = '[[connections]]\nfrom = "d.x"\nto = "a.Float64_continuous_input"\n'

#: name -> (scenario text or bytes, [expected words in the one line])
SCENARIOS: dict[str, tuple[str | bytes, list[str]]] = {
    "binary file": (os.urandom(4000), ["not a text file"]),
    "deep nesting": ("x = " + "[" * 5000 + "]" * 5000 + "\n", ["nested too deeply"]),
    "not toml": ("[experiment\n", ["not valid TOML"]),
    "unknown top key": ("stuff = 1\n" + HEAD, ["stuff", "unknown key"]),
    "a sweep file": ('base = "x.toml"\nsamples = 3\n', ["a sweep file", "wmr-cosim sweep"]),
    "a paper manifest": ('[tasks]\nG1 = "paper/g1.toml"\n', ["paper manifest", "wmr-cosim paper"]),
    "base missing": ('base = "nowhere.toml"\n' + HEAD, ["base", "nowhere.toml", "file not found"]),
    "base name too long for the system": ('base = "' + "b" * 5000 + '.toml"\n' + HEAD, ["base", "name too long"]),
    "base a folder": ('base = "."\n' + HEAD, ["base", "a folder"]),
    "replace without a base": ('replace = ["connections"]\n' + HEAD, ["replace", "this file has no base"]),
    "replace not an array": ('base = "g1_learn.toml"\nreplace = "connections"\n', ["replace", "must be an array"]),
    "replace of an unknown list": ('base = "g1_learn.toml"\nreplace = ["conections"]\n',
                                   ["replace", "did you mean 'connections'?"]),
    "an empty list over a base": ('base = "g1_learn.toml"\nconnections = []\n',
                                  ["connections", "adds nothing to the base's 11 connections", "replace = "]),
    "step negative": (HEAD.replace("step = 0.01", "step = -0.01"), ["experiment.step", "must be > 0"]),
    "step denormal": (HEAD.replace("step = 0.01", "step = 1e-320"), ["experiment.step", "not a finite number"]),
    "too many steps": (HEAD.replace("step = 0.01", "step = 1e-9"), ["experiment.step", "max_steps", "--force"]),
    "stop huge": (HEAD.replace("stop = 0.1", "stop = 1e300"), ["experiment.step"]),
    "stop before start": (HEAD.replace("stop = 0.1", "stop = 0.1\nstart = 1.0"), ["experiment.stop", "not after"]),
    "stop infinite": (HEAD.replace("stop = 0.1", "stop = inf"), ["experiment.stop", "finite"]),
    "algorithm unknown": (HEAD.replace("step = 0.01", 'step = 0.01\nalgorithm = "newton"'),
                          ["experiment.algorithm", "must be one of"]),
    "order with a number": (HEAD.replace("step = 0.01", 'step = 0.01\norder = ["a", 1]'),
                            ["experiment.order", "every instance"]),
    "order missing one": (HEAD.replace("step = 0.01", 'step = 0.01\norder = ["a"]'), ["experiment.order"]),
    "unknown experiment key": (HEAD.replace("step = 0.01", "step = 0.01\nstpe = 1"), ["experiment.stpe", "unknown key"]),
    "tolerance negative": (HEAD.replace("step = 0.01", "step = 0.01\ntolerance = -1"), ["experiment.tolerance"]),
    "max_steps zero": (HEAD.replace("step = 0.01", "step = 0.01\nmax_steps = 0"), ["experiment.max_steps"]),
    "no instances": ("[experiment]\nstop = 1.0\n", ["instances", "no FMU instances"]),
    "instances not a table": ('instances = "plant"\n', ["instances", "must be a table"]),
    "instances an array": ('instances = [1, 2]\n', ["instances", "must be a table"]),
    "instance not a table": ("[experiment]\nstop = 1.0\n[instances]\na = 3\n", ["instances.a", "must be a table"]),
    "instance name with a dash": (f'[instances."a-b"]\nfmu = "{FT}"\n', ["must be an identifier"]),
    "instance name of 300 characters": (f'[instances.{"a" * 300}]\nfmu = "{FT}"\n', ["at most 100"]),
    "fmu missing": ("[instances.a]\nparameters = {}\n", ["instances.a.fmu", "missing"]),
    "fmu file not found": ('[instances.a]\nfmu = "nope.fmu"\n', ["instances.a.fmu", "not found"]),
    "fmu unknown model": ('[instances.a]\nfmu = "NoSuchModel"\n', ["instances.a.fmu", "unknown model name"]),
    "unknown instance key": (HEAD.replace(f'fmu = "{DQ}"', f'fmu = "{DQ}"\nparams = 1'), ["instances.d.params"]),
    "unknown parameter": (HEAD + "[instances.d.parameters]\nkk = 1.0\n", ["instances.d.parameters.kk", "no variable"]),
    "parameter of the wrong type": (HEAD + '[instances.d.parameters]\nk = "fast"\n', ["parameters.k", "type mismatch"]),
    "parameter not finite": (HEAD + "[instances.d.parameters]\nk = nan\n", ["parameters.k", "not finite"]),
    "a calculated output set": (HEAD + "[instances.a.parameters]\nFloat64_continuous_output = 1.0\n",
                                ["Float64_continuous_output", "calculated"]),
    "names not a string": (HEAD + "[instances.d.names]\nx = 3\n", ["instances.d.names.x", "must map"]),
    "names onto one name": (HEAD + '[instances.d.names]\nx = "y"\nk = "y"\n', ["instances.d.names", "same name"]),
    "names onto a taken name": (HEAD + '[instances.d.names]\nx = "k"\n', ["instances.d.names.x", "already the name"]),
    "names unknown variable": (HEAD + '[instances.d.names]\nq = "r"\n', ["instances.d.names.q", "no variable"]),
    "units not a string": (HEAD + "[instances.d.units]\nx = 1\n", ["instances.d.units.x", "unit name"]),
    "logging level unknown": (HEAD.replace(f'fmu = "{DQ}"', f'fmu = "{DQ}"\nlogging = "loud"'),
                              ["instances.d.logging", "must be one of"]),
    "connection without to": (HEAD + '[[connections]]\nfrom = "d.x"\n', ["connections[0].to", "missing"]),
    "connection unknown instance": (HEAD + '[[connections]]\nfrom = "q.x"\nto = "a.Float64_continuous_input"\n',
                                    ["connections[0].from", "unknown instance"]),
    "connection unknown variable": (HEAD + '[[connections]]\nfrom = "d.xx"\nto = "a.Float64_continuous_input"\n',
                                    ["connections[0].from", "no variable"]),
    "connection from a parameter": (HEAD + '[[connections]]\nfrom = "d.k"\nto = "a.Float64_continuous_input"\n',
                                    ["connections[0].from", "not an output"]),
    "connection to an output": (HEAD + '[[connections]]\nfrom = "d.x"\nto = "a.Float64_continuous_output"\n',
                                ["connections[0].to", "not an input"]),
    "connection driven twice": (HEAD + CONN + CONN, ["connections[1].to", "already driven"]),
    "connection type mismatch": (HEAD + '[[connections]]\nfrom = "d.x"\nto = "a.Int32_input"\n',
                                 ["connections[0]", "type mismatch"]),
    "connection factor not finite": (HEAD + CONN + "factor = inf\n", ["connections[0].factor", "finite"]),
    "connection convert not a boolean": (HEAD + CONN + 'convert = "yes"\n', ["connections[0].convert"]),
    "record not a list": (HEAD + '[record]\nvariables = "d.x"\n', ["record.variables"]),
    "record matches nothing": (HEAD + '[record]\nvariables = ["d.z*"]\n', ["record.variables[0]", "matches no output"]),
    "record unknown instance": (HEAD + '[record]\nvariables = ["q.x"]\n', ["record.variables[0]", "unknown instance"]),
    "record a string": (HEAD + '[record]\nvariables = ["a.String_output"]\n', ["record.variables[0]", "String"]),
    "decimation zero": (HEAD + "[record]\ndecimation = 0\n", ["record.decimation"]),
    "csv not a boolean": (HEAD + '[record]\ncsv = "no"\n', ["record.csv"]),
    "recording too large": (HEAD + "[record]\nmax_bytes = 10\n", ["record", "max_bytes", "--force"]),
    "events not an array": ("events = 3\n" + HEAD, ["events", "array of tables"]),
    "connections not an array": ("connections = 3\n" + HEAD, ["connections", "array of tables"]),
    "event action unknown": (HEAD + '[[events]]\ntime = 0.05\nvariable = "a.Float64_continuous_input"\n'
                             'action = "shove"\nvalue = 1\n', ["events[0].action"]),
    "event without value": (HEAD + '[[events]]\ntime = 0.05\nvariable = "a.Float64_continuous_input"\n',
                            ["events[0].value", "missing"]),
    "reset with a value": (HEAD + '[[events]]\ntime = 0.05\nvariable = "a.Float64_continuous_input"\n'
                           'action = "reset"\nvalue = 1\n', ["events[0].value", "no value"]),
    "event at the stop time": (HEAD + '[[events]]\ntime = 0.1\nvariable = "a.Float64_continuous_input"\nvalue = 1\n',
                               ["events[0].time", "never act"]),
    "event on a parameter": (HEAD + '[[events]]\ntime = 0.05\nvariable = "d.k"\nvalue = 1\n',
                             ["events[0].variable", "input or output"]),
    "inputs file missing": (HEAD + '[inputs]\nfile = "none.csv"\n', ["inputs.file", "not a file"]),
    "inputs interpolation unknown": (HEAD + '[inputs]\nfile = "in.csv"\ninterpolation = { "a.Float64_continuous_input" '
                                     '= "cubic" }\n', ["inputs.interpolation", "linear or hold"]),
    "inputs column unknown": (HEAD + '[inputs]\nfile = "bad_col.csv"\n', ["inputs.a.nothing", "no variable"]),
    "inputs value not a number": (HEAD + '[inputs]\nfile = "bad_val.csv"\n', ["inputs.a.Int32_input", "not a valid"]),
    "inputs integer out of range": (HEAD + '[inputs]\nfile = "big.csv"\n', ["inputs.a.Int32_input", "does not fit"]),
    "run without a name": (HEAD + "[[runs]]\nparameters = {}\n", ["runs[0].name"]),
    "run name of 300 characters": (HEAD + f'[[runs]]\nname = "a"\n[[runs]]\nname = "{"r" * 300}"\n',
                                   ["runs[1].name", "at most 100"]),
    "two runs of one name": (HEAD + '[[runs]]\nname = "r"\n[[runs]]\nname = "r"\n', ["runs[1].name", "two runs"]),
    "carry from no run": (HEAD + '[[runs]]\nname = "r"\ncarry = { "d.k" = "q.d.x" }\n', ["runs[0].carry", "no earlier run"]),
}


@pytest.fixture
def sandbox(tmp_path, monkeypatch):
    """A working folder, and a temporary folder of its own that must be empty at the end."""
    work, tmp = tmp_path / "work", tmp_path / "tmp"
    work.mkdir()
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    monkeypatch.setenv("TMPDIR", str(tmp))
    monkeypatch.chdir(work)
    (work / "in.csv").write_text("time,a.Float64_continuous_input\n0,1\n1,2\n")
    (work / "bad_col.csv").write_text("time,a.nothing\n0,1\n")
    (work / "bad_val.csv").write_text("time,a.Int32_input\n0,one\n")
    (work / "big.csv").write_text("time,a.Int32_input\n0,9223372036854775807\n")
    yield work, tmp
    assert not list(tmp.iterdir()), f"left in the temporary folder: {list(tmp.iterdir())}"


def _one_line(capsys, code: int, expected_code: int, words: list[str]) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == expected_code, (code, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.mark.parametrize("case", sorted(SCENARIOS))
def test_bad_scenario_file(case, sandbox, capsys):
    work, _ = sandbox
    text, words = SCENARIOS[case]
    path = work / "bad.toml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    before = sorted(p.name for p in work.iterdir())
    for cmd in ("check", "run"):
        argv = [cmd, str(path)] + (["--out", str(work / "out"), "--quiet"] if cmd == "run" else [])
        line = _one_line(capsys, main(argv), 2, words)
        assert str(path) in line or "base" in words
        assert sorted(p.name for p in work.iterdir()) == before   # no results folder for a refused scenario


@pytest.mark.parametrize("argv, words", [
    (["run", "nowhere.toml"], ["nowhere.toml", "file not found"]),
    (["check", "."], ["a folder"]),
    (["check", "s" * 5000 + ".toml"], ["name too long"]),
    (["run", "s" * 5000 + ".toml"], ["name too long"]),
    (["run", "{good}", "--set", "d.k"], ["--set", "expected INSTANCE.PARAM=VALUE"]),
    (["run", "{good}", "--set", "q.k=1"], ["--set q.k", "unknown instance"]),
    (["run", "{good}", "--set", "d.kk=1"], ["no variable 'kk'"]),
    (["run", "{good}", "--variant", "fast"], ["--variant fast", "not declared"]),
    (["run", "{good}", "--input", "in.csv"], ["--input", "single FMU"]),
    (["run", "{good}", "--out", "{file}"], ["--out", "not a folder"]),
    (["run", "{good}", "--out", "{file}/sub"], ["--out", "cannot write"]),
    (["run", "{good}", "--out", "/proc/wmr-cosim-out"], ["--out", "cannot write"]),
    (["run", str(FT), "--input", "bad_col.csv", "--out", "o"], ["bad_col.csv", "no variable"]),
    (["run", str(FT), "--set", "Feedthrough.Float64_fixed_parameter=x"], ["type mismatch"]),
    (["gamma-search", "{good}"], ["gamma-search needs a protocol"]),
    (["run", "{flat}", "--set", "a.k=1"], ["instances.a", "must be a table"]),
    (["run", "{good}", "--algorithm", "jacobi"], ["--algorithm", "--set experiment.algorithm=jacobi"]),
    (["check", "--tolerance", "1e-4", "{good}"], ["--tolerance", "--set experiment.tolerance=1e-4"]),
])
def test_bad_command_line(argv, words, sandbox, capsys):
    work, _ = sandbox
    good = work / "good.toml"
    good.write_text(HEAD)
    (work / "afile").write_text("x")
    (work / "flat.toml").write_text("[instances]\na = 3\n")
    argv = [a.format(good=good, file=work / "afile", flat=work / "flat.toml") for a in argv]
    _one_line(capsys, main(argv), 2, words)


@pytest.mark.parametrize("argv, words", [
    (["run", "{good}", "--live", "--port", "70000"], ["--port", "'70000'", "0 (any free port) to 65535"]),
    (["run", "{good}", "--live", "--port", "x"], ["--port", "'x'", "a port number"]),
    (["run", "{good}", "--live", "--port", "-1"], ["--port"]),
    (["run", "{good}", "--live", "--host", "nohost"], ["--host", "'nohost'", "an IP address"]),
    (["run", "{good}", "--live", "--host", "127.0.0.1:80"], ["--host", "an IP address"]),
    (["run", "{good}", "--port", "8000"], ["--port goes with --live"]),
    (["run", "{good}", "--host", "0.0.0.0"], ["--host goes with --live"]),
    (["run", "{good}", "--paused"], ["--paused goes with --live"]),
    (["run", "{good}", "--open"], ["--open goes with --live"]),
    (["run", "{protocol}", "--live"], ["--live serves a single run", "a protocol of 2 runs"]),
    (["check", "{good}", "--live"], ["unrecognized arguments: --live"]),
    (["sweep", "{good}", "--live"], ["unrecognized arguments: --live"]),
])
def test_bad_live_options(argv, words, sandbox, capsys):
    """run --live's options: bad values, without --live, with what cannot be served (a protocol), or given to
    another command: one line, exit 2, before anything runs or listens."""
    work, _ = sandbox
    (work / "good.toml").write_text(HEAD)
    (work / "protocol.toml").write_text(HEAD + '[[runs]]\nname = "a"\n[[runs]]\nname = "b"\n')
    argv = [a.format(good=work / "good.toml", protocol=work / "protocol.toml") for a in argv] + ["--out", "o"] * (
        argv[0] == "run")
    try:
        code = main(argv)
    except SystemExit as exc:   # (argparse's refusals)
        code = int(exc.code or 0)
    _one_line(capsys, code, 2, words)
    assert not (work / "o").exists()


def test_live_without_its_extra_is_refused(sandbox, capsys, monkeypatch):
    import importlib.util

    work, _ = sandbox
    (work / "good.toml").write_text(HEAD)
    find = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "uvicorn" else find(name, *a))
    _one_line(capsys, main(["run", str(work / "good.toml"), "--out", "o", "--live"]), 2,
              ["--live needs uvicorn", "pip install 'wmr-cosim[live]'"])
    assert not (work / "o").exists()


def test_repeated_set_options_add_up(sandbox, capsys):
    work, _ = sandbox
    good = work / "good.toml"
    good.write_text(HEAD + "[record]\nvariables = [\"d.k\", \"a.Float64_tunable_parameter\"]\n")
    assert main(["run", str(good), "--out", "o", "--quiet", "--set", "d.k=2.0",
                 "--set", "a.Float64_tunable_parameter=3.0"]) == 0
    import numpy as np
    d = np.load(work / "o" / "signals.npy")
    assert d["d.k"][0] == 2.0 and d["a.Float64_tunable_parameter"][0] == 3.0


def test_unicode_instance_names_run_everywhere(sandbox, capsys):
    work, _ = sandbox
    path = work / "u.toml"
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances."pläntλ"]\nfmu = "{DQ}"\n'
                    f'[instances."pläntλ".names]\nx = "größe"\n', encoding="utf-8")
    assert main(["run", str(path), "--out", "o", "--quiet"]) == 0, capsys.readouterr().err
    import numpy as np
    d = np.load(work / "o" / "signals.npy")
    assert "pläntλ.größe" in d.dtype.names and (work / "o" / "logs" / "pläntλ.log").is_file()
    assert (work / "o" / "signals.csv").read_text(encoding="utf-8").startswith("time,pläntλ.größe")


def test_a_second_run_into_the_same_folder_is_refused(sandbox, capsys):
    from wmr_cosim.cosim.results.recording import OutputLock

    work, _ = sandbox
    good = work / "good.toml"
    good.write_text(HEAD)
    (work / "o").mkdir()
    with OutputLock(work / "o"):  # another run holds the folder
        line = _one_line(capsys, main(["run", str(good), "--out", "o", "--quiet"]), 2, ["in use", str(os.getpid())])
        assert "o" in line
    assert main(["run", str(good), "--out", "o", "--quiet"]) == 0   # released: the folder is usable again


def test_an_fmu_with_a_range_and_units_refuses_bad_values(sandbox, capsys, tmp_path_factory):
    fmu = build_probe(tmp_path_factory.mktemp("probe"))
    work, _ = sandbox
    for extra, words in (('[instances.p.parameters]\np = 11.0\n', ["parameters.p", "above the maximum"]),
                         (f'[instances.q]\nfmu = "{fmu}"\nunits = {{ y = "s" }}\n[[connections]]\nfrom = "q.y"\n'
                          f'to = "p.u"\n', ["instances.q.units.y", "contradicts the unit"]),
                         (f'[instances.q]\nfmu = "{fmu}"\nunits = {{ y = "s" }}\noverride_declared_units = true\n'
                          f'[[connections]]\nfrom = "q.y"\nto = "p.u"\n', ["connections[0]", "unit mismatch"])):
        path = work / "p.toml"
        path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\n[instances.p]\nfmu = "{fmu}"\n' + extra)
        _one_line(capsys, main(["check", str(path)]), 2, words)


# ------------------------------------------------------------------------------- runs that share or lose a folder
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

_RSS = ("import resource, sys; from wmr_cosim.cli import main; code = main(sys.argv[1:]); "
        "print('maxrss', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr); sys.exit(code)")


def _long(work: Path, steps: int, csv: bool = True, columns: int = 3) -> Path:
    """Dahlquist feeding a chain of Feedthroughs for ``steps`` steps, recording every output."""
    text = f'[experiment]\nstop = {steps * 0.001!r}\nstep = 0.001\n[instances.d]\nfmu = "{DQ}"\n'
    prev = "d.x"
    for i in range(columns):
        text += f'[instances.f{i}]\nfmu = "{FT}"\n[[connections]]\nfrom = "{prev}"\nto = "f{i}.Float64_continuous_input"\n'
        prev = f"f{i}.Float64_continuous_output"
    text += f'[record]\ncsv = {"true" if csv else "false"}\n'
    path = work / f"long_{steps}_{csv}.toml"
    path.write_text(text)
    return path


def _start(args: list[str], cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", _RSS, *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_two_concurrent_runs_into_one_folder(sandbox):
    work, tmp = sandbox
    path = _long(work, 300_000)
    first = _start(["run", str(path), "--out", "o", "--quiet"], work)
    deadline = time.time() + 30
    while not (work / "o" / ".wmr-cosim.lock").exists() and time.time() < deadline:
        time.sleep(0.02)
    second = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "run", str(path), "--out", "o", "--quiet"],
                            cwd=work, capture_output=True, text=True)
    out, err = first.communicate(timeout=120)
    assert first.returncode == 0, err
    assert second.returncode == 2 and f"process {first.pid}" in second.stderr, second.stderr
    assert len(second.stderr.strip().splitlines()) == 1
    import numpy as np
    d = np.load(work / "o" / "signals.npy")
    assert len(d) == 300_001 and np.all(np.diff(d["time"]) > 0)


#: The command line, stopped (SIGSTOP) at the moment it would give the written CSV its name: the test
#: kills it there, deterministically, however fast the machine writes.
_STOP_BEFORE_THE_CSV_IS_NAMED = r"""
import os, signal, sys
_replace = os.replace
def _stop_first(src, dst, *args, **kwargs):
    if str(dst).endswith("signals.csv"):
        os.kill(os.getpid(), signal.SIGSTOP)
    return _replace(src, dst, *args, **kwargs)
os.replace = _stop_first
from wmr_cosim.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_a_kill_while_the_csv_is_written_leaves_no_partial_csv(sandbox):
    work, _ = sandbox
    path = _long(work, 100_000, columns=8)
    p = subprocess.Popen([sys.executable, "-c", _STOP_BEFORE_THE_CSV_IS_NAMED, "run", str(path), "--out", "o",
                          "--quiet"], cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    part = work / "o" / "signals.csv.part"
    deadline = time.time() + 120
    stopped = False
    while time.time() < deadline and p.poll() is None and not stopped:
        time.sleep(0.01)
        stopped = Path(f"/proc/{p.pid}/stat").read_text().split(")")[-1].split()[0] == "T"
    assert stopped, f"the run did not stop before naming its CSV: {p.communicate()}"
    assert part.stat().st_size > 0
    p.send_signal(signal.SIGKILL)
    p.communicate(timeout=30)
    assert not (work / "o" / "signals.csv").exists()      # no truncated file under the result's name
    import numpy as np
    assert len(np.load(work / "o" / "signals.npy")) == 100_001   # the recording is whole
    part.unlink()


_CSV_RSS = """
import resource, sys
import numpy as np
from wmr_cosim.cosim.results.recording import write_csv
npy, csv = sys.argv[1], sys.argv[2]
rows = 500_000
data = np.lib.format.open_memmap(npy, mode="w+", dtype=[("time", "<f8")] + [(f"c{i}", "<f8") for i in range(8)],
                                 shape=(rows,))
for i in range(0, rows, 50_000):   # (written in slices: this process never holds the whole table)
    k = np.arange(i, min(i + 50_000, rows), dtype=float)
    data["time"][i:i + 50_000] = k * 0.001
    for j in range(8):
        data[f"c{j}"][i:i + 50_000] = np.sin(k * (j + 1) * 1e-3) / 3.0
data.flush()
del data
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
write_csv(npy, csv, start=0.0, step=0.001)
print(before, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def test_the_csv_writer_needs_bounded_memory(tmp_path):
    """500,000 rows of 9 columns (a 500 s run at 1 ms) to a 75 MB CSV: the writer's peak memory grows by
    less than 40 MB (the whole table as Python floats would take some 150 MB; a chunk of 20,000 rows, 6 MB)."""
    p = subprocess.run([sys.executable, "-c", _CSV_RSS, str(tmp_path / "s.npy"), str(tmp_path / "s.csv")],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    before, after = map(int, p.stdout.split())
    size = (tmp_path / "s.csv").stat().st_size
    assert size > 50e6
    with open(tmp_path / "s.csv") as fh:
        assert fh.readline() == "time,c0,c1,c2,c3,c4,c5,c6,c7\n"
        assert fh.readline().startswith("0.0,0.0,")
    assert (after - before) * 1024 < 40e6, (before, after)


def test_sweep_gamma_search_and_paper_folders_are_locked_too(sandbox, capsys):
    from wmr_cosim.cosim.results.recording import OutputLock

    work, _ = sandbox
    root = Path(__file__).resolve().parents[1] / "scenarios"
    (work / "s").mkdir()
    with OutputLock(work / "s"):   # another sweep holds the folder: refused before any cluster starts
        _one_line(capsys, main(["sweep", str(root / "sweep-geometry.toml"), "--out", "s", "--quiet"]), 2,
                  ["in use", f"process {os.getpid()}"])
        _one_line(capsys, main(["gamma-search", str(root / "paper" / "g1.toml"), "--out", "s", "--quiet"]), 2,
                  ["in use", f"process {os.getpid()}"])
        _one_line(capsys, main(["paper", "--out", "s", "--quiet", "--no-compare"]), 2,
                  ["in use", f"process {os.getpid()}"])
