"""Model Exchange FMUs in the master: the Reference FMUs run alone through the master's integrators
against FMPy's own Model Exchange simulation and their reference results, events against analytic times,
a Model Exchange FMU among co-simulation FMUs against a hand-written FMPy loop, state for rollback."""
from __future__ import annotations

import csv
import ctypes
import math
import re
from pathlib import Path
from typing import Any

import fmpy
import numpy as np
import pytest
from fmpy import simulate_fmu

from wmr_cosim.cosim.runtime import execution

from wmr_cosim.cosim.scenario import document as scenario

from wmr_cosim import cosim
from wmr_cosim.cosim.instances.integrators import SolverSpec
from wmr_cosim.cosim.instances.kinds import model_exchange
from wmr_cosim.cosim.model.description import load_model
from wmr_cosim.runner import fmu_document

from reference_fmus import REF

ME_MODELS = [("fmi2", m) for m in ("BouncingBall", "Dahlquist", "Stair", "VanDerPol", "Resource", "Feedthrough")] + \
            [("fmi3", m) for m in ("BouncingBall", "Dahlquist", "Stair", "VanDerPol", "Resource", "Feedthrough",
                                   "StateSpace")]


def _plan(fmu: Path, **fields: Any) -> cosim.Plan:
    """The plan of one FMU run alone as Model Exchange, ``fields`` added to its instance."""
    doc = fmu_document(fmu)
    (inst,) = doc["instances"].values()
    inst.update({"interface": "model-exchange", **fields})
    return cosim.resolve(scenario.parse(doc, str(fmu)))


def _run(plan: cosim.Plan, out: Path) -> tuple[execution.RunResult, np.ndarray]:
    res = execution.run(plan, out, progress=False)
    assert res.status in ("ok", "terminated"), res.message
    return res, np.load(out / "signals.npy")


def _on_grid(theirs: np.ndarray, times: np.ndarray) -> np.ndarray:
    """FMPy's rows at the communication points (the last one where an event shares the time: the values
    after the event, as the master records them)."""
    keep = []
    for t in times:
        hit = np.flatnonzero(np.abs(theirs["time"] - t) <= 1e-9 * max(1.0, abs(t)))
        assert hit.size, t
        keep.append(hit[-1])
    return theirs[keep]


@pytest.mark.parametrize("version, model", ME_MODELS)
def test_a_reference_fmu_under_cvode_equals_fmpy(version, model, tmp_path):
    """CVODE (the default) on the same output grid as FMPy's simulate_fmu (Model Exchange, CVode): every
    output within 1e-6 of the output's largest magnitude."""
    fmu = REF / version / f"{model}.fmu"
    plan = _plan(fmu)
    assert plan.instances[model].interface == "model-exchange" and plan.instances[model].solver.name == "cvode"
    res, ours = _run(plan, tmp_path / "out")
    theirs = simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="CVode", output_interval=plan.scenario.step,
                          stop_time=plan.scenario.stop)
    rows = ours if res.status == "ok" else ours[:-1]   # (FMPy keeps no row after the event that ended the run)
    theirs = _on_grid(theirs, rows["time"])
    for name in theirs.dtype.names[1:]:
        a, b = _column(rows, model, name), np.asarray(theirs[name], float)
        scale = max(1e-12, float(np.max(np.abs(b))))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-6 * scale, err_msg=name)
    assert len(theirs.dtype.names) > 1


def _column(ours: np.ndarray, model: str, name: str) -> np.ndarray:
    """Our recording of output ``name`` as floats: its column, or an FMI 3.0 array's element columns side by
    side (``y[1]``, ``y[2]``, ...)."""
    col = f"{model}.{name}"
    if col in ours.dtype.names:
        return np.asarray(ours[col], float)
    elems = sorted((c for c in ours.dtype.names if c.startswith(col + "[")), key=lambda c: int(c[len(col) + 1:-1]))
    assert elems, col
    return np.stack([np.asarray(ours[c], float) for c in elems], axis=1)


def _reference(path: Path) -> dict[str, list[str]]:
    """A reference CSV's columns as text (an array's elements space-separated in one field)."""
    with path.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    return {name: [r[i] for r in rows[1:]] for i, name in enumerate(rows[0])}


