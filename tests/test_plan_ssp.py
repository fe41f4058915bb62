"""SSP 1.0 export and import (cosim/plan/ssp.py, `wmr-cosim export-ssp`, `wmr-cosim run FILE.ssp`): the archive's
content and schema validity, a foreign archive, one-line errors for bad or foreign archives, and archives
whose entries would extract outside their folder refused before anything is written."""
from __future__ import annotations

import os
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree as ET

from cosim_support import G1, g1_with_paths
from wmr_cosim import cosim
from wmr_cosim.cosim.scenario import document as scenario
from wmr_cosim.cosim.messages.errors import ScenarioError
from wmr_cosim.cosim.plan.ssp import NS, OSP_NS, export_ssp, load_ssp, validate_xml


@pytest.fixture(scope="module")
def resolver(built_fmus):
    return lambda name: built_fmus.get(name)


def _plan(path, resolver, **over):
    sc = scenario.load(path, resolver)
    for k, v in over.items():
        setattr(sc, k, v)
    return cosim.resolve(sc)


@pytest.fixture(scope="module")
def g1_ssp(resolver, tmp_path_factory):
    out = tmp_path_factory.mktemp("ssp") / "g1.ssp"
    return export_ssp(_plan(G1, resolver), out)


def _cli(*args, env=None, cwd=None):
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", *map(str, args)], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300)


def test_export_writes_a_valid_ssp_archive(g1_ssp, built_fmus):
    with zipfile.ZipFile(g1_ssp) as zf:
        names = set(zf.namelist())
        ssd = zf.read("SystemStructure.ssd")
        ssv = zf.read("resources/controller.ssv")
        # the FMUs travel as resources, byte for byte
        assert zf.read("resources/WmrPlant.fmu") == built_fmus["WmrPlant"].read_bytes()
    assert {"SystemStructure.ssd", "resources/WmrPlant.fmu", "resources/WmrSensor.fmu", "resources/WmrController.fmu",
            "resources/controller.ssv"} <= names
    validate_xml(ssd, "ssd", "SystemStructure.ssd")      # SSP 1.0 schema
    validate_xml(ssv, "ssv", "controller.ssv")
    root = ET.fromstring(ssd)
    assert root.get("version") == "1.0"
    comps = {c.get("name"): c for c in root.findall("ssd:System/ssd:Elements/ssd:Component", NS)}
    assert set(comps) == {"plant", "sensor", "controller"}
    assert comps["plant"].get("source") == "resources/WmrPlant.fmu"
    assert comps["plant"].get("type") == "application/x-fmu-sharedlibrary"
    kinds = {c.get("name"): c.get("kind") for c in comps["plant"].findall("ssd:Connectors/ssd:Connector", NS)}
    assert kinds["u1"] == "input" and kinds["alpha1"] == "output"
    real = comps["plant"].find("ssd:Connectors/ssd:Connector[@name='alpha1']/ssc:Real", NS)
    assert real.get("unit") == "rad"
    assert {u.get("name") for u in root.findall("ssd:Units/ssc:Unit", NS)} >= {"rad", "N.m", "rad/s", "m"}
    conns = root.findall("ssd:System/ssd:Connections/ssd:Connection", NS)
    assert len(conns) == 11
    de = root.find("ssd:DefaultExperiment", NS)
    assert (float(de.get("startTime")), float(de.get("stopTime"))) == (0.0, 50.0)
    assert float(de.find(f".//{{{OSP_NS}}}FixedStepAlgorithm").get("baseStepSize")) == 0.002
    # the parameter values: one SSV parameter set per component, all named "parameters"
    pset = ET.fromstring(ssv)
    assert pset.get("name") == "parameters"
    values = {p.get("name"): p[0] for p in pset.findall("ssv:Parameters/ssv:Parameter", NS)}
    assert values["goal_x"].get("value") == "2.0" and ET.QName(values["goal_x"]).localname == "Real"
    assert ET.QName(values["adapt"]).localname == "Boolean"
    # task = "goal" (a String, the FMU's default) is held back from the set and the connectors, which
    # OMSimulator cannot import with a String in them, into our own annotation on the system
    assert "task" not in values
    assert "task" not in {c.get("name") for c in comps["controller"].findall("ssd:Connectors/ssd:Connector", NS)}
    held = root.findall("ssd:System/ssd:Annotations/ssc:Annotation[@type='org.wmr-cosim.parameters']/*", NS)
    assert [(e.get("component"), e.get("name"), e.get("value")) for e in held] == [("controller", "task", "goal")]
    binding = comps["controller"].find("ssd:ParameterBindings/ssd:ParameterBinding", NS)
    assert binding.get("source") == "resources/controller.ssv"


