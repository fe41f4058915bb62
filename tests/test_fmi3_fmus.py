"""Our three models as FMI 3.0 FMUs (WmrPlant3, WmrSensor3, WmrController3, pythonfmu3): FMPy's validation,
the same interface as the FMI 2.0 FMUs (units, ranges, dependencies; arrays for W and P), G1 through them
bit for bit G1 through the FMI 2.0 FMUs, mixed FMI 2.0 / 3.0 systems, state round trips, the failure
rules, and FMPy's simulate_fmu (another FMI 3.0 host) against our master."""
from __future__ import annotations

import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from cosim_support import G1, toml_value, write_scenario
from wmr_cosim import cosim
from wmr_cosim.runner import fmu_plan

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("WmrPlant", "WmrSensor", "WmrController")


@pytest.fixture(scope="session")
def fmus3(tmp_path_factory):
    """The three FMI 3.0 FMUs built once per session: {model name: path}."""
    from wmr_cosim.fmus.build import SLAVES3, build_all

    from conftest import fmu_cache

    return build_all(fmu_cache(tmp_path_factory, "fmus3"), models=tuple(SLAVES3))


def _name3(column: str) -> str:
    """The FMI 3.0 column of an FMI 2.0 column: controller.W1 -> controller.W[1], P12 -> P[1,2]."""
    m = re.fullmatch(r"controller\.W(\d)", column)
    if m:
        return f"controller.W[{m.group(1)}]"
    m = re.fullmatch(r"controller\.P(\d)(\d)", column)
    if m:
        return f"controller.P[{m.group(1)},{m.group(2)}]"
    return column


def _run(tmp: Path, models: dict[str, Path], name: str, stop: float, extra: str = "") -> np.ndarray:
    text = f"base = {toml_value(str(G1))}\n[experiment]\nstop = {stop}\n"
    text += "".join(f"[instances.{inst}]\nfmu = {toml_value(str(models[inst]))}\n"
                    for inst in ("plant", "sensor", "controller"))
    path = write_scenario(tmp / f"{name}.toml", text + extra)
    res = cosim.run(cosim.resolve(cosim.load(path)), tmp / name, progress=False)
    assert res.status == "ok", res.message
    return np.load(tmp / name / "signals.npy")


def _assert_same(a: np.ndarray, b: np.ndarray) -> int:
    """Every column of the FMI 2.0 run ``a`` equals its FMI 3.0 column in ``b`` bit for bit; returns how many."""
    assert len(a) == len(b)
    for name in a.dtype.names:
        assert np.array_equal(a[name], b[name if name in b.dtype.names else _name3(name)]), name
    return len(a.dtype.names)


def test_fmi3_fmus_pass_fmpy_validation(fmus3):
    for model, path in fmus3.items():
        assert validate_fmu(str(path)) == [], model
        md = read_model_description(str(path))
        assert md.fmiVersion == "3.0" and md.coSimulation.canGetAndSetFMUstate
        assert md.coSimulation.canSerializeFMUstate


