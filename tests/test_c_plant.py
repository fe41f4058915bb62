"""The plant FMU from another toolchain (fmus/c_plant/, WmrCPlant.fmu): built from its C sources with cmake
and the C compiler, valid for FMPy, bit-identical to components/plant.py step for step, and swapped into
the G1 learning run by scenarios/g1_c_plant.toml (other names, degrees, rpm) with the same metrics.  Its
Model Exchange interface (the same library), driven by FMPy alone: CVode and Euler agree with the
co-simulation interface, the foam's kinks are time events and its region's entry a state event, a
non-finite input is an error; the FMU state rolls both interfaces back."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from cosim_support import ROOT
from wmr_cosim.components.metrics import run_metrics
from wmr_cosim.components.plant import Plant, PlantParams
from wmr_cosim import cosim
from wmr_cosim.fmus import cplant_build

G1_C = ROOT / "scenarios" / "g1_c_plant.toml"
G1 = ROOT / "scenarios" / "g1_learn.toml"
RAD2DEG, RADS2RPM = 180.0 / math.pi, 30.0 / math.pi


@pytest.fixture(scope="module")
def c_plant(tmp_path_factory):
    return cplant_build.build_c_plant(tmp_path_factory.mktemp("cplant"))


@pytest.fixture(scope="module")
def resolver(built_fmus, c_plant):
    fmus = {**built_fmus, "WmrCPlant": c_plant}
    return lambda name: fmus.get(name)


def test_it_is_a_c_fmu_that_passes_fmpy_validation(c_plant):
    import zipfile

    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(c_plant)) == []
    names = set(zipfile.ZipFile(c_plant).namelist())
    assert {"modelDescription.xml", "binaries/linux64/WmrCPlant.so", "sources/wmr_c_plant.c"} <= names
    assert not any("resources/" in n for n in names)          # no Python inside
    md = read_model_description(str(c_plant))
    units = {v.name: v.unit for v in md.modelVariables}
    assert units["phi_right"] == "deg" and units["omega_right"] == "rpm" and units["torque_right"] == "N.m"
    assert not {"alpha1", "u1", "x_A"} & set(units)            # other names than the Python plant's


@pytest.mark.slow
def test_rebuilt_only_when_its_sources_change(c_plant, tmp_path, monkeypatch):
    src = tmp_path / "c_plant"
    shutil.copytree(cplant_build.SRC, src)
    monkeypatch.setattr(cplant_build, "SRC", src)
    out = tmp_path / "out"
    fmu = cplant_build.build_c_plant(out)
    stamp = fmu.stat().st_mtime_ns
    assert cplant_build.build_c_plant(out).stat().st_mtime_ns == stamp          # up to date: not rebuilt
    c = src / "sources" / "wmr_c_plant.c"
    c.write_text(c.read_text() + "\n/* changed */\n")
    assert cplant_build.build_c_plant(out).stat().st_mtime_ns != stamp          # changed source: rebuilt
    c.write_text(c.read_text() + "\n#error broken\n")
    with pytest.raises(cplant_build.CBuildError, match="failed"):
        cplant_build.build_c_plant(out)


def _slave(c_plant, unzip_dir, reals=None, ints=None, bools=None, model_exchange=False):
    """WmrCPlant instantiated through FMPy (co-simulation, or Model Exchange: then in event mode), the
    values set, initialised; with the value references by name."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Model, FMU2Slave

    md = read_model_description(str(c_plant))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = (FMU2Model if model_exchange else FMU2Slave)(
        guid=md.guid, unzipDirectory=extract(str(c_plant), unzipdir=str(unzip_dir)), modelIdentifier="WmrCPlant",
        instanceName="p")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    for values, setter in ((reals, s.setReal), (ints, s.setInteger), (bools, s.setBoolean)):
        if values:
            setter([vr[k] for k in values], list(values.values()))
    s.enterInitializationMode()
    s.exitInitializationMode()
    return s, vr