def test_fmpy_reads_the_exported_system_structure(g1_ssp):
    from fmpy.ssp.ssd import read_ssd  # a third-party reader, validating against its own copy of the schema
    ssd = read_ssd(str(g1_ssp), validate=True)
    assert sorted(c.name for c in ssd.system.elements) == ["controller", "plant", "sensor"]
    assert len(ssd.system.connections) == 11


def test_linear_transform_goes_out_and_comes_back(resolver, tmp_path, built_fmus):
    path = g1_with_paths(tmp_path, built_fmus, """
[experiment]
stop = 0.1
[[connections]]
from = "controller.dF_hat1"
to = "plant.tau_d1"
factor = 0.5
offset = 0.25
""")
    out = export_ssp(_plan(path, None), tmp_path / "lt.ssp")
    root = ET.fromstring(zipfile.ZipFile(out).read("SystemStructure.ssd"))
    lt = root.findall(".//ssd:Connection/ssc:LinearTransformation", NS)
    assert [(float(e.get("factor")), float(e.get("offset"))) for e in lt] == [(0.5, 0.25)]
    arch = load_ssp(out)
    try:
        c = [c for c in arch.scenario.connections if c.dst == "plant.tau_d1"][0]
        assert (c.src, c.factor, c.offset) == ("controller.dF_hat1", 0.5, 0.25)
        assert arch.scenario.algorithm == "gauss-seidel" and arch.scenario.order == ["plant", "sensor", "controller"]
        assert (arch.scenario.step, arch.scenario.stop) == (0.002, 0.1)
    finally:
        arch.cleanup()
    assert not arch.folder.exists()


def test_export_refuses_events(resolver, tmp_path, built_fmus):
    path = g1_with_paths(tmp_path, built_fmus, '[[events]]\ntime = 1.0\nvariable = "plant.tau_d1"\nvalue = 0.1\n')
    with pytest.raises(ScenarioError, match="events cannot be expressed in SSP 1.0"):
        export_ssp(_plan(path, None), tmp_path / "ev.ssp")
    assert not (tmp_path / "ev.ssp").exists()


def test_cli_export_check_and_run(g1_ssp, tmp_path, built_fmus):
    scen = g1_with_paths(tmp_path, built_fmus, "[experiment]\nstop = 1.0\n")
    p = _cli("export-ssp", scen, "--out", tmp_path / "short.ssp", "--set", "controller.goal_x=1.5")
    assert p.returncode == 0, p.stderr
    p = _cli("check", tmp_path / "short.ssp")
    assert p.returncode == 0 and "3 instances" in p.stdout and "500 steps of 0.002 s (gauss-seidel)" in p.stdout, p
    p = _cli("run", tmp_path / "short.ssp", "--out", tmp_path / "res", "--quiet")
    assert p.returncode == 0, p.stderr
    import json
    resolved = json.loads((tmp_path / "res" / "scenario.json").read_text())
    assert resolved["instances"]["controller"]["parameters"]["goal_x"] == 1.5   # the SSV's value, applied
    assert np.load(tmp_path / "res" / "signals.npy")["time"][-1] == 1.0
    p = _cli("export-ssp", scen, "--out", tmp_path / "x.zip")
    assert p.returncode == 2 and "ends in .ssp" in p.stderr