def test_fmi3_interface_is_the_fmi2_one_with_arrays(built_fmus, fmus3):
    """Same variables (scalars of an array mapped to its elements), units, ranges, causality,
    variability, start values and direct-feedthrough dependencies as the FMI 2.0 FMU."""
    for model in MODELS:
        md2 = read_model_description(str(built_fmus[model]))
        md3 = read_model_description(str(fmus3[model + "3"]))
        v3 = {v.name: v for v in md3.modelVariables}
        deps3 = {u.variable.name: {d.name for d in u.dependencies} for u in md3.outputs}
        deps2 = {u.variable.name: {d.name for d in u.dependencies} for u in md2.outputs}
        assert v3["time"].causality == "independent" and v3["time"].valueReference == 0
        n_array_elems = 0
        for v in md2.modelVariables:
            m = re.fullmatch(r"(W|P)([1-3])([1-3])?(_init)?", v.name)
            m = m if m and (v.causality == "parameter") == (m.group(4) is not None) else None
            if m:
                name = m.group(1) + (m.group(4) or "")
                w = v3[name]
                dims = [int(d.start) for d in w.dimensions]
                assert dims == ([3] if m.group(1) == "W" else [3, 3])
                i = int(m.group(2)) - 1
                j = None if m.group(3) is None else int(m.group(3)) - 1
                flat = i if j is None else i * 3 + j
                if v.causality != "output":
                    starts = [float(x) for x in w.start.split()]
                    assert starts[flat] == float(v.start)
                    if j is not None:
                        assert starts[j * 3 + i] == float(v.start)  # symmetric
                n_array_elems += 1
            else:
                w = v3[v.name]
                assert w.type == {"Real": "Float64", "Integer": "Int32"}.get(v.type, v.type), v.name
                if v.causality != "output":
                    assert str(w.start).lower() == str(v.start).lower(), v.name
                if v.causality == "output":
                    assert deps3[v.name] == deps2[v.name], v.name
            # (the sensor's and the controller's inputs are clocked by their sample clock: discrete in FMI 3.0)
            assert (w.causality, w.variability) == (v.causality, "discrete" if w.clocks else v.variability), v.name
            assert (w.unit or None) == (v.unit or None), v.name
            if v.type == "Real" and v.causality == "parameter" and not m:
                assert (w.min, w.max) == (v.min, v.max), v.name
        assert n_array_elems == (18 if model == "WmrController" else 0)
    md3 = read_model_description(str(fmus3["WmrSensor3"]))
    rad = {u.name: u for u in md3.unitDefinitions}["rad"]
    assert [(d.name, d.factor) for d in rad.displayUnits] == [("deg", 180.0 / np.pi)]


@pytest.mark.slow
def test_g1_through_fmi3_fmus_is_bit_identical_to_fmi2(built_fmus, fmus3, tmp_path):
    """The whole G1 learning run (50 s, adaptation to 39 s): every recorded column equal bit for bit."""
    two = _run(tmp_path, {"plant": built_fmus["WmrPlant"], "sensor": built_fmus["WmrSensor"],
                          "controller": built_fmus["WmrController"]}, "fmi2", 50.0)
    three = _run(tmp_path, {"plant": fmus3["WmrPlant3"], "sensor": fmus3["WmrSensor3"],
                            "controller": fmus3["WmrController3"]}, "fmi3", 50.0)
    assert _assert_same(two, three) > 50
    assert np.array_equal(three["controller.P[1,2]"], three["controller.P[2,1]"])
    assert not np.array_equal(three["controller.W[1]"][:10], three["controller.W[1]"][-10:])  # it learned


@pytest.mark.parametrize("plant3", [False, True])
def test_mixed_fmi2_and_fmi3_systems_equal_the_fmi2_system(built_fmus, fmus3, tmp_path, plant3):
    """An FMI 2.0 plant with the FMI 3.0 sensor and controller, and the reverse, equal the FMI 2.0 system;
    the initial weights given as the FMI 3.0 arrays equal the FMI 2.0 scalars."""
    w, p = [0.02, 0.04, 0.06], [50.0, 1.0, 2.0, 60.0, 3.0, 70.0]  # P11 P12 P13 P22 P23 P33
    sc2 = ("[instances.controller.parameters]\n" + "".join(f"W{i + 1}_init = {x}\n" for i, x in enumerate(w))
           + "".join(f"P{ij}_init = {x}\n" for ij, x in zip(("11", "12", "13", "22", "23", "33"), p)))
    full = [p[0], p[1], p[2], p[1], p[3], p[4], p[2], p[4], p[5]]
    sc3 = f"[instances.controller.parameters]\nW_init = {w}\nP_init = {full}\n"
    two = _run(tmp_path, {"plant": built_fmus["WmrPlant"], "sensor": built_fmus["WmrSensor"],
                          "controller": built_fmus["WmrController"]}, "fmi2", 4.0, sc2)
    models = {"plant": fmus3["WmrPlant3"], "sensor": built_fmus["WmrSensor"], "controller": built_fmus["WmrController"]} \
        if plant3 else {"plant": built_fmus["WmrPlant"], "sensor": fmus3["WmrSensor3"], "controller": fmus3["WmrController3"]}
    mixed = _run(tmp_path, models, "mixed", 4.0, sc2 if plant3 else sc3)
    assert _assert_same(two, mixed) > 50
    assert two["controller.W1"][0] == w[0] and two["controller.P12"][0] == p[1]


