"""The FMUs' model descriptions (validation, units, ranges, causality, structure) and their build
(unique bundle names, idempotence, a rebuilt FMU runs its new code)."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from wmr_cosim.components.controller import CONTROLLER_OUTPUTS, ControllerParams
from wmr_cosim.components.plant import PLANT_OUTPUTS, PlantParams
from wmr_cosim.components.sensor import SENSOR_OUTPUTS, SensorParams
from wmr_cosim.fmus import build as fbuild

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("WmrPlant", "WmrSensor", "WmrController")
OUTPUTS = {"WmrPlant": PLANT_OUTPUTS, "WmrSensor": SENSOR_OUTPUTS, "WmrController": CONTROLLER_OUTPUTS}
PARAMS = {"WmrPlant": PlantParams, "WmrSensor": SensorParams, "WmrController": ControllerParams}
INPUTS = {"WmrPlant": ("u1", "u2", "tau_d1", "tau_d2"), "WmrSensor": ("alpha1", "alpha2"),
          "WmrController": ("alpha_m1", "alpha_m2", "alpha_dot_m1", "alpha_dot_m2", "x_true", "y_true", "beta_true")}


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validation_reports_no_problem(built_fmus, model):
    assert validate_fmu(str(built_fmus[model])) == []


@pytest.mark.parametrize("model", MODELS)
def test_variables_units_ranges_causality(built_fmus, model):
    md = read_model_description(str(built_fmus[model]))
    assert md.modelName == model
    assert md.coSimulation.modelIdentifier == model
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert not md.coSimulation.canInterpolateInputs  # pythonfmu does not implement it
    # the plant integrates over any step; the sensor chain and the controller sample at their step
    assert md.coSimulation.canHandleVariableCommunicationStepSize == (model == "WmrPlant")
    assert not md.coSimulation.canBeInstantiatedOnlyOncePerProcess
    de = md.defaultExperiment
    assert (float(de.startTime), float(de.stopTime), float(de.stepSize)) == (0.0, 50.0, 0.002)
    units = {u.name for u in md.unitDefinitions}
    by = {v.name: v for v in md.modelVariables}
    for v in md.modelVariables:
        assert v.description, v.name
        if v.type == "Real":
            assert v.unit in units, v.name
        if v.causality == "parameter":
            assert v.variability in ("fixed", "tunable") and v.initial == "exact" and v.start is not None, v.name
            if v.type in ("Real", "Integer"):  # a master can refuse a bad value before instantiating
                assert v.min is not None, v.name
    # names: the component's outputs, inputs and dataclass fields (tuples as scalars)
    assert [v.name for v in md.modelVariables if v.causality == "output"] == list(OUTPUTS[model])
    assert tuple(v.name for v in md.modelVariables if v.causality == "input") == INPUTS[model]
    fields = set(PARAMS[model].__dataclass_fields__) - {"W_init", "P_init"}
    params = {v.name for v in md.modelVariables if v.causality == "parameter"}
    if model == "WmrController":
        fields |= {"W1_init", "W2_init", "W3_init", "P11_init", "P12_init", "P13_init", "P22_init", "P23_init",
                   "P33_init"}
    assert params == fields
    # the start values are the components' defaults, exactly
    d = PARAMS[model]()
    for name in params & set(d.__dataclass_fields__):
        default, v = getattr(d, name), by[name]
        if v.type in ("Real", "Integer"):
            assert float(v.start) == default, name
            assert float(v.min) <= default and (v.max is None or default <= float(v.max)), name
        else:
            assert v.start == (str(default).lower() if v.type == "Boolean" else default), name
    if model == "WmrController":
        assert float(by["W2_init"].start) == d.W_init[1] and float(by["P33_init"].start) == d.P_init[5]
        assert by["adapting"].type == "Boolean"
        tunable = {v.name for v in md.modelVariables if v.variability == "tunable"}
        assert tunable == {"goal_x", "goal_y", "adapt", "adapt_t_start", "adapt_t_end", "gamma"}
    if model == "WmrSensor":
        assert by["count1"].type == by["count2"].type == "Integer"
        assert (float(by["phase1"].min), float(by["phase1"].max)) == (0.0, 1.0)
    if model == "WmrPlant":
        assert by["u1"].unit == "N.m" and by["x_A"].unit == "m" and by["alpha_dot1"].unit == "rad/s"
        assert float(by["r"].min) > 0.0
        assert {v.name for v in md.modelVariables if v.variability == "tunable"} == {"foam_da1", "foam_da2"}


def test_model_structure_tells_the_truth(built_fmus):
    """Plant outputs: no direct feedthrough; sensor outputs: their own wheel's angle; controller: the
    declared subsets; every output an InitialUnknown whose input dependencies match."""
    deps = {}
    for model in MODELS:
        md = read_model_description(str(built_fmus[model]))
        outs = {u.variable.name: sorted(d.name for d in u.dependencies) for u in md.outputs}
        init = {u.variable.name: sorted(d.name for d in u.dependencies if d.causality == "input")
                for u in md.initialUnknowns}
        assert set(init) == set(outs) == set(OUTPUTS[model])
        for u in md.initialUnknowns:  # parameters may be listed (they are knowns), nothing else
            assert all(d.causality in ("input", "parameter") for d in u.dependencies)
        deps[model] = (outs, init)
    p_out, p_init = deps["WmrPlant"]
    assert all(d == [] for d in p_out.values()) and all(d == [] for d in p_init.values())
    s_out, s_init = deps["WmrSensor"]
    for name, d in s_out.items():
        assert d == [f"alpha{name[-1]}"], name
    assert s_init["count1"] == ["alpha1"] and s_init["alpha_m1"] == []
    c_out, c_init = deps["WmrController"]
    assert c_out == c_init
    for name in ("W1", "W2", "W3", "P11", "P33", "P_norm", "adapting"):
        assert c_out[name] == [], name
    assert c_out["u1"] == sorted(INPUTS["WmrController"])
    assert c_out["x_hat"] == ["alpha_m1", "alpha_m2", "x_true"]


def test_bundle_is_unique_and_self_contained(built_fmus):
    modules = set()
    for model in MODELS:
        plan = fbuild.plan(model)
        with zipfile.ZipFile(built_fmus[model]) as zf:
            names = zf.namelist()
            slave_module = zf.read("resources/slavemodule.txt").decode().strip()
            script = zf.read(f"resources/{slave_module}.py").decode()
        assert slave_module == plan.module and plan.hash8 in slave_module
        assert f"resources/{plan.package}/paper_results.json" in names
        assert f"resources/{plan.package}/fmi_base.py" in names
        assert f"from {plan.package}." in script
        for line in script.splitlines():
            assert not line.lstrip().startswith(("import wmr_cosim", "from wmr_cosim")), line
        modules |= {slave_module, plan.package}
        assert (built_fmus[model].parent / f"{model}.fmu.sha256").read_text().strip() == plan.digest
    assert len(modules) == 6  # no two FMUs share a module or package name


def test_build_is_idempotent(tmp_path):
    out = tmp_path / "out"
    paths = fbuild.build_all(out)
    stamps = {m: p.stat().st_mtime_ns for m, p in paths.items()}
    assert all(fbuild.up_to_date(out).values())
    again = fbuild.build_all(out)
    assert again == paths and {m: p.stat().st_mtime_ns for m, p in again.items()} == stamps
    (out / "WmrSensor.fmu.sha256").write_text("0" * 64)  # as if the sources had changed
    fbuild.build_all(out)
    assert paths["WmrSensor"].stat().st_mtime_ns != stamps["WmrSensor"]
    assert paths["WmrPlant"].stat().st_mtime_ns == stamps["WmrPlant"]
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [f"{m}.fmu" for m in MODELS] + [f"{m}.fmu.sha256" for m in MODELS])


def test_cli_build(tmp_path):
    from wmr_cosim.cli import main
    out = tmp_path / "cli out"
    assert main(["build", "--out", str(out)]) == 0
    assert all((out / f"{m}.fmu").is_file() for m in MODELS)
    assert main(["build", "--out", str(out / "WmrPlant.fmu")]) == 2  # not a directory


_RUN_PLANT = r"""
import sys
from pathlib import Path
sys.path.insert(0, {tests!r})
from fmu_support import Fmu
for i, path in enumerate(sys.argv[1:]):
    f = Fmu(Path(path), f"p{{i}}")
    f.init()
    f.step(0.0, 0.002, (1.0, 1.0, 0.0, 0.0))
    print(f.get("foam_level"))
    f.free()
