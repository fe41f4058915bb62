"""FMI 3.0 Scheduled Execution: the Reference FMU Clocks run by the master's scheduler of its input clocks
(periodic inClock1, triggered inClock2 ticked by ``clock_ticks``, countdown inClock3 set by the FMU)
equals its reference result; ``check`` lists each clock; what the scheduler cannot honour exactly is
refused at ``check`` in one line (exit 2)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_csv

from cosim_support import write_scenario
from wmr_cosim import cosim
from reference_fmus import REF

FMI3 = REF / "fmi3"
COLUMNS = ("inClock1Ticks", "inClock2Ticks", "inClock3Ticks", "totalInClockTicks")


def _scenario(tmp: Path, instance: str = 'clock_ticks = { inClock2 = [0.0, 1.0, 8.0, 9.0] }', experiment: str = "",
              step: str = "1.0") -> Path:
    return write_scenario(tmp / "clocks.toml", f'''
[experiment]
stop = 10.0
step = {step}
{experiment}
[instances.C]
fmu = "{FMI3 / 'Clocks.fmu'}"
{instance}
[record]
variables = [{", ".join(f'"C.{c}"' for c in COLUMNS)}]
''')


def _cli(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


def test_clocks_run_by_the_scheduler_equal_the_reference(tmp_path):
    res = cosim.run(cosim.resolve(cosim.load(_scenario(tmp_path))), tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    ours = np.load(tmp_path / "out" / "signals.npy")
    ref = read_csv(str(FMI3 / "Clocks_ref.csv"))
    t_ours = np.round(ours["time"], 9)
    compared = 0
    for i, t in enumerate(np.round(ref["time"], 9)):   # the reference at its times
        hit = np.flatnonzero(t_ours == t)
        assert hit.size, t
        for c in COLUMNS:
            assert int(ours[f"C.{c}"][hit[-1]]) == int(ref[c][i]), (c, t)
            compared += 1
    assert compared == len(ref) * len(COLUMNS) == 40


def test_check_lists_each_clock_its_kind_interval_and_variables(tmp_path):
    p = _cli("check", _scenario(tmp_path))
    assert p.returncode == 0, p.stderr
    out = p.stdout
    assert "C: scheduled execution" in out
    assert ("clock inClock1: periodic input clock (constant); interval 1.0 s; priority 0; clocks inClock3, outClock, "
            "inClock1Ticks, totalInClockTicks") in out
    assert "clock inClock2: triggered input clock; priority 1;" in out and "ticked at 0, 1, 8, 9 s" in out
    assert "clock inClock3: countdown input clock; priority 2;" in out
    assert "clock outClock: output clock, raised by the FMU" in out
    assert "note: C: output clock outClock is raised by the FMU and feeds nothing" in out


@pytest.mark.parametrize("instance, experiment, step, field, words", [
    ("", "", "1.0", "instances.C.clock_ticks", "triggered input clock inClock2 has no source"),
    ('clock_ticks = { inClock2 = [0.0, 1.0] }', "", "0.3", "experiment.step",
     "clock C.inClock1 ticks every 1.0 s, not a whole number of steps"),
    ('clock_ticks = { inClock2 = [0.0, 1.5] }', "", "1.0", "instances.C.clock_ticks.inClock2",
     "1.5 s is not on the grid of 1 s steps"),
    ('clock_ticks = { inClock2 = [0.0], inClock1 = [1.0] }', "", "1.0", "instances.C.clock_ticks.inClock1",
     "has no triggered input clock 'inClock1'"),
    ('clock_ticks = { inClock2 = [0.0] }', 'algorithm = "jacobi"', "1.0", "experiment.algorithm",
     "runs under gauss-seidel only"),
    ('clock_ticks = { inClock2 = [0.0] }\nisolate = true', "", "1.0", "instances.C.isolate",
     "not supported for a scheduled execution instance"),
    ('clock_ticks = { inClock2 = [0.0] }\ninterface = "co-simulation"', "", "1.0", "instances.C.interface",
     "has no co-simulation interface"),
    ('clock_ticks = { inClock2 = [0.0] }\n[[events]]\ntime = 2.0\nvariable = "C.inClock1Ticks"\naction = "override"\n'
     'value = 1', "", "1.0", "events[0].variable", "events on a scheduled execution instance are not supported yet"),
])
def test_what_the_scheduler_cannot_honour_is_refused_at_check_in_one_line(instance, experiment, step, field, words,
                                                                         tmp_path):
    p = _cli("check", _scenario(tmp_path, instance, experiment, step))
    assert p.returncode == 2, p.stdout + p.stderr
    line = p.stderr.strip()
    assert "\n" not in line and field in line and words in line, line


def test_a_co_simulation_fmu_with_clocks_is_refused_unless_scheduled(tmp_path):
    """clock_ticks on an instance without scheduled execution: refused, naming the key."""
    path = write_scenario(tmp_path / "ft.toml", f'''
[experiment]
stop = 1.0
step = 0.1
[instances.F]
fmu = "{FMI3 / 'Feedthrough.fmu'}"
clock_ticks = {{ c = [0.0] }}
''')
    p = _cli("check", path)
    assert p.returncode == 2 and "instances.F.clock_ticks" in p.stderr and "\n" not in p.stderr.strip(), p.stderr


def test_export_ssp_and_export_fmu_refuse_a_scheduled_execution_instance(tmp_path):
    """(Its clock_ticks have no place in SSP 1.0, and the container runs co-simulation and Model Exchange
    instances): one line, exit 2, nothing written."""
    sc = _scenario(tmp_path)
    for command, out, field in (("export-ssp", "c.ssp", "instances.C"), ("export-fmu", "c.fmu", "instances.C")):
        p = _cli(command, sc, "--out", tmp_path / out)
        assert p.returncode == 2 and field in p.stderr and "scheduled" in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1 and not (tmp_path / out).exists()
