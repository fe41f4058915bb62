"""Out-of-process instances: an FMU that crashes, aborts, exits or hangs inside a step, hosted in a child
process (isolate = true), gives one line naming the instance, the time and how it died, exit code 1, and
the recording complete up to the last finished step; the other instances are terminated and freed. The
same FMUs in process take the master down: that is what isolation is for. Isolated runs are bit-identical
to in-process runs."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from c_fmu_support import build_probe
from cosim_support import write_scenario

from reference_fmus import REF as _REF
from wmr_cosim.paper import robot_system

REF = _REF / "fmi2"


@pytest.fixture(params=["c", "python"])
def child(request, monkeypatch) -> str:
    """Which child serves the isolated C FMU: the C child (its step in C on both sides), or the Python child
    (``WMR_COSIM_CHILD=python``): each crash is reported the same way by both."""
    if request.param == "python":
        monkeypatch.setenv("WMR_COSIM_CHILD", "python")
    else:
        monkeypatch.delenv("WMR_COSIM_CHILD", raising=False)
        from wmr_cosim.cosim.instances import slot_c

        if slot_c.library_path() is None:
            pytest.skip("no C child here (no C compiler)")
    return request.param


def _scenario(tmp: Path, fmu: Path, isolate: bool, extra: str = "") -> Path:
    return write_scenario(tmp / f"iso_{isolate}.toml", f'''
[experiment]
stop = 0.5
step = 0.01
[instances.d]
fmu = "{REF / 'Dahlquist.fmu'}"
[instances.probe]
fmu = "{fmu}"
isolate = {"true" if isolate else "false"}
{extra}
[instances.f]
fmu = "{REF / 'Feedthrough.fmu'}"
[[connections]]
from = "d.x"
to = "probe.u"
[[connections]]
from = "probe.y"
to = "f.Float64_continuous_input"
[record]
variables = ["d.x", "probe.y", "probe.n", "f.Float64_continuous_output"]
''')


def _run(path: Path, out: Path, timeout: float = 120, tmp: Path | None = None) -> subprocess.CompletedProcess:
    """The run in a fresh process; ``tmp`` its temporary folder (a master that dies leaves its extracted
    FMUs there)."""
    import os

    env = dict(os.environ, TMPDIR=str(tmp)) if tmp is not None else None
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "run", str(path), "--out", str(out), "--quiet"],
                          capture_output=True, text=True, timeout=timeout, env=env)


@pytest.mark.parametrize("flag, how", [("SEGFAULT_AT", "killed by SIGSEGV"), ("ABORT_AT", "killed by SIGABRT"),
                                       ("EXIT_AT", "exited with code 3")])
def test_a_crash_in_an_isolated_fmu_is_one_line_and_keeps_the_recording(flag, how, child, tmp_path):
    fmu = build_probe(tmp_path / "fmu", **{flag: 0.25})
    p = _run(_scenario(tmp_path, fmu, True), tmp_path / "out")
    assert p.returncode == 1 and "Traceback" not in p.stderr, p.stderr
    first = p.stderr.strip().splitlines()[0]
    assert "probe" in first and how in first and "t = 0.25 s" in first, first
    d = np.load(tmp_path / "out" / "signals.npy")
    assert len(d) == 26 and d["time"][-1] == pytest.approx(0.25)      # every step before the crash
    assert d["probe.n"][-1] == 25
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["status"] == "failed" and s["steps"] == 25


@pytest.mark.parametrize("flag, extra", [("SEGFAULT_AT", ""), ("ABORT_AT", ""), ("EXIT_AT", ""),
                                         ("HANG_AT", "step_timeout = 1.0")])
def test_the_c_child_and_the_python_child_report_a_crash_alike(flag, extra, tmp_path, monkeypatch):
    """The same one line and exit code for each crash, whichever child hosts the FMU."""
    from wmr_cosim.cosim.instances import slot_c

    if slot_c.library_path() is None:
        pytest.skip("no C child here (no C compiler)")
    fmu = build_probe(tmp_path / "fmu", **{flag: 0.25})
    seen = []
    for child in ("c", "python"):
        monkeypatch.setenv("WMR_COSIM_CHILD", child)
        p = _run(_scenario(tmp_path, fmu, True, extra), tmp_path / child)
        seen.append((p.returncode, p.stderr.strip().splitlines()[0]))
    assert seen[0] == seen[1] and seen[0][0] == 1, seen


def test_an_isolated_c_fmu_is_served_by_the_c_child(tmp_path, monkeypatch):
    """A C FMU's isolated instance: the master's side of its slot in C (the compiled loop calls it directly);
    not with WMR_COSIM_CHILD=python, nor for a pythonfmu FMU."""
    from fmpy import extract, read_model_description

    from wmr_cosim.cosim.instances import slot_c
    from wmr_cosim.cosim.instances.isolation import IsolatedInstance
    from wmr_cosim.runner import resolve_model

    if slot_c.library_path() is None:
        pytest.skip("no C child here (no C compiler)")
    fmus = {"c": build_probe(tmp_path / "fmu"), "pythonfmu": resolve_model("WmrSensor")}
    served = {}
    for env in ("", "python"):
        monkeypatch.setenv("WMR_COSIM_CHILD", env)
        for kind, fmu in fmus.items():
            inst = IsolatedInstance("x", read_model_description(str(fmu), validate=False),
                                    extract(str(fmu), unzipdir=str(tmp_path / f"{kind}{env}")), None, "warning", 60.0, 0)
            try:
                inst.instantiate()
                fp = inst.fast_path([], 0, [], 0)
                served[(kind, env)] = inst.child.c_side is not None and fp.abi == 2
            finally:
                inst.shutdown()
    assert served == {("c", ""): True, ("pythonfmu", ""): False, ("c", "python"): False,
                      ("pythonfmu", "python"): False}


def test_a_hang_in_an_isolated_fmu_is_ended_after_its_step_timeout(child, tmp_path):
    fmu = build_probe(tmp_path / "fmu", HANG_AT=0.25)
    p = _run(_scenario(tmp_path, fmu, True, "step_timeout = 2.0"), tmp_path / "out")
    assert p.returncode == 1 and "did not answer within 2 s" in p.stderr and "t = 0.25 s" in p.stderr, p.stderr
    assert len(np.load(tmp_path / "out" / "signals.npy")) == 26


def test_a_second_ctrl_c_during_a_hung_isolated_step_interrupts_the_run(child, tmp_path):
    """Ctrl-C twice while an isolated FMU hangs in its step: the run ends interrupted (exit code 130, the
    steps before kept), with either child: the C child's wait, in C, asks Python whether the signal's
    handler raised.  (The hung child is then asked to shut down, which takes the step timeout.)"""
    import signal
    import time

    fmu = build_probe(tmp_path / "fmu", HANG_AT=0.25)
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "wmr_cosim.cli", "run",
                          str(_scenario(tmp_path, fmu, True, "step_timeout = 15.0")), "--out", str(out), "--quiet"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        for _ in range(600):   # the child started (its output file made), then the hang reached
            if list(tmp_path.rglob("probe.log.stdout")):
                break
            time.sleep(0.05)
        time.sleep(3.0)
        p.send_signal(signal.SIGINT)
        time.sleep(0.3)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        assert p.returncode == 130 and "interrupted by the user at t = 0.25 s" in err, (p.returncode, err)
    finally:   # (the master and its hung child, should the run not have ended)
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        p.communicate()


def test_a_child_slower_to_start_than_the_step_timeout_is_not_ended(child, tmp_path, monkeypatch):
    """The child's start (here made 1.5 s slower by a sitecustomize on its path) is not held to a step
    timeout of 1 s: the run completes, bit-identical to the run in process."""
    fmu = build_probe(tmp_path / "fmu")
    slow = tmp_path / "slow"
    slow.mkdir()
    (slow / "sitecustomize.py").write_text("import time\ntime.sleep(1.5)\n")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(slow), os.environ.get("PYTHONPATH")])))
    p = _run(_scenario(tmp_path, fmu, True, "step_timeout = 1.0"), tmp_path / "iso")
    assert p.returncode == 0, p.stderr
    monkeypatch.delenv("PYTHONPATH")
    q = _run(_scenario(tmp_path, fmu, False), tmp_path / "inproc")
    assert q.returncode == 0, q.stderr
    assert np.array_equal(np.load(tmp_path / "iso" / "signals.npy"), np.load(tmp_path / "inproc" / "signals.npy"))


def test_junk_on_stdout_from_an_isolated_fmu_goes_to_a_file(child, tmp_path):
    fmu = build_probe(tmp_path / "fmu", JUNK_AT=0.25)
    p = _run(_scenario(tmp_path, fmu, True), tmp_path / "out")
    assert p.returncode == 0 and "junk from an FMU" not in p.stdout, p.stdout
    assert b"junk from an FMU" in (tmp_path / "out" / "logs" / "probe.log.stdout").read_bytes()


@pytest.mark.parametrize("flag", ["SEGFAULT_AT", "EXIT_AT"])
def test_the_same_crash_in_process_takes_the_master_down(flag, tmp_path):
    """What isolation is for: in process the master dies with the FMU (no summary is written)."""
    fmu = build_probe(tmp_path / "fmu", **{flag: 0.25})
    (tmp_path / "tmp").mkdir()
    p = _run(_scenario(tmp_path, fmu, False), tmp_path / "out", tmp=tmp_path / "tmp")
    assert p.returncode in (-11, 3), (p.returncode, p.stderr)
    assert list((tmp_path / "tmp").glob("wmr-cosim-fmus-*"))   # it could not even clean up
    assert not (tmp_path / "out" / "summary.json").exists()


def test_isolated_runs_are_bit_identical_to_in_process_runs(child, tmp_path):
    fmu = build_probe(tmp_path / "fmu")
    for iso in (True, False):
        p = _run(_scenario(tmp_path, fmu, iso, 'parameters = { p = 2.5 }'), tmp_path / f"out{iso}")
        assert p.returncode == 0, p.stderr
    a, b = (np.load(tmp_path / f"out{iso}" / "signals.npy") for iso in (True, False))
    assert a.dtype == b.dtype and all(np.array_equal(a[n], b[n]) for n in a.dtype.names)
    assert a["probe.y"][0] == 2.5   # the initialisation reached the child: y = p u with u = x(0) = 1


def test_g1_with_every_instance_isolated_is_bit_identical(tmp_path):
    """Our own (pythonfmu) FMUs, each in a child process (--isolate): the same recording bit for bit."""
    from cosim_support import G1

    path = write_scenario(tmp_path / "g1.toml", f'base = "{G1}"\n[experiment]\nstop = 1.0\n[record]\ncsv = false\n')
    for iso in ([], ["--isolate"]):
        p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "run", str(path), "--out",
                            str(tmp_path / f"o{bool(iso)}"), "--quiet", *iso], capture_output=True, text=True,
                           timeout=300)
        assert p.returncode == 0, p.stderr
    a, b = (np.load(tmp_path / f"o{iso}" / "signals.npy") for iso in (True, False))
    assert len(a) == 501 and all(np.array_equal(a[n], b[n]) for n in a.dtype.names)
    assert all((tmp_path / "oTrue" / "logs" / f"{n}.log.stdout").exists() for n in ("plant", "sensor", "controller"))
    assert not (tmp_path / "oFalse" / "logs" / "plant.log.stdout").exists()


def test_the_python_api_steps_and_reads_an_isolated_instance(child, tmp_path):
    """Stepwise control over an isolated FMU: read a value between steps, the same as in process."""
    from wmr_cosim import Simulation

    fmu = build_probe(tmp_path / "fmu")
    values = {}
    for iso in (True, False):
        sim = Simulation.load(_scenario(tmp_path, fmu, iso))
        run = sim.start(out=tmp_path / f"api{iso}")
        try:
            run.step_to(0.2)
            values[iso] = (run.get("probe.n"), run.get("probe.y"), run.get("d.x"))
        finally:
            run.close()
    assert values[True] == values[False] and values[True][0] == 20


@pytest.mark.slow
def test_a_sweep_point_whose_isolated_fmu_crashes_is_a_failed_row(child, tmp_path):
    """The crash ends that point's run, not the Dask worker: the other points run and the table has the
    failed row with its reason."""
    from wmr_cosim.studies.sweep import run_sweep

    fmu = build_probe(tmp_path / "fmu", SEGFAULT_AT=0.25)
    base = _scenario(tmp_path, fmu, True)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "{base}"\nmetrics = []\n[grid]\n"probe.p" = [1.0, 2.0]\n')
    df = run_sweep(sweep, tmp_path / "out", workers=1, progress=False, system=robot_system())
    assert len(df) == 2 and set(df["status"]) == {"failed"}, df[["status", "reason"]]
    assert all("killed by SIGSEGV" in r for r in df["reason"]), list(df["reason"])