def _numbers(values: list[str]) -> np.ndarray | None:
    """A reference CSV's column as floats (false/true as 0/1, an array as a row of its elements), or None
    for text."""
    try:
        return np.array([[float(x) for x in v.split()] if " " in v.strip() else float(v) for v in values])
    except ValueError:
        if {v.lower() for v in values} <= {"true", "false"}:
            return np.array([v.lower() == "true" for v in values], float)
        return None


def _internal_step(model: str) -> float:
    """The fixed step [s] of the model's own forward Euler (its co-simulation interface; config.h)."""
    text = (REF.path / "models" / model / "config.h").read_text(encoding="utf-8")
    return float(re.search(r"#define FIXED_SOLVER_STEP\s+(\S+)", text).group(1))


@pytest.mark.parametrize("version, model", ME_MODELS)
def test_a_reference_fmu_under_euler_at_its_own_step_equals_its_reference_result(version, model, tmp_path):
    """The reference CSVs are the FMUs' co-simulation runs, forward Euler at their own fixed step: the
    master's Euler at that step gives them within 1e-6 (of each output's range) at every time both have;
    BouncingBall up to its first bounce, which the master locates inside the step where the FMU's own
    solver takes it at the step's end."""
    fmu = REF / version / f"{model}.fmu"
    _, ours = _run(_plan(fmu, solver="euler", max_step=_internal_step(model)), tmp_path / "out")
    ref = _reference(REF / version / f"{model}_ref.csv")
    t_ours = np.round(ours["time"], 9)
    hits = 0
    for name in list(ref)[1:]:
        want = _numbers(ref[name])
        if want is None or not any(c.split("[")[0] == f"{model}.{name}" for c in ours.dtype.names):
            continue          # (String and Binary outputs are not recorded; the FMI 2.0 Feedthrough has no Float32)
        got = _column(ours, model, name)
        span = max(1.0, float(np.ptp(want)))
        for t, v in zip(np.round(np.array(ref["time"], float), 9), want):
            hit = np.flatnonzero(t_ours == t)
            if hit.size and not (model == "BouncingBall" and t > _bounce_times()[0]):
                assert np.max(np.abs(got[hit[-1]] - v)) <= 1e-6 * span, (name, t)
                hits += 1
    assert hits > 0


def _bounce_times(h0: float = 1.0, g: float = 9.81, e: float = 0.7, v_min: float = 0.1) -> list[float]:
    """Analytic: h(t) = h0 - g t^2 / 2 to the first impact, then flights of 2 v / g with v -> e v until
    v < v_min (BouncingBall's model)."""
    t = math.sqrt(2 * h0 / g)
    v, times = g * t, [t]
    while True:
        v *= e
        if v < v_min:
            return times
        t += 2 * v / g
        times.append(t)


def _execute(plan: cosim.Plan, out: Path, name: str) -> tuple[execution.RunResult, np.ndarray,
                                                                 list[tuple[float, str]]]:
    """Run the plan through an Execution: its result, the signals and instance ``name``'s events."""
    ex = execution.Execution(plan, out)
    ex.initialize()
    try:
        ex.simulate_until(plan.scenario.stop)
    except execution.FmuEnded:
        pass
    events = list(ex.instances[name].events)
    res = ex.close()
    return res, np.load(out / "signals.npy"), events


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("solver, fields", [("cvode", {"tolerance": 1e-10}), ("rk4", {"max_step": 1e-3}),
                                            ("euler", {"max_step": 1e-5})])
