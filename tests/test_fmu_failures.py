"""A failing step is logged with its cause and reported as fmi2Discard, after which the
host can terminate and free the instance without crashing; a parameter out of range makes initialisation
fail (fmi2Fatal, the only status pythonfmu has there) with a clear message in the FMU log, and its
declared min/max would have let a master refuse it first.  Each runs in a child process, so that a
regression (a crash of the host) fails the test instead of killing the test session."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from fmpy import read_model_description

TESTS = Path(__file__).resolve().parent

_STEP_FAILS = r"""
import gc, json, sys
from pathlib import Path
sys.path.insert(0, {tests!r})
from fmu_support import Fmu, FMICallException

def steps(f, n):
    out = []
    for k in range(n):
        try:
            f.fmu.doStep(k * 0.002, 0.002)
            out.append(0)
        except FMICallException as e:
            out.append(e.status)
    return out

res = {{}}
p = Fmu(Path(sys.argv[1]), "plant one")
p.init(params={{"friction_form": "printed"}})  # the printed friction overflows at large negative speeds
p.set(u1=-1e7)
res["plant"] = steps(p, 3)
res["plant_log"] = p.log
p.free()  # terminate + free after a Discard must not crash the host
c = Fmu(Path(sys.argv[2]), "controller one")
c.init()
res["controller_ok"] = steps(c, 1)
c.set(alpha_m1=float("nan"))
res["controller"] = steps(c, 1)
res["controller_log"] = c.log
c.free()
gc.collect()
print(json.dumps(res))
"""


def test_failing_step_is_logged_and_reported_as_discard(built_fmus, tmp_path):
    script = tmp_path / "step_fails.py"
    script.write_text(_STEP_FAILS.format(tests=str(TESTS)))
    r = subprocess.run([sys.executable, str(script), str(built_fmus["WmrPlant"]), str(built_fmus["WmrController"])],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]  # the host survived terminate + free + garbage collection
    res = json.loads(r.stdout.strip().splitlines()[-1])
    assert res["plant"] == [2, 2, 2]  # fmi2Discard, then every later step refused the same way
    (s1, cat1, m1), (s2, cat2, m2) = res["plant_log"][:2]
    assert (s1, cat1) == (2, "logStatusDiscard")
    assert "WmrPlant instance plant one" in m1 and "OverflowError" in m1 and "t = 0.0 s" in m1
    assert "refused" in m2 and "OverflowError" in m2
    assert res["controller_ok"] == [0] and res["controller"] == [2]
    assert any("non-finite input: alpha_m1 = nan" in m for _, _, m in res["controller_log"])


_INIT_FAILS = r"""
import json, sys
from pathlib import Path
sys.path.insert(0, {tests!r})
from fmu_support import Fmu, FMICallException
res = []
for path, name, value in json.loads(sys.argv[1]):
    f = Fmu(Path(path), "bad " + name)
    try:
        f.init(params={{name: value}})
        status = 0
    except FMICallException as e:
        status = e.status
    res.append([status, f.log])
    # after fmi2Fatal no further call on this instance (FMI 2.0; freeing it crashes pythonfmu): leaked on purpose
print(json.dumps(res))
"""

BAD = [  # model, parameter, out-of-range value, expected one-line cause
    ("WmrPlant", "r", -0.1, "plant parameter r = -0.1: must be > 0"),
    ("WmrPlant", "substeps", 0, "plant parameter substeps = 0: must be an integer >= 1"),
    ("WmrSensor", "phase1", 1.5, "sensor parameter phase1 = 1.5: must be in [0, 1) counts"),
    ("WmrController", "gamma", 0.0, "controller parameter gamma = 0.0: must be > 0"),
    ("WmrController", "player_gamma_power", 3, "controller parameter player_gamma_power = 3: must be 1 or 2"),
    ("WmrController", "task", "circle", "controller parameter task = 'circle': must be one of goal, line"),
]


def test_parameter_out_of_range_fails_initialisation_with_a_clear_log(built_fmus, tmp_path):
    for model, name, value, _ in BAD:  # the declared range refuses the value before instantiation
        v = {x.name: x for x in read_model_description(str(built_fmus[model])).modelVariables}[name]
        if v.type in ("Real", "Integer"):
            assert value < float(v.min) or (v.max is not None and value > float(v.max)), (model, name)
        else:
            assert name in ("task",) and "goal" in v.description and "line" in v.description
    script = tmp_path / "init_fails.py"
    script.write_text(_INIT_FAILS.format(tests=str(TESTS)))
    arg = json.dumps([[str(built_fmus[m]), n, v] for m, n, v, _ in BAD])
    r = subprocess.run([sys.executable, str(script), arg], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads(r.stdout.strip().splitlines()[-1])
    for (model, name, value, cause), (status, log) in zip(BAD, res):
        assert status == 4, (model, name)  # fmi2Fatal: pythonfmu has no other failure status here
        ours = [m for s, cat, m in log if cat == "logStatusFatal"]
        assert ours and ours[0] == f"{model} instance bad {name}: initialisation failed: ParameterError: {cause}"