CASES = {
    "default": ({}, {}, {}, {}),
    "foam by time, printed friction, 3 substeps, disturbances": (
        dict(foam_da1=0.4, foam_da2=0.5, foam_on_time=True, foam_t_on=1.001, friction_form="printed", substeps=3,
             x0=0.1, y0=-0.2),
        {"foam_rise_right": 0.4, "foam_rise_left": 0.5, "foam_time": 1.001, "start_x": 0.1, "start_y": -0.2},
        {"rk4_substeps": 3}, {"foam_at_time": True, "exp_friction": True}),
    "foam by region": (
        dict(foam_da1=0.3, foam_da2=0.2, foam_on_region=True, foam_x_min=0.05, foam_x_max=5.0, foam_y_min=-5.0,
             foam_y_max=5.0, foam_ramp=0.05),
        {"foam_rise_right": 0.3, "foam_rise_left": 0.2, "foam_x_lo": 0.05, "foam_x_hi": 5.0, "foam_y_lo": -5.0,
         "foam_y_hi": 5.0, "foam_ramp_time": 0.05}, {}, {"foam_in_region": True}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bit_identical_to_the_python_plant_step_for_step(c_plant, case, tmp_path):
    pp, reals, ints, bools = CASES[case]
    s, vr = _slave(c_plant, tmp_path, reals, ints, bools)
    plant = Plant(PlantParams(**pp))
    outs = [vr[n] for n in ("phi_right", "phi_left", "omega_right", "omega_left", "pos_x", "pos_y", "heading",
                            "dist_total_right", "dist_total_left", "foam_lambda")]
    ins = [vr[n] for n in ("torque_right", "torque_left", "dist_right", "dist_left")]
    h = 0.002
    try:
        for k in range(3000):
            t = k * h
            u1, u2 = 5.0 * math.sin(0.3 * t) + 4.5, 5.0 * math.cos(0.2 * t) + 4.4
            d1, d2 = (0.1, -0.05) if 2.0 < t < 3.0 else (0.0, 0.0)
            s.setReal(ins, [u1, u2, d1, d2])
            s.doStep(t, h)
            got = s.getReal(outs)
            a1, a2, w1, w2, x, y, b, df1, df2, lam = plant.step(t, h, u1, u2, d1, d2)
            # the same states; the unit changes are single multiplications, done the same way here
            want = [a1 * RAD2DEG, a2 * RAD2DEG, w1 * RADS2RPM, w2 * RADS2RPM, x, y, b * RAD2DEG, df1, df2, lam]
            assert got == want, k
        if case != "default":
            assert lam == 1.0 and df1 != 0.0     # the foam was reached and ramped up
    finally:
        s.terminate()
        s.freeInstance()


def test_bad_parameter_is_an_error_with_a_message(c_plant, tmp_path):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(c_plant))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(c_plant), unzipdir=str(tmp_path)),
                  modelIdentifier="WmrCPlant", instanceName="p")
    s.instantiate(loggingOn=True)
    s.setReal([vr["inertia_a1"], vr["inertia_a2"], vr["inertia_a3"]], [1.0, 0.0, -0.5])
    s.enterInitializationMode()
    with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
        s.exitInitializationMode()
    s.terminate()
    s.freeInstance()


@pytest.fixture(scope="module")
def python_plant_run(resolver, tmp_path_factory):
    out = tmp_path_factory.mktemp("py")
    res = cosim.run(cosim.resolve(cosim.load(G1, resolver)), out, progress=False)
    assert res.status == "ok", res.message
    return np.load(out / "signals.npy")


@pytest.mark.slow
def test_swapped_into_g1_with_a_name_map_it_gives_the_same_metrics(resolver, tmp_path, python_plant_run):
    plan = cosim.resolve(cosim.load(G1_C, resolver))
    conv = {c.spec.src: (c.factor, c.offset) for c in plan.connections}
    assert conv["plant.alpha1"] == (math.pi / 180, 0.0)              # deg -> rad into the sensor
    assert plan.instances["plant"].model.model_name == "WmrCPlant"
    res = cosim.run(plan, tmp_path, progress=False)
    assert res.status == "ok", res.message
    c = np.load(tmp_path / "signals.npy")
    py = python_plant_run
    m = run_metrics({k: c[k] for k in c.dtype.names}, (2, 5))
    m0 = run_metrics({k: py[k] for k in py.dtype.names}, (2, 5))
    keys = ("rmse_e", "rmse_edot", "final_position")
    for a, b in zip(sum((m[k] for k in keys), []), sum((m0[k] for k in keys), [])):
        assert a == pytest.approx(b, rel=1e-3)
    assert m["goal_distance"] < 0.03
    # recorded under the scenario's names, in the FMU's own units: degrees
    assert np.allclose(c["plant.alpha1"] / RAD2DEG, py["plant.alpha1"], rtol=0, atol=1e-12)
    # measured: the deg -> rad round trip flips no encoder count, so the closed loop is bit-identical
    # (not required: one flipped count would change the rest of the run, hence the 1e-3 above)
    same = np.array_equal(c["controller.u1"], py["controller.u1"])
    print("controller.u1 bit-identical to the Python plant's run:", same)