def test_bouncing_ball_bounces_at_the_analytic_times(version, solver, fields, tmp_path):
    """The state events' times, as the instance records them, within 1e-6 s of the analytic ones (CVODE at
    rtol 1e-10 and RK4, exact on these parabolas) and within 2e-3 s for Euler (first order)."""
    plan = _plan(REF / version / "BouncingBall.fmu", solver=solver, **fields)
    _, _, events = _execute(plan, tmp_path / "out", "BouncingBall")
    bounces = [t for t, kind in events if kind == "state"]
    want = _bounce_times()
    assert len(bounces) >= len(want)
    np.testing.assert_allclose(bounces[:len(want)], want, rtol=0, atol=2e-3 if solver == "euler" else 1e-6)


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("solver", ["cvode", "euler", "rk4"])
def test_stair_counts_at_its_time_events_exactly(version, solver, tmp_path):
    """Stair's counter steps at t = 1, 2, ... s, time events inside the 0.3 s steps used here: the events
    at exactly those times, the counter k + 1 from t = k s on, the FMU ends the run at 9 s."""
    plan = _plan(REF / version / "Stair.fmu", solver=solver, **({"max_step": 0.1} if solver != "cvode" else {}))
    plan.scenario.step = 0.3
    plan.scenario.stop = 9.9
    plan = cosim.resolve(plan.scenario)
    res, ours, events = _execute(plan, tmp_path / "out", "Stair")
    assert [t for t, kind in events if kind == "time"] == [float(k) for k in range(1, 10)]
    assert res.status == "terminated"
    for t, c in zip(ours["time"], ours["Stair.counter"]):
        assert c == min(10, math.floor(t + 1e-12) + 1), (t, c)


# ---------------------------------------------------------------- among co-simulation FMUs
def _chain(tmp: Path) -> Path:
    """VanDerPol (Model Exchange, CVODE) -> Feedthrough (co-simulation) -> the C plant (Model Exchange,
    CVODE): x0 becomes the right wheel's torque; 2 s of 10 ms steps."""
    from wmr_cosim.runner import resolve_model

    path = tmp / "chain.toml"
    path.write_text(f'''
[experiment]
stop = 2.0
step = 0.01

[instances.vdp]
fmu = "{REF / "fmi2" / "VanDerPol.fmu"}"
interface = "model-exchange"

[instances.ft]
fmu = "{REF / "fmi2" / "Feedthrough.fmu"}"

[instances.plant]
fmu = "{resolve_model("WmrCPlant")}"
interface = "model-exchange"

[[connections]]
from = "vdp.x0"
to = "ft.Float64_continuous_input"

[[connections]]
from = "ft.Float64_continuous_output"
to = "plant.torque_right"

[record]
variables = ["vdp.x0", "ft.Float64_continuous_output", "plant.pos_x", "plant.pos_y", "plant.omega_right"]
''', encoding="utf-8")
    return path


def _fmpy_chain(plan: cosim.Plan, tmp: Path) -> dict[str, list[float]]:
    """The same system as a hand-written FMPy loop: FMU2Model with FMPy's CVodeSolver for the two Model
    Exchange FMUs (restarted where an input changed), FMU2Slave for the co-simulation one, Gauss-Seidel."""
    from fmpy.fmi2 import FMU2Model, FMU2Slave
    from fmpy.sundials import CVodeSolver

    sc = plan.scenario
    h, n = sc.step, plan.n_steps
    fmus, solvers = {}, {}

    class NoInput:
        def apply(self, *a, **k):
            return None

    for name in ("vdp", "ft", "plant"):
        md = plan.instances[name].model.md
        unz = fmpy.extract(str(plan.instances[name].model.path), str(tmp / f"unz_{name}"))
        me = name != "ft"
        cls = FMU2Model if me else FMU2Slave
        ident = (md.modelExchange if me else md.coSimulation).modelIdentifier
        fmu = cls(guid=md.guid, unzipDirectory=unz, modelIdentifier=ident, instanceName=name)
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0, stopTime=sc.stop)
        fmu.enterInitializationMode()
        fmus[name] = (fmu, md)
    vr = {f"{i}.{v.name}": v.valueReference for i, (f, md) in fmus.items() for v in md.modelVariables}
    vdp, ft, plant = (fmus[k][0] for k in ("vdp", "ft", "plant"))
    ft.setReal([vr["ft.Float64_continuous_input"]], vdp.getReal([vr["vdp.x0"]]))
    plant.setReal([vr["plant.torque_right"]], ft.getReal([vr["ft.Float64_continuous_output"]]))
    for name in ("vdp", "ft", "plant"):
        fmus[name][0].exitInitializationMode()
    for name in ("vdp", "plant"):
        fmu, md = fmus[name]
        while fmu.newDiscreteStates()[0]:
            pass
        fmu.enterContinuousTimeMode()
        solvers[name] = CVodeSolver(nx=md.numberOfContinuousStates, nz=md.numberOfEventIndicators,
                                    get_x=fmu.getContinuousStates, set_x=fmu.setContinuousStates,
                                    get_dx=fmu.getDerivatives, get_z=fmu.getEventIndicators,
                                    get_nominals=fmu.getNominalsOfContinuousStates, set_time=fmu.setTime,
                                    input=NoInput(), startTime=0.0, maxStep=sc.stop / 50, relativeTolerance=1e-5,
                                    maxNumSteps=100_000)
    out: dict[str, list[float]] = {k: [] for k in ("x0", "ft", "pos_x", "omega")}

    def sample() -> None:
        out["x0"].append(vdp.getReal([vr["vdp.x0"]])[0])
        out["ft"].append(ft.getReal([vr["ft.Float64_continuous_output"]])[0])
        out["pos_x"].append(plant.getReal([vr["plant.pos_x"]])[0])
        out["omega"].append(plant.getReal([vr["plant.omega_right"]])[0])

    def advance(name: str, t: float) -> None:
        fmu = fmus[name][0]
        _, _, t_reached = solvers[name].step(t, t + h)
        fmu.setTime(t + h)
        assert t_reached == pytest.approx(t + h)

    sample()
    u_last = None
    for k in range(n):
        t = k * h
        advance("vdp", t)
        ft.setReal([vr["ft.Float64_continuous_input"]], vdp.getReal([vr["vdp.x0"]]))
        ft.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        u = ft.getReal([vr["ft.Float64_continuous_output"]])
        plant.setReal([vr["plant.torque_right"]], u)
        if u != u_last:
            solvers["plant"].reset(t)
            u_last = u
        advance("plant", t)
        sample()
    return out


