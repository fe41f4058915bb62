"""Crash safety of the master: an FMU failing mid-run (Discard, Fatal), non-finite values, Ctrl-C.
Each stops the run with one line naming the FMU, the time and the status, exits non-zero, never
crashes the host, and leaves on disk everything recorded up to the failure."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cosim_support import build_test_fmu, g1_with_paths


@pytest.fixture(scope="module")
def failer(tmp_path_factory):
    return build_test_fmu("failer.py", tmp_path_factory.mktemp("failer"))


def _scenario(tmp_path: Path, built_fmus, failer: Path, mode: str, t_fail: float = 0.5) -> Path:
    """The G1 loop (its connections, from the base) plus a failing FMU fed by the plant (so it is stepped
    every step)."""
    return g1_with_paths(tmp_path, built_fmus, f"""
[experiment]
stop = 2.0
order = ["plant", "sensor", "controller", "failer"]
[instances.failer]
fmu = "{failer}"
[instances.failer.parameters]
mode = "{mode}"
t_fail = {t_fail}
[[connections]]
from = "plant.alpha1"
to = "failer.x"
[record]
variables = ["plant.*", "controller.u1", "failer.y"]
""", name=f"{mode}.toml", head="")


def _cli(*args: str, env: dict | None = None, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", *args], capture_output=True, text=True,
                          env=env, timeout=timeout)


@pytest.mark.parametrize("mode, status", [("discard", "Discard"), ("fatal", "Fatal")])
def test_fmu_failing_mid_run(mode, status, built_fmus, failer, tmp_path):
    path = _scenario(tmp_path, built_fmus, failer, mode)
    out = tmp_path / "out"
    p = _cli("run", str(path), "--out", str(out), "--quiet")
    assert p.returncode == 1, (p.returncode, p.stderr)   # not a crash (a negative code would be a signal)
    assert "Traceback" not in p.stderr
    first = p.stderr.strip().splitlines()[0]
    assert "failer" in first and "fmi2DoStep" in first and status in first and "t = 0.5" in first, first
    if mode == "discard":
        assert "deliberate failure" in first           # the FMU's last log lines
    else:
        assert "deliberate fatal error" in first
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 250
    data = np.load(out / "signals.npy")                # everything up to the failure is on disk
    assert len(data) == 251 and data["time"][-1] == pytest.approx(0.5)
    assert (out / "signals.csv").read_text().count("\n") == 252
    assert "deliberate" in (out / "logs" / "failer.log").read_text()


def test_nan_output_stops_the_run(built_fmus, failer, tmp_path):
    path = _scenario(tmp_path, built_fmus, failer, "nan")
    out = tmp_path / "out"
    p = _cli("run", str(path), "--out", str(out), "--quiet")
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert "failer.y is nan at t = 0.502" in p.stderr
    assert json.loads((out / "summary.json").read_text())["steps"] == 251
    data = np.load(out / "signals.npy")
    assert np.isnan(data["failer.y"][-1]) and np.all(np.isfinite(data["failer.y"][:-1]))


def test_nonfinite_value_on_a_connection_stops_at_once(built_fmus, tmp_path):
    # an absurd torque override drives the plant to infinity; the first non-finite connected value stops it
    path = g1_with_paths(tmp_path, built_fmus, """
[experiment]
stop = 5.0
[[events]]
time = 0.2
variable = "controller.u1"
action = "override"
value = 1e300
""")
    out = tmp_path / "out"
    p = _cli("run", str(path), "--out", str(out), "--quiet")
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert "non-finite" in p.stderr and "sensor" in p.stderr and "t = 0.2 s" in p.stderr
    assert "plant.alpha" in p.stderr and "produced" in p.stderr   # the output that produced it, named
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 100   # the override acts from step 100
    data = np.load(out / "signals.npy")
    assert len(data) == 101 and np.all(np.isfinite(data["plant.x_A"]))


def test_ctrl_c_stops_cleanly_and_keeps_the_record(built_fmus, tmp_path):
    path = g1_with_paths(tmp_path, built_fmus, "[experiment]\nstop = 600.0\n")
    out = tmp_path / "out"
    env = {**os.environ, "TMPDIR": str(tmp_path / "tmp")}
    (tmp_path / "tmp").mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "wmr_cosim.cli", "run", str(path), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.time() + 60
    while time.time() < deadline:   # wait until the recording has reached the disk
        if (out / "signals.npy").exists() and len(np.load(out / "signals.npy")) > 2500:
            break
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert len(np.load(out / "signals.npy")) == summary["steps"] + 1
    assert list((tmp_path / "tmp").iterdir()) == []     # extraction folders removed


def test_quiet_progress_and_cleanup_when_not_a_terminal(built_fmus, tmp_path):
    path = g1_with_paths(tmp_path, built_fmus, "[experiment]\nstop = 12.0\n")
    (tmp_path / "tmp").mkdir()
    p = _cli("run", str(path), "--out", str(tmp_path / "out"), env={**os.environ, "TMPDIR": str(tmp_path / "tmp")})
    assert p.returncode == 0, p.stderr
    assert p.stderr == ""                                # no progress bar into a pipe
    assert "ok, 6000 steps" in p.stdout
    assert list((tmp_path / "tmp").iterdir()) == []


@pytest.mark.parametrize("mode", ["ok", "discard", "fatal"])
def test_every_instance_terminated_and_freed_exactly_once(mode, built_fmus, failer, tmp_path, monkeypatch):
    """On success and on error each instance gets one fmi2Terminate and one fmi2FreeInstance; an instance
    that reported Fatal gets no call at all after it (FMI 2.0)."""
    from fmpy.fmi2 import FMU2Slave

    from wmr_cosim import cosim

    calls: list[tuple[str, str]] = []
    real_term, real_free = FMU2Slave.terminate, FMU2Slave.freeInstance

    def term(self):
        calls.append(("terminate", self.instanceName))
        return real_term(self)

    def free(self):
        calls.append(("free", self.instanceName))
        return real_free(self)

    monkeypatch.setattr(FMU2Slave, "terminate", term)
    monkeypatch.setattr(FMU2Slave, "freeInstance", free)
    path = _scenario(tmp_path, built_fmus, failer, mode)
    res = cosim.run(cosim.resolve(cosim.load(path)), tmp_path / "out", progress=False)
    assert res.status == ("ok" if mode == "ok" else "failed")
    survivors = ["plant", "sensor", "controller"] + ([] if mode == "fatal" else ["failer"])
    for name in survivors:
        assert calls.count(("terminate", name)) == 1, (name, calls)
        assert calls.count(("free", name)) == 1, (name, calls)
    if mode == "fatal":
        assert not [c for c in calls if c[1] == "failer"]


def test_a_failed_step_of_our_plant_is_a_failure_not_an_end(built_fmus, tmp_path):
    """A torque so large the plant's state overflows: its step fails with Discard (pythonfmu says
    fmi2Terminated too), and the message it logs at Discard makes this a failure, not the FMU ending the run."""
    path = g1_with_paths(tmp_path, built_fmus, """
[experiment]
stop = 2.0
[[events]]
time = 0.2
variable = "controller.u1"
action = "override"
value = 1e308
""")
    out = tmp_path / "out"
    p = _cli("run", str(path), "--out", str(out), "--quiet")
    summary = json.loads((out / "summary.json").read_text())
    assert p.returncode == 1 and summary["status"] == "failed", (p.returncode, p.stderr, summary["status"])
    assert "plant" in p.stderr and "Discard" in p.stderr