def _instance(path: Path, tmp: Path, log: list[tuple[int, str]]) -> FMU3Slave:
    md = read_model_description(str(path))
    d = extract(str(path), unzipdir=str(tmp / md.modelName))
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="inst")
    fmu.instantiate(loggingOn=True, logMessage=lambda env, status, cat, msg: log.append((status, msg.decode())))
    fmu.md = md
    return fmu


def _vr(fmu: FMU3Slave, name: str) -> int:
    return next(v.valueReference for v in fmu.md.modelVariables if v.name == name)


@pytest.mark.parametrize("model", ["WmrPlant3", "WmrSensor3", "WmrController3"])
def test_state_round_trip_and_serialisation(fmus3, tmp_path, model):
    """Save the state after 200 steps, step 100 more, restore (directly and from the serialised bytes):
    the same 100 steps again give the same outputs bit for bit, internal states included."""
    log: list[tuple[int, str]] = []
    fmu = _instance(fmus3[model], tmp_path, log)
    md = fmu.md
    ins = [v for v in md.modelVariables if v.causality == "input" and v.type != "Clock"]
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Float64"]
    n_out = sum(int(np.prod([int(d.start) for d in v.dimensions])) if v.dimensions else 1
                for v in md.modelVariables if v.valueReference in outs)
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    h = 0.002

    def step(k: int) -> list[float]:
        t = k * h
        fmu.setFloat64([v.valueReference for v in ins], [0.3 * np.sin(3 * t + j) + 0.1 * t for j in range(len(ins))])
        fmu.doStep(t, h)
        return fmu.getFloat64(outs, nValues=n_out)

    for k in range(200):
        step(k)
    state = fmu.getFMUState()
    blob = fmu.serializeFMUState(state)
    first = [step(k) for k in range(200, 300)]
    fmu.setFMUState(state)
    again = [step(k) for k in range(200, 300)]
    fmu.setFMUState(fmu.deserializeFMUState(blob))
    third = [step(k) for k in range(200, 300)]
    assert first == again == third
    assert first[0] != first[-1]  # the outputs moved
    fmu.freeFMUState(state)
    fmu.terminate()
    fmu.freeInstance()


def test_failure_rules_discard_then_refuse_and_asymmetric_p_refused(fmus3, tmp_path):
    from fmpy.fmi1 import FMICallException

    log: list[tuple[int, str]] = []
    fmu = _instance(fmus3["WmrPlant3"], tmp_path, log)
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    u1 = _vr(fmu, "u1")
    fmu.setFloat64([u1], [float("nan")])
    with pytest.raises(FMICallException):
        fmu.doStep(0.0, 0.002)
    assert log[-1][0] == 2 and "non-finite input" in log[-1][1]  # fmi3Discard with the cause
    fmu.setFloat64([u1], [0.0])
    with pytest.raises(FMICallException):
        fmu.doStep(0.0, 0.002)
    assert log[-1][0] == 2 and "an earlier step failed" in log[-1][1]
    fmu.terminate()
    fmu.freeInstance()

    log.clear()
    plant = _instance(fmus3["WmrPlant3"], tmp_path / "p", log)
    plant.enterInitializationMode(startTime=0.0)
    plant.exitInitializationMode()
    with pytest.raises(FMICallException):
        plant.setFloat64([_vr(plant, "a1")], [0.07])
    assert any(st == 4 and "fixed parameter a1 after initialisation" in m for st, m in log)

    log.clear()
    ctl = _instance(fmus3["WmrController3"], tmp_path / "c", log)
    p = [100.0, 1.0, 0.0, 2.0, 100.0, 0.0, 0.0, 0.0, 100.0]
    with pytest.raises(FMICallException):
        ctl.setFloat64([_vr(ctl, "P_init")], p)
    ours = [m for st, m in log if st == 4 and "P_init: not symmetric" in m]  # fmi3Fatal, one line naming both
    assert ours and "P_init[1,2] = 1.0, P_init[2,1] = 2.0" in ours[0]
    # after fmi3Fatal the instance is left alone (not freed), as the failure rules say