def test_a_model_exchange_chain_with_a_co_simulation_fmu_equals_a_hand_written_fmpy_loop(tmp_path):
    """Gauss-Seidel over VanDerPol (ME) -> Feedthrough (CS) -> C plant (ME): every recorded value within
    1e-9 of the FMPy loop doing the same (same CVODE settings, the plant's integrator restarted where its
    input changed, as the master does)."""
    from wmr_cosim.runner import load_plan

    plan = load_plan(_chain(tmp_path))
    assert [plan.instances[n].interface for n in ("vdp", "ft", "plant")] == ["model-exchange", "co-simulation",
                                                                           "model-exchange"]
    _, ours = _run(plan, tmp_path / "out")
    theirs = _fmpy_chain(plan, tmp_path)
    for col, key in (("vdp.x0", "x0"), ("ft.Float64_continuous_output", "ft"), ("plant.pos_x", "pos_x"),
                     ("plant.omega_right", "omega")):
        np.testing.assert_allclose(ours[col], theirs[key], rtol=1e-9, atol=1e-12, err_msg=col)
    assert abs(ours["plant.pos_x"][-1]) > 1e-3      # (the plant moved: the chain carried the torque)


# ---------------------------------------------------------------- state for rollback
@pytest.mark.parametrize("solver, isolated", [("cvode", False), ("rk4", False), ("cvode", True)])
def test_a_saved_model_exchange_state_repeats_the_step_exactly(solver, isolated, tmp_path):
    """The C plant as Model Exchange with a torque input (in this process, and in a child): save at
    t = 0.1 s, two steps, restore, one step: bit-identical to the first step after the save, and not to
    the second."""
    from wmr_cosim.cosim.instances.isolation import IsolatedInstance
    from wmr_cosim.runner import resolve_model

    model = load_model(resolve_model("WmrCPlant"))
    unz = fmpy.extract(str(model.path), str(tmp_path / "unz"))
    spec = SolverSpec(solver, max_step=1e-3)
    inst = IsolatedInstance("p", model.md, unz, None, "warning", 60.0, 0, spec) if isolated else \
        model_exchange("p", model.md, unz, None, "warning", spec)
    try:
        assert inst.can_get_and_set_state
        inst.instantiate()
        inst.setup_experiment(0.0, 1.0, None)
        inst.enter_initialization()
        u, x = model.variables["torque_right"].vr, model.variables["pos_x"].vr
        fp = inst.fast_path([u], 1, [x], 1)
        inst.exit_initialization()
        T, H, out = ctypes.c_double(0.0), ctypes.c_double(0.05), (ctypes.c_double * 1)()
        uvr, xvr, one = (ctypes.c_uint * 1)(u), (ctypes.c_uint * 1)(x), ctypes.c_size_t(1)

        def step(t: float, torque: float) -> float:
            fp.in_val[0] = torque
            assert fp.set_real(fp.c, uvr, one, fp.in_val, *fp.set_tail) == 0
            T.value = t
            assert fp.do_step(fp.c, T, H, *fp.step_tail) == 0
            assert fp.get_real(fp.c, xvr, one, out, *fp.get_tail) == 0
            return out[0]
        step(0.0, 2.0)
        step(0.05, 2.5)
        saved = inst.get_state()
        first, second = step(0.1, 3.0), step(0.15, 3.5)
        inst.set_state(saved)
        again = step(0.1, 3.0)
        inst.free_state(saved)
        assert again == first != second
    finally:
        inst.shutdown()


