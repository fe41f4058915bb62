"""The master on FMI 3.0 co-simulation FMUs: the Reference FMUs (tests/data/reference-fmus/fmi3) against
FMPy's simulate_fmu with the same step and their reference results; every type recorded as its own
dtype; arrays as columns x[1], ...; Int64 inputs exact from a table; a mixed FMI 2.0 / 3.0 system; FMUs
that need clocks refused at check."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_csv, simulate_fmu

from cosim_support import write_scenario
from wmr_cosim import cosim
from wmr_cosim.cosim.messages.errors import ScenarioError
from wmr_cosim.runner import fmu_plan

from reference_fmus import REF
FMI3 = REF / "fmi3"


def _ours(fmu: Path, tmp: Path, **kw) -> np.ndarray:
    res = cosim.run(fmu_plan(fmu, **kw), tmp / "out", progress=False)
    assert res.status in ("ok", "terminated"), res.message
    return np.load(tmp / "out" / "signals.npy")


@pytest.mark.parametrize("model", ["BouncingBall", "Dahlquist", "Feedthrough", "Resource", "Stair", "VanDerPol",
                                   "StateSpace"])
def test_fmi3_reference_fmu_equals_fmpy_and_its_reference(model, tmp_path):
    fmu = FMI3 / f"{model}.fmu"
    plan = fmu_plan(fmu)
    ours = _ours(fmu, tmp_path)
    theirs = simulate_fmu(str(fmu), output_interval=plan.scenario.step, stop_time=plan.scenario.stop)
    assert len(ours) == len(theirs), (len(ours), len(theirs))
    np.testing.assert_allclose(ours["time"], theirs["time"], rtol=0, atol=1e-12)
    for name in theirs.dtype.names[1:]:
        col = theirs[name]
        if col.ndim == 2:   # an array: one column per element
            for j in range(col.shape[1]):
                np.testing.assert_allclose(ours[f"{model}.{name}[{j + 1}]"], col[:, j], rtol=0, atol=1e-12)
            continue
        if col.dtype.kind in "OSU":   # String and Binary outputs are not recorded
            assert f"{model}.{name}" not in ours.dtype.names
            continue
        ours_col = ours[f"{model}.{name}"]
        assert ours_col.dtype == col.dtype or col.dtype.kind == "f", (name, ours_col.dtype, col.dtype)
        np.testing.assert_allclose(ours_col.astype(float), col.astype(float), rtol=0, atol=1e-12, err_msg=name)
    ref = REF / "fmi3" / f"{model}_ref.csv"
    if model in ("BouncingBall", "Dahlquist", "Stair", "VanDerPol"):
        r = read_csv(str(ref))
        t_ours = np.round(ours["time"], 9)
        for name in r.dtype.names[1:]:
            for t, v in zip(np.round(r["time"], 9), r[name]):
                hit = np.flatnonzero(t_ours == t)
                if hit.size:
                    assert abs(float(ours[f"{model}.{name}"][hit[-1]]) - float(v)) < 1e-6, (name, t)


def test_fmi3_types_and_exact_64_bit_integers_from_the_shipped_input_file(tmp_path):
    """Feedthrough with its input file: Int64 and UInt64 extremes pass exactly (read as integers, never as
    floats), every output has its own dtype, and the results equal FMPy's given the same exact table."""
    fmu, table = FMI3 / "Feedthrough.fmu", REF / "Feedthrough_in.csv"
    ours = _ours(fmu, tmp_path, inputs=table, stop=2.0, step=0.1)
    assert ours["Feedthrough.Int64_output"].dtype == np.int64 and ours["Feedthrough.UInt64_output"].dtype == np.uint64
    assert ours["Feedthrough.Int64_output"].max() == 2 ** 63 - 1 and ours["Feedthrough.Int64_output"].min() == -2 ** 63
    assert ours["Feedthrough.UInt64_output"].max() == 2 ** 64 - 1
    assert ours["Feedthrough.Int8_output"].dtype == np.int8 and ours["Feedthrough.Boolean_output"].dtype == np.bool_
    with open(table) as fh:
        rows = list(csv.reader(fh))
    types = {"Int8": "i1", "UInt8": "u1", "Int16": "i2", "UInt16": "u2", "Int32": "i4", "UInt32": "u4",
             "Int64": "i8", "UInt64": "u8"}
    dtype = [("time", "f8")] + [(h, types[h.split("_")[0]]) for h in rows[0][1:]]
    exact = np.array([tuple([float(r[0])] + [int(x) for x in r[1:]]) for r in rows[1:]], dtype=dtype)
    theirs = simulate_fmu(str(fmu), output_interval=0.1, stop_time=2.0, input=exact)
    for name in (h.replace("_input", "_output") for h in rows[0][1:]):
        assert np.array_equal(ours[f"Feedthrough.{name}"], theirs[name].astype(ours[f"Feedthrough.{name}"].dtype)), name


