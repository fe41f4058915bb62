"""Every check before the first step fails with one line naming the file, the field and the reason."""
from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from cosim_support import g1_with_paths
from wmr_cosim import cosim
from wmr_cosim.cosim.model.archive import check_archive, safe_extract
from wmr_cosim.cosim.messages.errors import CosimError, FmuLoadError, ScenarioError
from wmr_cosim.cosim.model.units import KNOWN, conversion


def _resolve(path: Path):
    return cosim.resolve(cosim.load(path))


def _rewrite_fmu(src: Path, dst: Path, old: str, new: str) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                assert old in text, old
                data = text.replace(old, new).encode()
            zout.writestr(item, data)
    return dst


BAD = {
    "unknown top key": ("HEAD colour = 1\n", "colour", "unknown key"),
    "unknown experiment key": ("[experiment]\nstpe = 0.1\n", "experiment.stpe", "unknown key"),
    "unknown instance key": ("[instances.sensor]\nfmuu = 1\n", "instances.sensor.fmuu", "unknown key"),
    "missing fmu file": ('[instances.sensor]\nfmu = "nowhere/Missing.fmu"\n', "instances.sensor.fmu", "not found"),
    "unknown model name": ('[instances.sensor]\nfmu = "NoSuchModel"\n', "instances.sensor.fmu", "unknown model name"),
    "unknown parameter": ("[instances.plant.parameters]\nfoam_dx = 1.0\n", "instances.plant.parameters.foam_dx",
                          "no variable 'foam_dx'"),
    "parameter below min": ("[instances.sensor.parameters]\nppr = -500.0\n", "instances.sensor.parameters.ppr",
                            "below the minimum"),
    "parameter above max": ("[instances.sensor.parameters]\nphase2 = 1.5\n", "instances.sensor.parameters.phase2",
                            "above the maximum"),
    "parameter of wrong type": ('[instances.controller.parameters]\ngamma = "eleven"\n',
                                "instances.controller.parameters.gamma", "type mismatch"),
    "output set as parameter": ("[instances.plant.parameters]\nx_A = 1.0\n", "instances.plant.parameters.x_A",
                                "only parameters, inputs and variables with initial exact or approx"),
    "unknown variable in connection": ('[[connections]]\nfrom = "plant.alpha9"\nto = "sensor.alpha1"\n',
                                       "connections[0].from", "no variable 'alpha9'"),
    "input driven twice": ('[[connections]]\nfrom = "plant.alpha1"\nto = "sensor.alpha1"\n'
                           '[[connections]]\nfrom = "plant.alpha2"\nto = "sensor.alpha1"\n', "connections[1].to",
                           "already driven by connections[0]"),
    "output used as target": ('[[connections]]\nfrom = "plant.alpha2"\nto = "controller.u1"\n',
                              "connections[0].to", "not an input"),
    "input used as source": ('[[connections]]\nfrom = "plant.u1"\nto = "plant.tau_d1"\n', "connections[0].from",
                             "not an output"),
    "type mismatch": ('[[connections]]\nfrom = "sensor.count1"\nto = "plant.tau_d1"\n', "connections[0]",
                      "type mismatch"),
    "unit mismatch": ('[[connections]]\nfrom = "plant.x_A"\nto = "plant.tau_d1"\n', "connections[0]",
                      "unit mismatch: plant.x_A -> plant.tau_d1: unit 'm' is incompatible with 'N.m'"),
    "step not dividing the run": ("[experiment]\nstep = 0.003\nstop = 1.0\n", "experiment.stop",
                                  "sensor: WmrSensor.fmu declares canHandleVariableCommunicationStepSize = false"),
    "bad algorithm": ('[experiment]\nalgorithm = "newton"\n', "experiment.algorithm", "must be one of"),
    "bad order": ('[experiment]\norder = ["plant", "sensor"]\n', "experiment.order", "every instance"),
    "bad reference": ('[[connections]]\nfrom = "plant"\nto = "sensor.alpha1"\n', "connections[0].from",
                      "instance.variable"),
    "record nothing": ('[record]\nvariables = ["plant.nothing*"]\n', "record.variables[0]", "matches no output"),
    "bad decimation": ("[record]\ndecimation = 0\n", "record.decimation", "integer >= 1"),
    "event on a parameter": ('[[events]]\ntime = 1.0\nvariable = "plant.a1"\nvalue = 1.0\n', "events[0].variable",
                             "must be an input or output"),
    "event outside the run": ('[[events]]\ntime = 99.0\nvariable = "plant.tau_d1"\nvalue = 1.0\n', "events[0].time",
                              "outside the run"),
    "event without value": ('[[events]]\ntime = 1.0\nvariable = "plant.tau_d1"\n', "events[0].value", "missing"),
    "not toml": ("[experiment\n", "", "not valid TOML"),
    "run without name": ("[[runs]]\nparameters = {}\n", "runs[0].name", "needs a name"),
    "carry from unknown run": ('[[runs]]\nname = "a"\ncarry = {"controller.W1_init" = "zzz.controller.W1"}\n',
                               "runs[0].carry.controller.W1_init", "no earlier run named 'zzz'"),
    "run parameter of unknown instance": ('[[runs]]\nname = "a"\nparameters = {"robot.x" = 1}\n',
                                          "runs[0].parameters.robot.x", "unknown instance 'robot'"),
    "variant key": ("[variants.v]\nparams = {}\n", "variants.v.params", "unknown key"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scenario_is_refused_with_file_field_and_reason(case, built_fmus, tmp_path):
    extra, field, reason = BAD[case]
    if extra.startswith("HEAD "):
        path = g1_with_paths(tmp_path, built_fmus, head=extra[5:])
    else:
        skip = ("sensor",) if extra.startswith("[instances.sensor]") else ()
        whole = 'replace = ["connections"]\n' if "[[connections]]" in extra else ""   # (the case's, not G1's)
        path = g1_with_paths(tmp_path, built_fmus, "\n" + extra, skip=skip, head=whole)
    with pytest.raises(ScenarioError) as exc:
        _resolve(path)
    msg = str(exc.value)
    assert "\n" not in msg
    assert msg.startswith(str(path)), msg
    assert exc.value.field == field, msg
    assert reason in msg, msg


def test_an_fmu_without_the_interface_asked_for_or_not_fmi2_is_refused(built_fmus, tmp_path):
    bad = _rewrite_fmu(built_fmus["WmrSensor"], tmp_path / "me.fmu", "<CoSimulation", "<ModelExchange")
    bad2 = _rewrite_fmu(built_fmus["WmrSensor"], tmp_path / "v1.fmu", 'fmiVersion="2.0"', 'fmiVersion="1.0"')
    for fmu, extra, field, why in (
            (bad, 'interface = "co-simulation"\n', "instances.sensor.interface",
             "me.fmu has no co-simulation interface (it has model exchange only)"),
            (bad2, "", "instances.sensor.fmu", "only FMI 2.0 and 3.0")):
        path = g1_with_paths(tmp_path, built_fmus, f'[instances.sensor]\nfmu = "{fmu}"\n{extra}',
                             name=f"{fmu.stem}.toml", skip=("sensor",))
        with pytest.raises(ScenarioError, match=re.escape(why)) as exc:
            _resolve(path)
        assert exc.value.field == field


def test_a_fixed_step_fmu_accepts_any_constant_step(built_fmus, tmp_path):
    """canHandleVariableCommunicationStepSize="false" asks for a constant step; the default experiment's
    step is a suggestion, not a requirement."""
    fixed = built_fmus["WmrSensor"]   # a sampled-data block: it declares false
    assert 'canHandleVariableCommunicationStepSize="false"' in zipfile.ZipFile(fixed).read("modelDescription.xml").decode()
    for step in (0.004, 0.001):
        path = g1_with_paths(tmp_path, built_fmus, f'[instances.sensor]\nfmu = "{fixed}"\n[experiment]\nstep = {step}\n',
                             name=f"s{step}.toml", skip=("sensor",))
        plan = _resolve(path)
        assert plan.scenario.step == step and plan.n_steps == round(50.0 / step)


def test_override_of_unknown_instance_or_parameter(built_fmus, tmp_path):
    path = g1_with_paths(tmp_path, built_fmus)
    with pytest.raises(ScenarioError, match="unknown instance 'robot'"):
        cosim.load(path, None, {"robot.gamma": 3})
    with pytest.raises(ScenarioError, match="no variable 'gama'"):
        cosim.resolve(cosim.load(path, None, {"controller.gama": 3}))


def test_units_convert_or_refuse():
    assert conversion(KNOWN["deg"], KNOWN["rad"])[0] == pytest.approx(0.017453292519943295, rel=1e-15)
    assert conversion(KNOWN["rpm"], KNOWN["rad/s"])[0] == pytest.approx(0.10471975511965977)
    f, o = conversion(KNOWN["degC"], KNOWN["K"])
    assert (f, o) == (1.0, 273.15)
    assert conversion(None, KNOWN["m"]) == (1.0, 0.0)
    with pytest.raises(CosimError, match="incompatible"):
        conversion(KNOWN["N.m"], KNOWN["rad"])


def _evil_zip(path: Path, kind: str) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("modelDescription.xml", "<fmiModelDescription/>")
        if kind == "dotdot":
            zf.writestr("../escaped.txt", "x")
        elif kind == "absolute":
            zf.writestr("/tmp/escaped_abs.txt", "x")
        elif kind == "symlink":
            info = zipfile.ZipInfo("resources/link")
            info.external_attr = (0o120777 << 16)
            zf.writestr(info, "/etc/passwd")
    return path


@pytest.mark.parametrize("kind", ["dotdot", "absolute", "symlink"])
def test_unsafe_archive_is_refused_before_anything_is_written(tmp_path, kind):
    box = tmp_path / "box"
    box.mkdir()
    evil = _evil_zip(box / "evil.fmu", kind)
    dest = box / "extract"
    before = set(tmp_path.rglob("*"))
    with pytest.raises(FmuLoadError, match="refused") as exc:
        safe_extract(evil, dest)
    assert "evil.fmu" in str(exc.value)
    assert set(tmp_path.rglob("*")) == before   # nothing written, not even the folder
    assert not Path("/tmp/escaped_abs.txt").exists()
    with pytest.raises(FmuLoadError):
        check_archive(evil)


def test_cli_check_and_info(built_fmus, tmp_path):
    path = g1_with_paths(tmp_path, built_fmus)
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "check", str(path)], capture_output=True, text=True)
    assert p.returncode == 0 and "11 connections" in p.stdout, p.stderr
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "check", str(path), "--set", "sensor.ppr=-1"],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "instances.sensor.parameters.ppr" in p.stderr
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "info", str(built_fmus["WmrPlant"])],
                       capture_output=True, text=True)
    assert p.returncode == 0 and "foam_da1" in p.stdout and "N.m" in p.stdout
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "info", str(tmp_path / "missing.fmu")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "not found" in p.stderr and "Traceback" not in p.stderr
    for cmd in ("run", "check", "info", "build", "direct"):
        h = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", cmd, "--help"], capture_output=True, text=True)
        assert h.returncode == 0 and "usage" in h.stdout


def test_protocol_errors(built_fmus, tmp_path):
    from wmr_cosim.cosim.runtime.protocol import plan_runs, run_protocol

    path = g1_with_paths(tmp_path, built_fmus, """
[experiment]
stop = 0.1
[record]
variables = ["plant.x_A"]
[[runs]]
name = "a"
[[runs]]
name = "b"
carry = { "controller.W1_init" = "a.controller.W1" }
""")
    with pytest.raises(ScenarioError, match="--variant nope: not declared"):
        plan_runs(path, None, "nope")
    with pytest.raises(ScenarioError, match=r"runs.b.carry.controller.W1_init: 'a.controller.W1' was not recorded"):
        run_protocol(path, tmp_path / "out", None, progress=False)