# ---------------------------------------------------------------- G1 with the C plant as Model Exchange
SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def _g1_final(file: str, tmp: Path, **plant: Any) -> np.ndarray:
    """The final pose (x_A, y_A) [m] of the 50 s G1 learning run of ``file``, ``plant`` fields set on its
    plant instance."""
    from wmr_cosim.runner import resolve_model

    sc = scenario.load(SCENARIOS / file, resolve_model)
    sc.record = ["plant.x_A", "plant.y_A"]
    for key, value in plant.items():
        setattr(sc.instances["plant"], key, value)
    out = tmp / f"{file}_{'_'.join(map(str, plant.values()))}"
    _, sig = _run(cosim.resolve(sc), out)
    return np.array([sig["plant.x_A"][-1], sig["plant.y_A"][-1]])


def test_g1_with_the_model_exchange_c_plant_under_rk4_ends_where_the_co_simulation_plant_does(tmp_path):
    """RK4 at 1 ms, the co-simulation interface's own integration (2 substeps of the 2 ms step): the final
    pose within 1e-6 m (measured: 3e-14 m); the plant really ran as Model Exchange (a distinct result
    from Euler's)."""
    cs = _g1_final("g1_c_plant.toml", tmp_path)
    me = _g1_final("g1_c_plant_me.toml", tmp_path, solver="rk4", max_step=0.001)
    assert np.linalg.norm(me - cs) < 1e-6, me - cs
    euler = _g1_final("g1_c_plant_me.toml", tmp_path, solver="euler", max_step=0.001)
    assert np.linalg.norm(euler - cs) > 1e-5     # (a first-order method is visibly off: the solver is used)


@pytest.mark.slow
def test_g1_with_the_model_exchange_c_plant_under_cvode_converges_to_the_co_simulation_plant(tmp_path):
    """CVODE: the final pose's distance from the co-simulation plant's falls as the tolerance tightens,
    below 1e-6 m at rtol 1e-11 (measured: 2.2e-4, 6.2e-6, 8.4e-8 m at 1e-7, 1e-9, 1e-11)."""
    cs = _g1_final("g1_c_plant.toml", tmp_path)
    d = [float(np.linalg.norm(_g1_final("g1_c_plant_me.toml", tmp_path, tolerance=tol) - cs))
         for tol in (1e-7, 1e-9, 1e-11)]
    assert d[0] > d[1] > d[2] and d[2] < 1e-6, d


@pytest.mark.slow
def test_the_paper_protocol_runs_through_the_model_exchange_c_plant(tmp_path):
    """The G1 protocol (learn, frozen, foam: the weights carried, the foam's kinks at 8.38 and 8.48 s time
    events) with the plant of g1_c_plant_me.toml under RK4 at 1 ms: every run ok, the foam run's final
    pose within 1e-6 m of the same protocol through the co-simulation C plant, and the foam events at
    their times."""
    from wmr_cosim.runner import read_scenario, run_protocol

    finals = {}
    for key, plant_file in (("cs", "g1_c_plant.toml"), ("me", "g1_c_plant_me.toml")):
        proto = read_scenario(SCENARIOS / "paper" / "g1.toml")
        plant = read_scenario(SCENARIOS / plant_file).document["instances"]["plant"]
        proto.document["instances"]["plant"] = dict(plant, **({"solver": "rk4", "max_step": 0.001}
                                                            if key == "me" else {}))
        results = run_protocol(proto, tmp_path / key)
        assert [r.status for r in results.values()] == ["ok"] * 3, {n: r.message for n, r in results.items()}
        sig = np.load(tmp_path / key / "foam" / "signals.npy")
        finals[key] = np.array([sig["plant.x_A"][-1], sig["plant.y_A"][-1]])
        level = sig["plant.foam_level"]
        assert level[sig["time"] < 8.38 - 1e-9].max() == 0.0 and level[sig["time"] >= 8.48].min() == 1.0
    assert np.linalg.norm(finals["me"] - finals["cs"]) < 1e-6, finals