def _run_signals(plan, out: Path) -> np.ndarray:
    res = cosim.run(plan, out, progress=False)
    assert res.status == "ok", res.message
    return np.load(out / "signals.npy")


@pytest.mark.parametrize("task", ["goal", "line"])
def test_a_string_parameter_reaches_our_master_through_the_archive(task, tmp_path, built_fmus):
    """OMSimulator imports neither a String connector nor a String parameter.  At the FMU's default ("goal",
    the controller's task in scenarios/g1_learn.toml) it is held back from the parameter set and the
    connectors into our own annotation; at another value ("line") it stays in the set, where libcosim and
    ecos apply it too.  Either way our run of the archive is our run of the scenario."""
    from wmr_cosim.components.paper import task_controller

    params = {"goal": {"task": "goal"}, "line": task_controller("LINE")}[task]
    extra = "[experiment]\nstop = 1.0\n[instances.controller.parameters]\n" + "".join(
        f"{k} = {v!r}\n".replace("'", '"') for k, v in params.items())
    path = g1_with_paths(tmp_path, built_fmus, extra)
    plan = _plan(path, None)
    assert dict((v.name, x) for v, x in plan.instances["controller"].parameters)["task"] == task
    out = export_ssp(plan, tmp_path / "s.ssp")
    with zipfile.ZipFile(out) as zf:
        root = ET.fromstring(zf.read("SystemStructure.ssd"))
        ssv = ET.fromstring(zf.read("resources/controller.ssv"))
    in_set = {p.get("name"): p[0] for p in ssv.findall("ssv:Parameters/ssv:Parameter", NS)}
    connectors = {c.get("name") for c in root.findall("ssd:System/ssd:Elements/ssd:Component[@name='controller']"
                                                       "/ssd:Connectors/ssd:Connector", NS)}
    held = root.findall("ssd:System/ssd:Annotations/ssc:Annotation[@type='org.wmr-cosim.parameters']/*", NS)
    if task == "goal":
        assert "task" not in in_set and "task" not in connectors
        assert [(e.get("component"), e.get("name"), e.get("value")) for e in held] == [("controller", "task", "goal")]
    else:
        assert in_set["task"].get("value") == "line" and ET.QName(in_set["task"]).localname == "String"
        assert "task" in connectors and held == []
    arch = load_ssp(out)
    try:
        assert arch.scenario.instances["controller"].parameters["task"] == task
        from_ssp = _run_signals(cosim.resolve(arch.scenario), tmp_path / "from_ssp")
    finally:
        arch.cleanup()
    from_toml = _run_signals(_plan(path, None), tmp_path / "from_toml")
    for name in from_toml.dtype.names:
        assert np.array_equal(from_ssp[name], from_toml[name]), name
    if task == "line":  # (the value matters: the default task gives another run)
        default = _run_signals(_plan(g1_with_paths(tmp_path, built_fmus, "[experiment]\nstop = 1.0\n", name="d.toml"),
                                     None), tmp_path / "default")
        assert not np.array_equal(default["plant.x_A"], from_toml["plant.x_A"])


def test_export_ssp_names_the_string_parameter_and_omsimulators_jacobi_master(tmp_path, built_fmus, capsys):
    from wmr_cosim.runner import export_ssp as export_file

    export_file(g1_with_paths(tmp_path, built_fmus), tmp_path / "g1.ssp")      # Gauss-Seidel, task = "goal"
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2, err
    assert err[0].startswith("wmr-cosim: warning: controller.task = 'goal' (String) is left out of the parameter set")
    assert "the FMU's default" in err[0]
    assert err[1].startswith("wmr-cosim: note: OMSimulator runs the archive as Jacobi") and "gauss-seidel" in err[1].lower()
    line = g1_with_paths(tmp_path, built_fmus, '[experiment]\nalgorithm = "jacobi"\n[instances.controller.parameters]\n'
                         'task = "line"\nb1 = 5.0\nline_b2 = 15.0\n', name="line.toml")
    export_file(line, tmp_path / "line.ssp")
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1, err                                                   # Jacobi: no note
    assert err[0].startswith("wmr-cosim: warning: controller.task = 'line' (String) stays in the parameter set")
    assert "OMSimulator cannot set a String parameter" in err[0] and "default 'goal'" in err[0]