@pytest.mark.parametrize("model", ["WmrPlant3", "WmrSensor3", "WmrController3"])
def test_fmpy_simulate_fmu_runs_each_alone_as_our_master(fmus3, tmp_path, model):
    """FMPy's simulate_fmu (another FMI 3.0 host) on each FMU alone equals our master's run of it."""
    path = fmus3[model]
    plan = fmu_plan(path, stop=1.0, step=0.002)
    res = cosim.run(plan, tmp_path / "ours", progress=False)
    assert res.status == "ok", res.message
    ours = np.load(tmp_path / "ours" / "signals.npy")
    theirs = simulate_fmu(str(path), stop_time=1.0, step_size=0.002, output_interval=0.002)
    assert len(ours) == len(theirs) == 501
    n = 0
    for name in theirs.dtype.names[1:]:
        col = theirs[name]
        if col.ndim > 1:   # an array (FMPy: one axis per dimension), row-major
            col = col.reshape(len(col), -1)
            for j in range(col.shape[1]):
                row, c = divmod(j, 3)
                key = f"{model}.{name}[{j + 1}]" if name == "W" else f"{model}.{name}[{row + 1},{c + 1}]"
                assert np.array_equal(ours[key], col[:, j]), key
                n += 1
            continue
        assert np.array_equal(ours[f"{model}.{name}"].astype(float), col.astype(float)), name
        n += 1
    assert n >= 8


def test_fmi3_interface_document_is_generated(fmus3):
    """docs/fmu-interfaces-fmi3.md is what doc_tables generates (python -m wmr_cosim.fmus.doc_tables --fmi 3
    --out docs/fmu-interfaces-fmi3.md)."""
    from wmr_cosim.fmus.doc_tables import document3

    assert (ROOT / "docs" / "fmu-interfaces-fmi3.md").read_text(encoding="utf-8") == document3(fmus3)


def test_ssp_export_and_import_of_a_mixed_system_with_array_parameters(built_fmus, fmus3, tmp_path):
    """A system of an FMI 2.0 plant and FMI 3.0 sensor and controller, W_init and P_init set as arrays,
    exported as SSP 1.0 (an array as one parameter per element) and run from the archive: the same
    results as from the scenario file."""
    from wmr_cosim.cosim.plan import ssp

    p = [50.0, 1.0, 2.0, 1.0, 60.0, 3.0, 2.0, 3.0, 70.0]
    text = (f"base = {toml_value(str(G1))}\n[experiment]\nstop = 1.0\n"
            f"[instances.plant]\nfmu = {toml_value(str(built_fmus['WmrPlant']))}\n"
            f"[instances.sensor]\nfmu = {toml_value(str(fmus3['WmrSensor3']))}\n"
            f"[instances.controller]\nfmu = {toml_value(str(fmus3['WmrController3']))}\n"
            f"[instances.controller.parameters]\nW_init = [0.02, 0.04, 0.06]\nP_init = {p}\n")
    path = write_scenario(tmp_path / "mixed.toml", text)
    plan = cosim.resolve(cosim.load(path))
    res = cosim.run(plan, tmp_path / "toml", progress=False)
    assert res.status == "ok", res.message
    archive = ssp.export_ssp(plan, tmp_path / "mixed.ssp")
    with zipfile.ZipFile(archive) as zf:
        ssv = zf.read("resources/controller.ssv").decode()
    assert 'name="P_init[2,3]"' in ssv and 'name="W_init[3]"' in ssv
    arch = ssp.load_ssp(archive)
    try:
        assert arch.scenario.instances["controller"].parameters["P_init"] == p
        res = cosim.run(cosim.resolve(arch.scenario), tmp_path / "ssp", progress=False)
        assert res.status == "ok", res.message
    finally:
        arch.cleanup()
    a, b = np.load(tmp_path / "toml" / "signals.npy"), np.load(tmp_path / "ssp" / "signals.npy")
    for name in a.dtype.names:
        assert np.array_equal(a[name], b[name]), name
    assert a["controller.W[2]"][0] == 0.04