# ---------------------------------------------------------------- values set between steps, isolation
def test_a_tunable_parameter_set_by_an_event_enters_event_mode_and_takes_effect(tmp_path):
    """BouncingBall's restitution e (tunable: set in event mode only) set to 0.5 at t = 1.2 s by a scenario
    event: the bounces before keep e = 0.7, the first one after rebounds with half the impact speed."""
    doc = fmu_document(REF / "fmi2" / "BouncingBall.fmu")
    doc["instances"]["BouncingBall"].update({"interface": "model-exchange", "solver": "rk4", "max_step": 1e-3})
    doc["events"] = [{"time": 1.2, "variable": "BouncingBall.e", "action": "set", "value": 0.5}]
    plan = cosim.resolve(scenario.parse(doc, "events.toml"))
    res, sig, events = _execute(plan, tmp_path / "out", "BouncingBall")
    assert res.status == "ok", res.message
    assert (1.2, "set") in events
    bounces = [t for t, kind in events if kind == "state"]
    want = _bounce_times()
    np.testing.assert_allclose(bounces[:2], want[:2], atol=1e-6)   # 0.45 and 1.08 s: e = 0.7
    g, v1 = 9.81, 9.81 * want[0] * 0.7 * 0.7                        # the impact speed of the third bounce
    third = want[1] + 2 * v1 / g                                    # analytic, e = 0.7 until then
    v_after = 0.5 * v1
    assert bounces[2] == pytest.approx(third, abs=1e-6)
    assert bounces[3] == pytest.approx(third + 2 * v_after / g, abs=1e-6)


def test_an_isolated_model_exchange_instance_gives_the_in_process_result(tmp_path):
    """The chain of Model Exchange and co-simulation FMUs with every instance in a child process: the
    signals bit-identical to the in-process run's; scenario.json says each instance's interface."""
    import json

    from wmr_cosim.runner import load_plan

    path = _chain(tmp_path)
    _, here = _run(load_plan(path), tmp_path / "here")
    _, there = _run(load_plan(path, isolate=True), tmp_path / "there")
    for col in here.dtype.names:
        assert np.array_equal(here[col], there[col]), col
    doc = json.loads((tmp_path / "there" / "scenario.json").read_text(encoding="utf-8"))
    assert {n: i["interface"] for n, i in doc["instances"].items()} == {
        "vdp": "model-exchange", "ft": "co-simulation", "plant": "model-exchange"}
    assert doc["instances"]["plant"]["solver"]["name"] == "cvode"


@pytest.mark.parametrize("solver", ["cvode", "rk4"])
def test_an_fmu_call_failing_inside_the_integration_ends_the_run_with_one_line_naming_it(solver, tmp_path):
    """fmi2GetDerivatives returning Error at t >= 0.5 s (VanDerPol, patched after initialisation): the run
    fails with one line naming the instance, the integrator, the FMI call and the time of the step; the
    rows up to that time are on disk."""
    from wmr_cosim.cosim.messages.errors import RunError

    plan = _plan(REF / "fmi2" / "VanDerPol.fmu", solver=solver)
    ex = execution.Execution(plan, tmp_path / "out")
    ex.initialize()
    inst = ex.instances["VanDerPol"]
    get_dx, clock = inst.eq.get_dx, {"t": 0.0}
    set_time = inst.eq.set_time

    def timed(t: float) -> int:
        clock["t"] = t
        return set_time(t)
    inst.eq.set_time = timed
    inst.eq.get_dx = lambda p: 3 if clock["t"] >= 0.5 else get_dx(p)
    with pytest.raises(RunError) as err:
        ex.simulate_until(plan.scenario.stop)
    res = ex.close()
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("VanDerPol: ") and f"the integration ({solver}" in msg, msg
    assert "fmi2GetDerivatives" in msg and "returned Error at t = " in msg, msg
    t_fail = float(re.search(r"returned Error at t = (\S+) s", msg).group(1))
    assert 0.4 <= t_fail < 0.5      # the step in which an evaluation reached 0.5 s (CVODE looks ahead)
    assert res.status == "failed"
    assert np.load(tmp_path / "out" / "signals.npy")["time"][-1] == pytest.approx(t_fail)


