"""The plant FMU from another toolchain (fmus/c_plant/, WmrCPlant.fmu): built from its C sources with cmake
and the C compiler, valid for FMPy, bit-identical to components/plant.py step for step, and swapped into
the G1 learning run by scenarios/g1_c_plant.toml (other names, degrees, rpm) with the same metrics."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from cosim_support import ROOT
from wmr_cosim.components.metrics import run_metrics
from wmr_cosim.components.plant import Plant, PlantParams
from wmr_cosim.cosim import execution, scenario, system
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


def _slave(c_plant, unzip_dir, reals=None, ints=None, bools=None):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(c_plant))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(c_plant), unzipdir=str(unzip_dir)),
                  modelIdentifier="WmrCPlant", instanceName="p")
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
    res = execution.run(system.resolve(scenario.load(G1, resolver)), out, progress=False)
    assert res.status == "ok", res.message
    return np.load(out / "signals.npy")


@pytest.mark.slow
def test_swapped_into_g1_with_a_name_map_it_gives_the_same_metrics(resolver, tmp_path, python_plant_run):
    plan = system.resolve(scenario.load(G1_C, resolver))
    conv = {c.spec.src: (c.factor, c.offset) for c in plan.connections}
    assert conv["plant.alpha1"] == (math.pi / 180, 0.0)              # deg -> rad into the sensor
    assert plan.instances["plant"].model.model_name == "WmrCPlant"
    res = execution.run(plan, tmp_path, progress=False)
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
        from wmr_cosim.cosim import execution, scenario, system
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        res = execution.run(system.resolve(scenario.load({str(scen)!r})), None, progress=False)
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