def test_a_mixed_fmi2_fmi3_system(tmp_path):
    """An FMI 2.0 Dahlquist feeding an FMI 3.0 Feedthrough feeding an FMI 2.0 Feedthrough, with a unitless
    linear transform, against the plain chain computed by hand from Dahlquist's own output."""
    path = write_scenario(tmp_path / "mixed.toml", f'''
[experiment]
stop = 1.0
step = 0.01
[instances.d]
fmu = "{REF / 'fmi2' / 'Dahlquist.fmu'}"
[instances.f3]
fmu = "{FMI3 / 'Feedthrough.fmu'}"
[instances.f2]
fmu = "{REF / 'fmi2' / 'Feedthrough.fmu'}"
[[connections]]
from = "d.x"
to = "f3.Float64_continuous_input"
factor = 2.0
[[connections]]
from = "f3.Float64_continuous_output"
to = "f2.Float64_continuous_input"
offset = 1.0
[[connections]]
from = "f3.Int32_output"
to = "f2.Int32_input"
[[events]]
time = 0.5
variable = "f3.Int32_input"
value = 42
[record]
variables = ["d.x", "f3.Float64_continuous_output", "f2.Float64_continuous_output", "f2.Int32_output"]
''')
    res = cosim.run(cosim.resolve(cosim.load(path)), tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    assert np.array_equal(d["f3.Float64_continuous_output"], 2.0 * d["d.x"])
    assert np.array_equal(d["f2.Float64_continuous_output"], 2.0 * d["d.x"] + 1.0)
    assert d["f2.Int32_output"][50] == 0 and d["f2.Int32_output"][51] == 42


def test_an_fmi3_array_is_connected_whole_and_recorded_by_element(tmp_path):
    path = write_scenario(tmp_path / "arr.toml", f'''
[experiment]
stop = 0.1
step = 0.01
[instances.a]
fmu = "{FMI3 / 'StateSpace.fmu'}"
[instances.b]
fmu = "{FMI3 / 'StateSpace.fmu'}"
parameters = {{ D = [2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0] }}
[[connections]]
from = "a.y"
to = "b.u"
[record]
variables = ["a.y", "b.y"]
''')
    plan = cosim.resolve(cosim.load(path))
    assert [r.column for r in plan.record] == ["a.y[1]", "a.y[2]", "a.y[3]", "b.y[1]", "b.y[2]", "b.y[3]"]
    res = cosim.run(plan, tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    assert d["a.y[3]"][0] == 3.0 and d["b.y[2]"][0] == 4.0   # b.y = C x + D u with x(0) = 0: 2 * a.y


def test_an_fmu_with_clocks_and_no_tick_for_its_triggered_clock_is_refused_at_check(tmp_path):
    path = write_scenario(tmp_path / "c.toml", f'[instances.c]\nfmu = "{FMI3 / "Clocks.fmu"}"\n')
    with pytest.raises(ScenarioError, match="triggered input clock inClock2 has no source") as exc:
        cosim.resolve(cosim.load(path))
    assert exc.value.field == "instances.c.clock_ticks"


def test_one_element_of_an_fmi3_array_connected_and_recorded(tmp_path):
    """a.y[2] (an element of a Float64 array output) drives a scalar input; b.y[3] is recorded alone; an
    element of an input array as a target, and arrays of different sizes, are refused in one line."""
    path = write_scenario(tmp_path / "el.toml", f'''
[experiment]
stop = 0.1
step = 0.01
[instances.a]
fmu = "{FMI3 / 'StateSpace.fmu'}"
[instances.f]
fmu = "{FMI3 / 'Feedthrough.fmu'}"
[[connections]]
from = "a.y[2]"
to = "f.Float64_continuous_input"
factor = 10.0
[record]
variables = ["a.y[2]", "f.Float64_continuous_output"]
''')
    plan = cosim.resolve(cosim.load(path))
    assert [r.column for r in plan.record] == ["a.y[2]", "f.Float64_continuous_output"]
    res = cosim.run(plan, tmp_path / "out", progress=False)
    assert res.status == "ok", res.message
    d = np.load(tmp_path / "out" / "signals.npy")
    assert np.array_equal(d["f.Float64_continuous_output"], 10.0 * d["a.y[2]"]) and d["a.y[2]"][0] == 2.0
    bad = path.read_text().replace('to = "f.Float64_continuous_input"', 'to = "a.u[1]"')
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(ScenarioError, match="an element of an input array cannot be a target"):
        cosim.resolve(cosim.load(tmp_path / "bad.toml"))
    bad2 = path.read_text().replace('from = "a.y[2]"', 'from = "a.y"')
    (tmp_path / "bad2.toml").write_text(bad2)
    with pytest.raises(ScenarioError, match="arrays connect whole"):
        cosim.resolve(cosim.load(tmp_path / "bad2.toml"))