# --- rows at the events: [record] event_rows, as FMPy's record_events ------------------------------------------

def _ball_scenario(tmp_path: Path, version: str, extra: str = "", record: str = "event_rows = true\n") -> Path:
    path = tmp_path / f"ball_{version}.toml"
    path.write_text(f'[experiment]\nstop = 3.0\nstep = 0.01\n[instances.ball]\nfmu = "{REF / version / "BouncingBall.fmu"}"\n'
                    f'interface = "model-exchange"\n{extra}[record]\nvariables = ["ball.h", "ball.v"]\n{record}')
    return path


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_event_rows_are_fmpys_record_events_rows(tmp_path, capsys, version):
    """BouncingBall through model exchange with ``event_rows``: a row before and one after each bounce at the
    bounce's time, as FMPy's simulate_fmu(record_events=True) gives them (the same CVODE settings: times and
    values to the solver's tolerance); the rows of the grid are those of the run without event rows, bit for
    bit."""
    from wmr_cosim.cli import main
    with_rows, without = tmp_path / "with", tmp_path / "without"
    assert main(["run", str(_ball_scenario(tmp_path, version)), "--out", str(with_rows), "--quiet"]) == 0
    assert main(["run", str(_ball_scenario(tmp_path, version, record="")), "--out", str(without), "--quiet"]) == 0
    ours, grid = np.load(with_rows / "signals.npy"), np.load(without / "signals.npy")
    ref = simulate_fmu(str(REF / version / "BouncingBall.fmu"), fmi_type="ModelExchange", stop_time=3.0,
                       output_interval=0.01, record_events=True, output=["h", "v"])
    at = np.flatnonzero(np.diff(ours["time"]) == 0)          # each event: the row before, then the one after
    ref_at = np.flatnonzero(np.diff(ref["time"]) == 0)
    assert len(at) == len(ref_at) >= 8                      # the ball bounces, ever faster, up to 3 s
    np.testing.assert_allclose(ours["time"][at], ref["time"][ref_at], rtol=1e-6)
    for shift in (0, 1):                                      # before and after
        np.testing.assert_allclose(ours["ball.v"][at + shift], ref["v"][ref_at + shift], rtol=1e-4, atol=1e-6)
        np.testing.assert_allclose(ours["ball.h"][at + shift], ref["h"][ref_at + shift], atol=1e-6)
    assert np.all(ours["ball.v"][at] < 0) and np.all(ours["ball.v"][at + 1] >= 0)   # falling, then rising (or at rest)
    events = set(at) | set(at + 1)
    on_grid = ours[[i for i in range(len(ours)) if i not in events]]
    assert np.array_equal(on_grid, grid)


@pytest.mark.parametrize("case, words", [
    ("co-simulation", "instance ball runs through co-simulation"),
    ("isolated", "instance ball is isolated"),
    ("two instances", "the run has 2 instances"),
    ("not a bool", "'yes': must be true or false"),
])
def test_event_rows_are_refused_where_they_cannot_be_honoured(tmp_path, capsys, case, words):
    from wmr_cosim.cli import main
    extra = {"co-simulation": "", "isolated": "isolate = true\n",
             "two instances": f'[instances.other]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n',
             "not a bool": ""}[case]
    path = _ball_scenario(tmp_path, "fmi2", extra, record='event_rows = "yes"\n' if case == "not a bool"
                          else "event_rows = true\n")
    if case == "co-simulation":
        path.write_text(path.read_text().replace('interface = "model-exchange"\n', ""))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{path}: record.event_rows: " in err and words in err, err