def _pyssp_foreign_archive(path: Path, built_fmus) -> Path:
    """An archive written with pyssp-standard's API the way another tool would: FMUs in a sub-folder,
    parameters inline at system level (names component.variable), no step annotation (the FMUs' default
    experiment gives it), connectors only for what is connected."""
    from pyssp_standard import SSP
    from pyssp_standard.common_content_ssc import TypeReal
    from pyssp_standard.ssd import SSD, Component, Connection, Connector, DefaultExperiment, ParameterBinding, System
    from pyssp_standard.ssv import SSVElem
    from pyssp_standard.parameter_types import ParameterType

    tmp = path.parent / "foreign_src"
    tmp.mkdir()
    wires = [("plant", "alpha1", "sensor", "alpha1"), ("plant", "alpha2", "sensor", "alpha2"),
             ("sensor", "alpha_m1", "controller", "alpha_m1"), ("sensor", "alpha_m2", "controller", "alpha_m2"),
             ("sensor", "alpha_dot_m1", "controller", "alpha_dot_m1"),
             ("sensor", "alpha_dot_m2", "controller", "alpha_dot_m2"),
             ("controller", "u1", "plant", "u1"), ("controller", "u2", "plant", "u2")]
    with SSD(tmp / "SystemStructure.ssd", mode="w") as ssd:
        ssd.name, ssd.version = "foreign", "1.0"
        sysm = System(name="root")
        for inst, model in (("plant", "WmrPlant"), ("sensor", "WmrSensor"), ("controller", "WmrController")):
            c = Component()
            c.name, c.component_type, c.source = inst, "application/x-fmu-sharedlibrary", f"resources/fmus/{model}.fmu"
            for a, av, b, bv in wires:
                if a == inst:
                    c.connectors.append(Connector(name=av, kind="output", type_=TypeReal(None)))
                if b == inst:
                    c.connectors.append(Connector(name=bv, kind="input", type_=TypeReal(None)))
            sysm.elements.append(c)
        for a, av, b, bv in wires:
            sysm.connections.append(Connection(start_element=a, start_connector=av, end_element=b, end_connector=bv))
        pset = SSVElem(name="set1", parameters=[{"name": "controller.goal_x", "type_name": "Real",
                                                 "type_value": ParameterType("Real", {"value": "1.25", "unit": "m"})}])
        sysm.parameter_bindings = [ParameterBinding(ssv=pset)]
        ssd.system = sysm
        de = DefaultExperiment()
        de.start_time, de.stop_time = 0.0, 0.5
        ssd.default_experiment = de
    with SSP(path, mode="w") as ssp:
        ssp.add_file(tmp / "SystemStructure.ssd")
        for model in ("WmrPlant", "WmrSensor", "WmrController"):
            ssp.add_file(built_fmus[model], "resources/fmus")
    return path


def test_a_foreign_archive_runs(tmp_path, built_fmus):
    path = _pyssp_foreign_archive(tmp_path / "foreign.ssp", built_fmus)
    arch = load_ssp(path)
    try:
        sc = arch.scenario
        assert sc.instances["controller"].parameters == {"goal_x": 1.25}
        plan = cosim.resolve(sc)
        assert (plan.scenario.step, plan.scenario.stop, plan.scenario.algorithm) == (0.002, 0.5, "jacobi")
        assert sc.step is None              # the step from the FMUs, into the plan's copy; SSP tools' Jacobi
        res = cosim.run(plan, tmp_path / "out", progress=False)
        assert res.status == "ok" and res.steps == 250, res.message
        assert "controller.u1" in res.columns
    finally:
        arch.cleanup()