def test_protocol_carry_through_fmi3_fmus_equals_fmi2(built_fmus, fmus3, tmp_path):
    """The paper's protocol (learn, then frozen with the learned W and P carried into W*_init, P*_init)
    through the FMI 3.0 FMUs (the carry gathered into W_init, P_init by runner.carry_fmi3), as
    ``wmr-cosim paper --fmi 3`` runs it: every final value equal to the FMI 2.0 run's."""
    from wmr_cosim.cosim.runtime.protocol import run_protocol
    from wmr_cosim.runner import carry_fmi3

    text = (f"base = {toml_value(str(ROOT / 'scenarios' / 'paper' / 'g1.toml'))}\n"
            "[experiment]\nstop = 4.0\n")  # the weights move from 3.7 s on
    path = write_scenario(tmp_path / "proto.toml", text)
    two = run_protocol(path, tmp_path / "two", lambda n: built_fmus.get(n), variant="freeze", progress=False)
    three = run_protocol(path, tmp_path / "three", lambda n: fmus3.get(n + "3"), variant="freeze", progress=False,
                         carry=carry_fmi3)
    assert list(two) == list(three) == ["learn", "frozen", "foam"]
    for run in two:
        assert two[run].status == three[run].status == "ok"
        f2, f3 = two[run].final, three[run].final
        assert len(f2) > 30 and all(f2[c] == f3[_name3(c)] for c in f2), run
    learned = [two["learn"].final[f"controller.W{i}"] for i in (1, 2, 3)]
    assert learned != [0.05] * 3  # the weights moved, and the frozen run started from them
    assert [np.load(tmp_path / "three" / "frozen" / "signals.npy")[f"controller.W[{i}]"][0] for i in (1, 2, 3)] == learned


def test_carry_fmi3_gathers_elements_into_arrays():
    from wmr_cosim.cosim.messages.errors import CosimError
    from wmr_cosim.runner import carry_fmi3

    finals = {"learn": {"controller.W[1]": 1.0, "controller.W[2]": 2.0, "controller.W[3]": 3.0,
                        "controller.P[1,1]": 11.0, "controller.P[1,2]": 12.0, "controller.P[1,3]": 13.0,
                        "controller.P[2,2]": 22.0, "controller.P[2,3]": 23.0, "controller.P[3,3]": 33.0,
                        "plant.x_A": 0.5}}
    carry = {f"controller.W{i}_init": f"learn.controller.W{i}" for i in (1, 2, 3)}
    carry.update({f"controller.P{ij}_init": f"learn.controller.P{ij}" for ij in ("11", "12", "13", "22", "23", "33")})
    carry["controller.x0"] = "learn.plant.x_A"
    out = carry_fmi3(carry, finals)
    assert out == {"controller.x0": 0.5, "controller.W_init": [1.0, 2.0, 3.0],
                   "controller.P_init": [11.0, 12.0, 13.0, 12.0, 22.0, 23.0, 13.0, 23.0, 33.0]}
    del carry["controller.W2_init"]
    with pytest.raises(CosimError, match="W_init: elements"):
        carry_fmi3(carry, finals)
    # one index beside two: one line, not an IndexError
    with pytest.raises(CosimError, match="P_init: elements of one index and of two"):
        carry_fmi3({"controller.P1_init": "learn.controller.P11", "controller.P12_init": "learn.controller.P12"}, finals)