"""


def test_rebuilt_fmu_runs_new_code(tmp_path):
    """A rebuilt FMU loaded in a process that loaded the old build would run the old code (module cache):
    after a source change the rebuilt FMU has new module names, so the next process, even one that
    loaded the old build first, runs the new code."""
    src = tmp_path / "src"
    shutil.copytree(ROOT / "components", src / "components", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "fmus", src / "fmus", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", src / "pyproject.toml")
    out = tmp_path / "out"

    def build() -> str:
        r = subprocess.run([sys.executable, str(src / "fmus" / "build.py"), "--out", str(out)],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        with zipfile.ZipFile(out / "WmrPlant.fmu") as zf:
            return zf.read("resources/slavemodule.txt").decode().strip()

    script = tmp_path / "run.py"
    script.write_text(_RUN_PLANT.format(tests=str(Path(__file__).parent)))
    old_module = build()
    old = tmp_path / "old" / "WmrPlant.fmu"
    old.parent.mkdir()
    shutil.copy(out / "WmrPlant.fmu", old)
    r = subprocess.run([sys.executable, str(script), str(old)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert float(r.stdout.split()[0]) == 0.0

    plant = src / "components" / "plant.py"
    text = plant.read_text()
    marker = "return (x1, x2, w1, w2, xa, ya, be, self.tau1, self.tau2, 0.0)"  # foam_level before the foam
    assert marker in text
    plant.write_text(text.replace(marker, "return (x1, x2, w1, w2, xa, ya, be, self.tau1, self.tau2, 1000.0)"))
    new_module = build()
    assert new_module != old_module
    # the next process loads the old build first, then the new one: each runs its own code
    r = subprocess.run([sys.executable, str(script), str(old), str(out / "WmrPlant.fmu")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert [float(x) for x in r.stdout.split()] == [0.0, 1000.0]


def test_interface_document_is_generated_from_the_model_descriptions(built_fmus):
    """docs/fmu-interfaces.md is what doc_tables generates from the FMUs (regenerate it after a change:
    python -m wmr_cosim.fmus.doc_tables --out docs/fmu-interfaces.md)."""
    from wmr_cosim.fmus.doc_tables import document

    text = document(built_fmus)
    assert (ROOT / "docs" / "fmu-interfaces.md").read_text(encoding="utf-8") == text
    for model in MODELS:
        md = read_model_description(str(built_fmus[model]))
        for v in md.modelVariables:
            assert f"| `{v.name}` |" in text