def test_the_scenario_resolves_wmrcplant_by_model_name(monkeypatch, tmp_path, c_plant):
    from wmr_cosim import runner

    monkeypatch.setattr(cplant_build, "default_out_dir", lambda: Path(c_plant).parent)
    assert runner.resolve_model("WmrCPlant") == c_plant


def test_fmpy_default_logging_still_works_after_our_master_ran(c_plant, built_fmus, tmp_path):
    """FMPy's C logger proxy forwards to one process-wide logger: the master must not leave it pointing at a
    collected Instance (a C FMU logging through FMPy's defaults afterwards then crashed the process), and
    each instance's messages must land in its own log."""
    import subprocess
    import sys
    import textwrap

    from cosim_support import g1_with_paths

    scen = g1_with_paths(tmp_path, built_fmus, "[experiment]\nstop = 0.01\n")
    code = textwrap.dedent(f"""
        import gc
        from wmr_cosim import cosim
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        res = cosim.run(cosim.resolve(cosim.load({str(scen)!r})), None, progress=False)
        assert res.status == "ok", res.message
        del res
        gc.collect()
        md = read_model_description({str(c_plant)!r})
        s = FMU2Slave(guid=md.guid, unzipDirectory=extract({str(c_plant)!r}, unzipdir={str(tmp_path / "unz")!r}),
                      modelIdentifier="WmrCPlant", instanceName="p")
        s.instantiate()
        s.setReal([0, 1, 2], [1.0, 0.0, -0.5])
        s.enterInitializationMode()
        try:
            s.exitInitializationMode()
        except Exception as exc:
            print("refused:", exc)
        s.terminate()
        s.freeInstance()
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "[Error] inertia_a1..a3 = 1, 0, -0.5: M of (35) is not positive definite" in p.stdout


def test_cli_build_with_the_c_plant(tmp_path):
    import subprocess
    import sys

    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "build", "--c-plant", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "WmrCPlant.fmu").is_file() and (tmp_path / "WmrPlant.fmu").is_file()
    assert "WmrCPlant" in p.stdout


# ------------------------------------------------------------------------------------------ Model Exchange
#: The Model Exchange states (value references 34-40) and their derivatives (41-47), in SI units.
STATES = ("state_phi_right", "state_phi_left", "state_omega_right", "state_omega_left", "state_pos_x",
          "state_pos_y", "state_heading")
DERS = tuple("der_" + s[len("state_"):] for s in STATES)
OUTS = ["phi_right", "omega_right", "pos_x", "pos_y", "heading", "dist_total_right", "foam_lambda"]
#: Constant drive torques [N.m]: the robot accelerates and turns left (0.44 m, 12.7 deg in 2 s).
DRIVE = {"torque_right": 3.0, "torque_left": 2.6}
H = 0.002
FOAM_BY_TIME = {**DRIVE, "foam_at_time": True, "foam_time": 0.7013, "foam_ramp_time": 0.25,
                "foam_rise_right": 0.4, "foam_rise_left": 0.5}
FOAM_BY_REGION = {**DRIVE, "foam_in_region": True, "foam_x_lo": 0.05, "foam_x_hi": 5.0, "foam_y_lo": -5.0,
                  "foam_y_hi": 5.0, "foam_ramp_time": 0.05, "foam_rise_right": 0.3, "foam_rise_left": 0.2}


def _me(c_plant, start, stop=2.0, solver="CVode", **kw):
    from fmpy import simulate_fmu

    if solver == "CVode":
        kw.setdefault("relative_tolerance", 1e-10)
        kw.setdefault("output_interval", H)
    return simulate_fmu(str(c_plant), fmi_type="ModelExchange", solver=solver, stop_time=stop,
                        start_values=start, output=OUTS, **kw)


def _cs(c_plant, start, stop=2.0):
    from fmpy import simulate_fmu

    return simulate_fmu(str(c_plant), fmi_type="CoSimulation", stop_time=stop, output_interval=H,
                        start_values={**start, "rk4_substeps": 20}, output=OUTS)


def _grid(res, h=H):
    """The rows on the output grid k h (FMPy adds rows at events: the last of equal times is kept)."""
    t = res["time"]
    keep = np.abs(t / h - np.round(t / h)) < 1e-6
    keep[:-1] &= t[:-1] != t[1:]
    return res[keep]


def _event_times(res):
    """FMPy's rows at an event: two with the same time, before and after it."""
    t = res["time"]
    return t[1:][t[1:] == t[:-1]]


def _worst(a, b, names=OUTS):
    assert len(a) == len(b) and np.abs(a["time"] - b["time"]).max() < 1e-12
    return {n: float(np.abs(a[n] - b[n]).max()) for n in names}


def test_one_archive_two_interfaces_one_library_and_the_states_declared(c_plant):
    import tomllib
    import zipfile

    from fmpy import read_model_description

    md = read_model_description(str(c_plant), validate=True)
    assert md.modelExchange.modelIdentifier == md.coSimulation.modelIdentifier == "WmrCPlant"
    # one library per platform: win64's where MinGW-w64 is on PATH (tests/test_windows.py runs it)
    win64 = ["binaries/win64/WmrCPlant.dll"] if cplant_build.mingw() else []
    assert [n for n in zipfile.ZipFile(c_plant).namelist() if n.startswith("binaries/")] == \
        ["binaries/linux64/WmrCPlant.so"] + win64
    assert md.modelExchange.canGetAndSetFMUstate and md.coSimulation.canGetAndSetFMUstate
    assert md.numberOfEventIndicators == 1 and md.numberOfContinuousStates == 7
    v = {x.name: x for x in md.modelVariables}
    # the existing value references are unchanged; the states and derivatives follow them
    assert [v[n].valueReference for n in ("inertia_a1", "torque_right", "phi_right", "foam_lambda")] == [0, 20, 24, 33]
    assert [v[n].valueReference for n in STATES + DERS] == list(range(34, 48))
    assert [d.variable.name for d in md.derivatives] == list(DERS)
    assert [d.variable.derivative.name for d in md.derivatives] == list(STATES)
    assert all(v[n].causality == "local" and v[n].variability == "continuous" for n in STATES + DERS)
    assert [v[n].unit for n in STATES] == ["rad", "rad", "rad/s", "rad/s", "m", "m", "rad"]
    # no clash with the name map that swaps the plant into G1 (FMU names nor the scenario's)
    names = tomllib.loads(G1_C.read_text())["instances"]["plant"]["names"]
    assert not (set(STATES + DERS) & (set(names) | set(names.values())))


def test_model_exchange_with_cvode_matches_the_co_simulation_interface(c_plant):
    me, cs = _me(c_plant, DRIVE), _cs(c_plant, DRIVE)
    assert cs["pos_x"][-1] > 0.4 and cs["heading"][-1] > 10.0         # it drove and turned
    worst = _worst(me, cs)
    print("ME (CVode 1e-10) - CS (RK4, 20 substeps of 0.1 ms), max |diff|:", worst)
    # measured: 3.8e-11 m, 2.5e-11 m, 1.5e-9 deg, 3.0e-8 rpm
    assert worst["pos_x"] < 1e-9 and worst["pos_y"] < 1e-9
    assert worst["heading"] < 1e-7 and worst["phi_right"] < 1e-7 and worst["omega_right"] < 1e-6
    assert worst["foam_lambda"] == 0.0


def test_model_exchange_with_euler_converges_to_it_at_first_order(c_plant):
    cs = _cs(c_plant, DRIVE, stop=1.0)
    err = []
    for h in (2e-4, 1e-4):
        me = _grid(_me(c_plant, DRIVE, stop=1.0, solver="Euler", step_size=h, output_interval=h))
        w = _worst(me, cs, ("pos_x", "pos_y"))
        err.append(max(w.values()))
    print("ME (Euler 0.2 ms, 0.1 ms) - CS, max |diff| of pos_x, pos_y [m]:", err)
    # measured: 8.8e-6 m, 4.4e-6 m
    assert err[1] < 1e-5
    assert err[0] / err[1] == pytest.approx(2.0, rel=0.05)


def test_foam_by_time_its_kinks_are_time_events_and_both_interfaces_agree(c_plant):
    t_on, ramp = FOAM_BY_TIME["foam_time"], FOAM_BY_TIME["foam_ramp_time"]
    me = _me(c_plant, FOAM_BY_TIME, record_events=True)
    assert _event_times(me).tolist() == pytest.approx([t_on, t_on + ramp], abs=1e-12)
    assert _event_times(_me(c_plant, DRIVE, record_events=True)).size == 0
    cs = _cs(c_plant, FOAM_BY_TIME)
    assert cs["foam_lambda"][-1] == 1.0 and 0.0 < np.interp(0.8, cs["time"], cs["foam_lambda"]) < 1.0
    worst = _worst(_grid(me), cs)
    print("foam by time, ME (CVode 1e-10) - CS, max |diff|:", worst)
    # measured: 5.6e-11 m, 5.1e-12 m, 4.4e-16, 2.8e-10 N.m
    assert worst["pos_x"] < 1e-9 and worst["pos_y"] < 1e-9
    assert worst["foam_lambda"] < 1e-12 and worst["dist_total_right"] < 1e-8


def test_foam_by_region_is_reached_at_the_state_event_of_the_edge_crossing(c_plant):
    x_lo, ramp = FOAM_BY_REGION["foam_x_lo"], FOAM_BY_REGION["foam_ramp_time"]
    me = _me(c_plant, FOAM_BY_REGION, stop=1.0, record_events=True)
    ev = _event_times(me)
    assert ev.size == 2 and ev[1] == pytest.approx(ev[0] + ramp, abs=1e-12)   # entry, then the ramp's end
    t_ev = ev[0]
    # where x_A crosses foam_x_lo on the trajectory (grid rows only, a cubic through the four around it)
    g = _grid(me)
    k = int(np.searchsorted(g["pos_x"], x_lo))
    t4, x4 = g["time"][k - 2:k + 2], g["pos_x"][k - 2:k + 2]
    roots = np.roots(np.polyfit(t4 - t4[1], x4 - x_lo, 3)) + t4[1]
    t_cross = float(next(r.real for r in roots if abs(r.imag) < 1e-12 and t4[1] <= r.real <= t4[2]))
    print(f"foam by region: state event at {t_ev!r} s, x_A crosses x_lo at {t_cross!r} s")
    # measured: 4.5e-10 s apart (the cubic's error: 2 ms rows); A is on the edge at the event
    assert t_ev == pytest.approx(t_cross, abs=1e-8)
    assert np.abs(me["pos_x"][me["time"] == t_ev] - x_lo).max() < 1e-10
    # the foam level starts rising at the event: 0 up to it, (t - t_ev) / ramp on the ramp
    lam, t = g["foam_lambda"], g["time"]
    assert np.all(lam[t <= t_ev] == 0.0) and np.all(lam[t > t_ev] > 0.0)
    on = (t > t_ev) & (t < t_ev + ramp)
    assert np.abs(lam[on] - (t[on] - t_ev) / ramp).max() < 1e-12
    # co-simulation keeps its behaviour: the region is checked at each step's start
    cs = _cs(c_plant, FOAM_BY_REGION, stop=1.0)
    t_cs = cs["time"][np.argmax(cs["pos_x"] >= x_lo)]        # the first step that starts inside
    assert cs["foam_lambda"][cs["time"] <= t_cs + 1e-12].max() == 0.0
    assert np.interp(t_cs + H, cs["time"], cs["foam_lambda"]) == pytest.approx(H / ramp, abs=1e-9)


_NON_FINITE = r"""
import math, sys
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model
path = sys.argv[1]
md = read_model_description(path)
vr = {v.name: v.valueReference for v in md.modelVariables}
m = FMU2Model(guid=md.guid, unzipDirectory=extract(path), modelIdentifier="WmrCPlant", instanceName="p")
m.instantiate()
m.setupExperiment(startTime=0.0)
m.enterInitializationMode()
m.exitInitializationMode()
m.newDiscreteStates()
m.enterContinuousTimeMode()
from ctypes import c_double
dx = (c_double * 7)()
m.getDerivatives(dx, 7)
print("finite:", list(dx)[2] == 0.0)
m.setReal([vr["dist_left"]], [math.nan])
try:
    m.getDerivatives(dx, 7)
    print("no error:", list(dx))
except Exception as exc:
    print("refused:", exc)
try:
    m.getDerivatives(dx, 7)
except Exception as exc:
    print("refused again:", exc)
m.terminate()
m.freeInstance()
try:
    r = simulate_fmu(path, fmi_type="ModelExchange", solver="Euler", step_size=1e-3, stop_time=0.01,
                     start_values={"torque_right": math.inf})
    print("simulated:", r["pos_x"][-1])
except Exception as exc:
    print("simulation refused:", exc)
"""


def test_a_non_finite_input_is_an_error_of_fmi2GetDerivatives_not_a_nan(c_plant, tmp_path):
    import os
    import subprocess
    import sys

    env = {**os.environ, "TMPDIR": str(tmp_path)}        # FMPy's extraction folders: the test's own
    p = subprocess.run([sys.executable, "-c", _NON_FINITE, str(c_plant)], capture_output=True, text=True,
                       timeout=120, cwd=tmp_path, env=env)
    assert p.returncode == 0, p.stderr[-2000:]
    out = p.stdout
    assert "finite: True" in out and "no error" not in out and "simulated:" not in out, out
    assert "refused: fmi2GetDerivatives failed with status 3 (error)" in out
    assert "derivatives at t = 0 s: non-finite input (torque_right = 0, torque_left = 0, dist_right = 0, " \
           "dist_left = nan N.m)" in out
    assert "fmi2GetDerivatives at t = 0 s refused: an earlier call failed" in out      # until a reset
    assert "simulation refused: fmi2GetDerivatives failed" in out and "torque_right = inf" in out


def _model(c_plant, unzip_dir, start):
    """A Model Exchange instance of WmrCPlant in event mode after initialisation with ``start``."""
    reals = {k: float(v) for k, v in start.items() if not isinstance(v, bool)}
    bools = {k: v for k, v in start.items() if isinstance(v, bool)}
    return _slave(c_plant, unzip_dir, reals, None, bools, model_exchange=True)


def test_model_exchange_calls_the_states_derivatives_and_the_region_indicator(c_plant, tmp_path):
    from ctypes import c_double

    m, vr = _model(c_plant, tmp_path, {**FOAM_BY_REGION, "start_heading": 30.0})
    with pytest.raises(Exception, match="fmi2SetBoolean"):      # a fixed parameter after initialisation
        m.setBoolean([vr["foam_in_region"]], [False])
    assert m.newDiscreteStates()[4] is False            # no time event before the foam is reached
    m.enterContinuousTimeMode()
    x, dx, z = (c_double * 7)(), (c_double * 7)(), (c_double * 1)()
    m.getContinuousStates(x, 7)
    assert list(x) == [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, math.radians(30.0)]
    m.getEventIndicators(z, 1)
    assert z[0] == -0.05                                  # min(x_A - x_lo, ...): 0.05 m from the rectangle
    state = [0.1, 0.2, 3.0, 2.0, 0.01, 0.02, 0.5]
    m.setTime(0.1)
    m.setContinuousStates((c_double * 7)(*state), 7)
    m.getDerivatives(dx, 7)
    # the derivatives against the stage of (34)-(36), (23)-(24) written out here
    a1, a2, a3, a4, a5, a6, cf, r, l1 = 0.0691, 0.0511, 0.0291, 0.0014, 4.3001, 4.3001, 0.226, 0.0825, 0.16
    m11, m12 = a1 + a2 + a3, a1 - a2
    w1, w2, be = state[2], state[3], state[6]
    c = 2 * a4 * (w2 - w1)
    r1 = 3.0 - c * w2 - 2 * a5 * math.tanh(cf * w1 / 2)
    r2 = 2.6 + c * w1 - 2 * a6 * math.tanh(cf * w2 / 2)
    det = m11 * m11 - m12 * m12
    want = [w1, w2, (m11 * r1 - m12 * r2) / det, (-m12 * r1 + m11 * r2) / det,
            r / 2 * (w1 + w2) * math.cos(be), r / 2 * (w1 + w2) * math.sin(be), r / (2 * l1) * (w1 - w2)]
    assert list(dx) == pytest.approx(want, rel=1e-13)
    assert m.getReal([vr[n] for n in STATES + DERS]) == state + list(dx)
    assert m.getReal([vr["phi_right"], vr["omega_right"], vr["pos_x"], vr["heading"]]) == pytest.approx(
        [math.degrees(0.1), 3.0 * RADS2RPM, 0.01, math.degrees(0.5)], rel=1e-15)
    m.getEventIndicators(z, 1)
    assert z[0] == pytest.approx(0.01 - 0.05, abs=1e-15)
    # A enters: the event sets the foam's time to the event's, then the end of the ramp is a time event
    state[4] = 0.06
    m.setTime(0.3)
    m.setContinuousStates((c_double * 7)(*state), 7)
    m.getEventIndicators(z, 1)
    assert z[0] > 0.0
    m.enterEventMode()
    ev = m.newDiscreteStates()
    assert ev[:4] == (False, False, False, False) and ev[4] and ev[5] == pytest.approx(0.35, abs=1e-15)
    m.enterContinuousTimeMode()
    m.getEventIndicators(z, 1)
    assert z[0] == 1.0                                    # reached: no more region events
    m.setTime(0.32)
    assert m.getReal([vr["foam_lambda"]]) == [pytest.approx(0.4, abs=1e-12)]
    m.getDerivatives(dx, 7)
    r1 = 3.0 - c * w2 - 2 * (a5 + 0.4 * 0.3) * math.tanh(cf * w1 / 2)      # rolling resistance + lambda da
    r2 = 2.6 + c * w1 - 2 * (a6 + 0.4 * 0.2) * math.tanh(cf * w2 / 2)
    assert dx[2] == pytest.approx((m11 * r1 - m12 * r2) / det, rel=1e-12)
    m.terminate()
    m.freeInstance()


def test_get_and_set_fmu_state_rolls_both_interfaces_back(c_plant, tmp_path):
    from ctypes import c_double

    # co-simulation: 100 steps after a saved state, again after restoring it: the same outputs, bit for bit,
    # the foam region reached in them both times (its flag and time are part of the state)
    pp, reals, ints, bools = CASES["foam by region"]
    s, vr = _slave(c_plant, tmp_path / "cs", reals, ints, bools)
    outs = [vr[n] for n in OUTS]
    ins = [vr["torque_right"], vr["torque_left"]]
    for k in range(100):
        s.setReal(ins, [4.0, 3.9])
        s.doStep(k * H, H)
    saved = s.getFMUstate()
    runs = []
    for _ in range(2):
        s.setFMUstate(saved)
        rows = []
        for k in range(100, 200):
            s.setReal(ins, [4.0 + 0.01 * k, 3.9])
            s.doStep(k * H, H)
            rows.append(s.getReal(outs))
        runs.append(rows)
    s.freeFMUstate(saved)
    assert runs[0] == runs[1]
    lam = [r[-1] for r in runs[0]]
    assert lam[0] == 0.0 and lam[-1] == 1.0
    s.terminate()
    s.freeInstance()
    # Model Exchange: the states, the time and the foam reached are restored, and the mode
    m, vr = _model(c_plant, tmp_path / "me", FOAM_BY_REGION)
    m.newDiscreteStates()
    m.enterContinuousTimeMode()
    x0 = (c_double * 7)()
    m.getContinuousStates(x0, 7)
    saved = m.getFMUstate()
    m.setTime(0.3)
    m.setContinuousStates((c_double * 7)(0, 0, 1, 1, 0.06, 0, 0), 7)
    m.enterEventMode()
    m.newDiscreteStates()
    m.enterContinuousTimeMode()
    m.setTime(0.32)
    assert m.getReal([vr["foam_lambda"], vr["pos_x"]]) == [pytest.approx(0.4, abs=1e-12), 0.06]
    m.enterEventMode()
    m.setFMUstate(saved)                                  # back in continuous-time mode at t = 0, no foam
    x = (c_double * 7)()
    m.getContinuousStates(x, 7)
    assert list(x) == list(x0)
    m.setTime(0.32)
    assert m.getReal([vr["foam_lambda"], vr["pos_x"]]) == [0.0, 0.0]
    z = (c_double * 1)()
    m.getEventIndicators(z, 1)
    assert z[0] < 0.0
    m.freeFMUstate(saved)
    m.terminate()
    m.freeInstance()