# ------------------------------------------------------------------------------- bad and foreign archives
def _rewrite(src: Path, dst: Path, edit=None, drop=(), add=()) -> Path:
    """A copy of an archive with SystemStructure.ssd edited (text -> text), entries dropped or added."""
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w") as zo:
        for info in zi.infolist():
            if info.filename in drop:
                continue
            data = zi.read(info)
            if info.filename == "SystemStructure.ssd" and edit is not None:
                data = edit(data.decode()).encode()
            zo.writestr(info, data)
        for name, data in add:
            zo.writestr(name, data)
    return dst


def _me_only_fmu(src: Path, dst: Path) -> Path:
    """A model-exchange-only FMU (its model description says so)."""
    def md(text):
        return text.replace("<CoSimulation", "<ModelExchange").replace("</CoSimulation>", "</ModelExchange>")
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w") as zo:
        for info in zi.infolist():
            data = zi.read(info)
            zo.writestr(info, md(data.decode()).encode() if info.filename == "modelDescription.xml" else data)
    return dst


@pytest.fixture(scope="module")
def bad_archives(g1_ssp, built_fmus, tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    me = _me_only_fmu(built_fmus["WmrSensor"], d / "me.fmu")
    return {
        "missing resource": (_rewrite(g1_ssp, d / "missing.ssp", drop=("resources/WmrSensor.fmu",)),
                             "resource 'resources/WmrSensor.fmu' is missing from the archive"),
        "unknown connector": (_rewrite(g1_ssp, d / "connector.ssp",
                                       edit=lambda t: t.replace('name="alpha_m1" kind="output"',
                                                                'name="alpha_mX" kind="output"', 1)),
                              "unknown connector: resources/WmrSensor.fmu has no variable 'alpha_mX'"),
        "SSP 2.0 namespace": (_rewrite(g1_ssp, d / "ns2.ssp", edit=lambda t: t.replace("SSP1/", "SSP2/")),
                              "not an SSP 1.0 system structure"),
        "model exchange FMU": (_rewrite(g1_ssp, d / "me.ssp", drop=("resources/WmrSensor.fmu",),
                                        add=(("resources/WmrSensor.fmu", me.read_bytes()),),
                                        edit=lambda t: t.replace('source="resources/WmrSensor.fmu"',
                                                                 'source="resources/WmrSensor.fmu" '
                                                                 'implementation="CoSimulation"', 1)),
                               "implementation 'CoSimulation': resources/WmrSensor.fmu has no co-simulation "
                               "interface (it has model exchange only)"),
        "not valid": (_rewrite(g1_ssp, d / "invalid.ssp", edit=lambda t: t.replace("<ssd:Elements>",
                                                                                  "<ssd:Bogus/><ssd:Elements>", 1)),
                      "not valid against the SSP 1.0 schema"),
        "no system structure": (_rewrite(g1_ssp, d / "nossd.ssp", drop=("SystemStructure.ssd",)),
                                "no SystemStructure.ssd"),
        "not a zip": ((d / "text.ssp").resolve(), "not a zip archive"),
        "held String of no component": (_rewrite(g1_ssp, d / "held.ssp", edit=lambda t: t.replace(
            'component="controller" name="task"', 'component="ctrl" name="task"', 1)),
            "String parameter 'task': component 'ctrl' is not in the system"),
    }


@pytest.mark.parametrize("case", ["missing resource", "unknown connector", "SSP 2.0 namespace",
                                  "model exchange FMU", "not valid", "no system structure", "not a zip",
                                  "held String of no component"])
def test_a_bad_or_foreign_archive_gives_one_line(bad_archives, case, tmp_path):
    path, expected = bad_archives[case]
    if case == "not a zip":
        path.write_text("not an archive")
    with pytest.raises(ScenarioError, match=expected.replace("(", r"\(").replace(")", r"\)")):
        load_ssp(path)
    p = _cli("run", path, "--out", tmp_path / "out", "--quiet")
    assert p.returncode == 2, p
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in p.stderr and expected.split(":")[0] in lines[0], p.stderr


def test_version_2_with_the_ssp_1_namespaces_is_read_with_a_warning(g1_ssp, tmp_path):
    """OMSimulator writes SSDs that say version "2.0" but use the SSP 1.0 namespaces."""
    path = _rewrite(g1_ssp, tmp_path / "oms.ssp", edit=lambda t: t.replace('version="1.0"', 'version="2.0"', 1))
    arch = load_ssp(path)
    try:
        assert len(arch.warnings) == 1 and "version '2.0'" in arch.warnings[0]
        assert set(arch.scenario.instances) == {"plant", "sensor", "controller"}
    finally:
        arch.cleanup()
    p = _cli("check", path)
    assert p.returncode == 0, p.stderr
    assert p.stderr.count("warning") == 1 and "SSP 1.0 namespaces" in p.stderr


# ------------------------------------------------------------------------------- archives escaping their folder
def _evil_zip(path: Path, kind: str, inner_ok: Path | None = None) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        if inner_ok is not None:
            with zipfile.ZipFile(inner_ok) as zi:
                for info in zi.infolist():
                    zf.writestr(info, zi.read(info))
        if kind == "dotdot":
            zf.writestr("../../evil_dotdot.txt", "x")
        elif kind == "dotdot-inside":   # climbs out from the middle of its path
            zf.writestr("resources/../../evil_dotdot.txt", "x")
        elif kind == "absolute":
            zf.writestr(str(path.parent / "evil_absolute.txt"), "x")
        elif kind == "symlink":
            info = zipfile.ZipInfo("resources/evil_link")
            info.external_attr = (stat.S_IFLNK | 0o777) << 16
            zf.writestr(info, str(path.parent / "evil_target.txt"))
    return path


@pytest.mark.parametrize("kind", ["dotdot", "dotdot-inside", "absolute", "symlink"])
def test_an_escaping_ssp_is_refused_before_anything_is_written(kind, g1_ssp, tmp_path):
    work = tmp_path / "work"
    (work / "tmp").mkdir(parents=True)
    bad = _evil_zip(work / "bad.ssp", kind, inner_ok=g1_ssp)
    before = sorted(p for p in tmp_path.rglob("*"))
    env = dict(os.environ, TMPDIR=str(work / "tmp"))   # every extraction folder would land here
    p = _cli("run", bad, "--out", work / "out", "--quiet", env=env)
    assert p.returncode == 2 and "refused" in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
    after = sorted(p for p in tmp_path.rglob("*"))
    assert after == before                    # nothing extracted, no results folder, no temporary folder
    assert not list(tmp_path.parent.glob("evil_*")) and not (tmp_path.parent.parent / "evil_dotdot.txt").exists()


@pytest.mark.parametrize("kind", ["dotdot", "symlink"])
def test_an_escaping_fmu_inside_an_ssp_or_a_scenario_is_refused(kind, g1_ssp, built_fmus, tmp_path):
    work = tmp_path / "work"
    (work / "tmp").mkdir(parents=True)
    evil_fmu = _evil_zip(work / "WmrSensor.fmu", kind, inner_ok=built_fmus["WmrSensor"])
    bad_ssp = _rewrite(g1_ssp, work / "inner.ssp", drop=("resources/WmrSensor.fmu",),
                       add=(("resources/WmrSensor.fmu", evil_fmu.read_bytes()),))
    scen = g1_with_paths(work, {**built_fmus, "WmrSensor": evil_fmu}, "[experiment]\nstop = 0.1\n")
    env = dict(os.environ, TMPDIR=str(work / "tmp"))
    for target in (bad_ssp, scen):
        before = sorted(tmp_path.rglob("*"))
        p = _cli("run", target, "--out", work / "out", "--quiet", env=env)
        assert p.returncode == 2 and "refused" in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
        assert sorted(tmp_path.rglob("*")) == before
