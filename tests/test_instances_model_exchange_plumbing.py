"""Model Exchange FMUs through the scenario, the plan, the start-up and the command line: the instance
fields ``interface``, ``solver``, ``max_step``, ``event_tolerance`` (and ``tolerance``) checked in one line
naming the field (exit code 2), the rule for the interface an instance uses, what ``check`` and ``info``
say, ``run X.fmu`` with ``--solver``, the isolated child, the Python API and SSP."""
from __future__ import annotations

import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

from reference_fmus import REF
from wmr_cosim import Simulation
from wmr_cosim.cli import main
from wmr_cosim import cosim
from wmr_cosim.cosim.messages.errors import ScenarioError
from wmr_cosim.cosim.instances.integrators import DEFAULT_EVENT_TOLERANCE, SolverSpec
from wmr_cosim.cosim.model.description import load_model
from wmr_cosim.runner import fmu_document, fmu_plan

BB2, BB3 = REF / "fmi2" / "BouncingBall.fmu", REF / "fmi3" / "BouncingBall.fmu"
DQ2, DQ3 = REF / "fmi2" / "Dahlquist.fmu", REF / "fmi3" / "Dahlquist.fmu"


# ------------------------------------------------------------------------------------------ test FMUs
def _edited(src: Path, dst: Path, edit) -> Path:
    """A copy of the FMU ``src`` at ``dst`` with its modelDescription.xml edited (text -> text)."""
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zo:
        for info in zi.infolist():
            data = zi.read(info)
            if info.filename == "modelDescription.xml":
                text = data.decode()
                new = edit(text)
                assert new != text, "the edit changed nothing"
                data = new.encode()
            zo.writestr(info, data)
    return dst


def _without(element: str):
    """An edit that removes the ``<element .../>`` (or ``<element ...>...</element>``) of a model description."""
    return lambda t: re.sub(rf"<{element}[^>]*?/>|<{element}\b.*?</{element}>", "", t, count=1, flags=re.S)


def me_only(src: Path, dst: Path) -> Path:
    """A copy of a Reference FMU with no co-simulation interface (its ``<CoSimulation>`` removed)."""
    return _edited(src, dst, _without("CoSimulation"))


def cs_only(src: Path, dst: Path) -> Path:
    """A copy of a Reference FMU with no model exchange interface (its ``<ModelExchange>`` removed)."""
    return _edited(src, dst, _without("ModelExchange"))


@pytest.fixture
def fmus(tmp_path) -> dict[str, Path]:
    """The FMI 2.0 BouncingBall with both interfaces, with model exchange only, with co-simulation only."""
    folder = tmp_path / "fmus"
    folder.mkdir()
    return {"both": BB2, "me": me_only(BB2, folder / "BB_ME.fmu"), "cs": cs_only(BB2, folder / "BB_CS.fmu")}


def _toml(tmp_path: Path, fmu: Path, fields: str = "", experiment: str = "stop = 0.1\nstep = 0.01\n",
          name: str = "s.toml") -> Path:
    path = tmp_path / name
    path.write_text(f'[experiment]\n{experiment}[instances.bb]\nfmu = "{fmu}"\n{fields}', encoding="utf-8")
    return path


def _plan(path: Path) -> cosim.Plan:
    return cosim.resolve(cosim.load(path))


def _one_line(capsys, code: int, words: list[str]) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2, (code, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


# ------------------------------------------------------------------------------------------ the model
def test_the_model_says_which_interfaces_it_has(fmus):
    both, me, cs = (load_model(fmus[k]) for k in ("both", "me", "cs"))
    assert both.interfaces == ("co-simulation", "model-exchange") and both.has_cs and both.has_me
    assert me.interfaces == ("model-exchange",) and me.has_me and not me.has_cs
    assert cs.interfaces == ("co-simulation",) and cs.has_cs and not cs.has_me
    assert me.identifier == me.identifier_of("model-exchange") == "BouncingBall"
    assert me.can_vary_step is True and me.internal_step is None and me.default_step == 0.01


def test_an_fmi3_model_exchange_only_fmu_has_no_fixed_internal_step(tmp_path):
    assert load_model(DQ3).internal_step == 0.1                 # (its co-simulation interface's)
    me = load_model(me_only(DQ3, tmp_path / "DQ3_ME.fmu"))
    assert me.interfaces == ("model-exchange",) and me.internal_step is None and me.can_vary_step


def test_a_scheduled_execution_or_interfaceless_fmu_is_refused(tmp_path):
    bare = _edited(cs_only(BB2, tmp_path / "cs.fmu"), tmp_path / "bare.fmu", _without("CoSimulation"))
    with pytest.raises(Exception, match=r"neither a co-simulation nor a model exchange FMU \(it declares no "
                                        r"interface\)"):
        load_model(bare)


def test_a_missing_binary_is_refused_for_the_interface_that_lacks_it(tmp_path):
    """Co-simulation's binary present, model exchange's named otherwise and absent: loadable, runs as
    co-simulation, refused as model exchange (naming the binary it lacks)."""
    fmu = _edited(BB2, tmp_path / "two.fmu", lambda t: re.sub(r'(<ModelExchange\s+modelIdentifier=")BouncingBall"',
                                                             r'\1Other"', t))
    model = load_model(fmu)
    assert model.identifier_of("model-exchange") == "Other" and list(model.missing_binaries) == ["model-exchange"]
    assert _plan(_toml(tmp_path, fmu)).instances["bb"].interface == "co-simulation"
    with pytest.raises(ScenarioError) as exc:
        _plan(_toml(tmp_path, fmu, 'interface = "model-exchange"\n', name="me.toml"))
    assert exc.value.field == "instances.bb.interface" and "binaries/linux64/Other.so" in str(exc.value)
    assert "\n" not in str(exc.value)


# ------------------------------------------------------------------------------------------ the rule
@pytest.mark.parametrize("which, fields, interface, solver", [
    ("both", "", "co-simulation", None),
    ("both", 'interface = "co-simulation"\n', "co-simulation", None),
    ("both", 'interface = "model-exchange"\n', "model-exchange", "cvode"),
    ("both", 'solver = "euler"\n', "model-exchange", "euler"),
    ("both", "max_step = 0.001\n", "model-exchange", "cvode"),
    ("both", "event_tolerance = 1e-6\n", "model-exchange", "cvode"),
    ("me", "", "model-exchange", "cvode"),
    ("me", 'solver = "rk4"\n', "model-exchange", "rk4"),
    ("cs", "", "co-simulation", None),
])
def test_the_interface_an_instance_uses(fmus, tmp_path, which, fields, interface, solver):
    ip = _plan(_toml(tmp_path, fmus[which], fields)).instances["bb"]
    assert ip.interface == interface
    assert (ip.solver.name if ip.solver is not None else None) == solver


def test_the_solver_gets_the_instances_settings_and_resolved_tolerance(fmus, tmp_path):
    ip = _plan(_toml(tmp_path, fmus["both"], 'solver = "rk4"\nmax_step = 0.002\nevent_tolerance = 1e-7\n'
                                             "tolerance = 1e-8\n")).instances["bb"]
    assert ip.solver == SolverSpec("rk4", 1e-8, 0.002, 1e-7)
    ip = _plan(_toml(tmp_path, fmus["me"], experiment="stop = 0.1\nstep = 0.01\ntolerance = 1e-6\n",
                     name="e.toml")).instances["bb"]
    assert ip.solver == SolverSpec("cvode", 1e-6, None, DEFAULT_EVENT_TOLERANCE) and ip.tolerance == 1e-6
    assert _plan(_toml(tmp_path, fmus["me"], name="n.toml")).instances["bb"].solver.tolerance is None


def test_the_fixed_internal_step_counts_for_co_simulation_only(tmp_path):
    cs = _plan(_toml(tmp_path, DQ3, experiment="stop = 1.0\nstep = 0.1\n"))
    me = _plan(_toml(tmp_path, DQ3, 'interface = "model-exchange"\n', experiment="stop = 1.0\nstep = 0.1\n",
                     name="me.toml"))
    assert cs.internal_steps == {"bb": 10} and me.internal_steps == {}


# ------------------------------------------------------------------------------------------ bad inputs
#: fields of [instances.bb] (on the FMU "both", "me" or "cs") -> (the field named, words of the reason)
BAD: dict[str, tuple[str, str, str, list[str]]] = {
    "interface unknown": ("both", 'interface = "modelexchange"\n', "interface",
                          ["must be one of co-simulation, model-exchange", "did you mean 'model-exchange'?"]),
    "interface not a string": ("both", "interface = 2\n", "interface", ["must be one of"]),
    "solver unknown": ("both", 'solver = "rk5"\n', "solver", ["must be one of cvode, euler, rk4",
                                                              "did you mean 'rk4'?"]),
    "solver not a string": ("both", "solver = true\n", "solver", ["must be one of"]),
    "solver with co-simulation": ("both", 'interface = "co-simulation"\nsolver = "rk4"\n', "solver",
                                  ["model exchange", 'interface = "co-simulation"']),
    "max_step with co-simulation": ("both", 'interface = "co-simulation"\nmax_step = 0.1\n', "max_step",
                                    ["model exchange"]),
    "event_tolerance with co-simulation": ("both", 'interface = "co-simulation"\nevent_tolerance = 1e-6\n',
                                           "event_tolerance", ["model exchange"]),
    "max_step zero": ("both", "max_step = 0\n", "max_step", ["must be > 0"]),
    "max_step negative": ("both", "max_step = -0.1\n", "max_step", ["must be > 0"]),
    "max_step infinite": ("both", "max_step = inf\n", "max_step", ["must be finite"]),
    "max_step nan": ("both", "max_step = nan\n", "max_step", ["must be finite"]),
    "max_step a string": ("both", 'max_step = "small"\n', "max_step", ["must be a number"]),
    "event_tolerance zero": ("both", "event_tolerance = 0.0\n", "event_tolerance", ["must be > 0"]),
    "event_tolerance negative": ("both", "event_tolerance = -1e-9\n", "event_tolerance", ["must be > 0"]),
    "event_tolerance infinite": ("both", "event_tolerance = inf\n", "event_tolerance", ["must be finite"]),
    "tolerance zero": ("both", "tolerance = 0\n", "tolerance", ["must be > 0"]),
    "tolerance negative": ("me", "tolerance = -1e-6\n", "tolerance", ["must be > 0"]),
    "model exchange asked of a co-simulation FMU": (
        "cs", 'interface = "model-exchange"\n', "interface",
        ["BB_CS.fmu has no model exchange interface (it has co-simulation only)"]),
    "a solver asked of a co-simulation FMU": (
        "cs", 'solver = "rk4"\n', "solver",
        ["BB_CS.fmu has no model exchange interface (it has co-simulation only)", "integrator setting"]),
    "co-simulation asked of a model exchange FMU": (
        "me", 'interface = "co-simulation"\n', "interface",
        ["BB_ME.fmu has no co-simulation interface (it has model exchange only)"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_interface_or_solver_field_is_one_line_naming_it(case, fmus, tmp_path, capsys):
    which, fields, key, words = BAD[case]
    path = _toml(tmp_path, fmus[which], fields)
    with pytest.raises(ScenarioError) as exc:
        _plan(path)
    assert exc.value.file == str(path) and exc.value.field == f"instances.bb.{key}", str(exc.value)
    assert "\n" not in str(exc.value) and all(w in exc.value.reason for w in words), str(exc.value)
    for argv in (["check", str(path)], ["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]):
        line = _one_line(capsys, main(argv), [str(path), f"instances.bb.{key}", *words])
        assert line.startswith("wmr-cosim: error: ")
    assert not (tmp_path / "out").exists()


def test_an_experiment_tolerance_below_zero_is_refused(fmus, tmp_path, capsys):
    path = _toml(tmp_path, fmus["me"], experiment="stop = 0.1\nstep = 0.01\ntolerance = -1e-6\n")
    _one_line(capsys, main(["check", str(path)]), [str(path), "experiment.tolerance", "must be > 0"])


@pytest.mark.parametrize("which, options, words", [
    ("cs", ["--solver", "rk4"], ["instances.BouncingBall.solver", "has no model exchange interface"]),
    ("both", ["--solver", "rk5"], ["instances.BouncingBall.solver", "did you mean 'rk4'?"]),
    ("both", ["--max-step", "0"], ["instances.BouncingBall.max_step", "must be > 0"]),
    ("both", ["--max-step", "-0.001"], ["instances.BouncingBall.max_step", "must be > 0"]),
])
def test_bad_solver_options_of_one_fmu_are_one_line(fmus, tmp_path, capsys, which, options, words):
    for cmd in ("check", "run"):
        out = ["--out", str(tmp_path / "out"), "--quiet"] if cmd == "run" else []
        _one_line(capsys, main([cmd, str(fmus[which]), *options, *out]), [str(fmus[which]), *words])


@pytest.mark.parametrize("option", [["--solver", "rk4"], ["--max-step", "0.1"]])
def test_solver_options_apply_to_a_single_fmu_only(fmus, tmp_path, capsys, option):
    path = _toml(tmp_path, fmus["both"])
    _one_line(capsys, main(["check", str(path), *option]), [option[0], "applies to a single FMU",
                                                            f"[instances.NAME] {option[0][2:].replace('-', '_')}"])


# ------------------------------------------------------------------------------------------ check and info
def _check(capsys, argv: list[str]) -> str:
    code = main(["check", *argv])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


def test_check_names_each_instances_interface(fmus, tmp_path, capsys):
    assert "\n  BouncingBall: model exchange, cvode, rtol 1e-05\n" in _check(capsys, [str(fmus["me"])])
    assert "\n  BouncingBall: co-simulation\n" in _check(capsys, [str(fmus["both"])])
    assert ("\n  BouncingBall: model exchange, rk4, max step 0.001 s, events located to 1e-10 s\n"
            in _check(capsys, [str(fmus["both"]), "--solver", "rk4", "--max-step", "0.001"]))
    assert "\n  BouncingBall: model exchange, euler, one step per communication step, events located to 1e-10 s\n" \
        in _check(capsys, [str(fmus["both"]), "--solver", "euler"])
    path = tmp_path / "two.toml"
    path.write_text(f'[experiment]\nstop = 0.1\nstep = 0.01\ntolerance = 1e-7\n[instances.plant]\nfmu = "{fmus["both"]}"\n'
                    'interface = "model-exchange"\nmax_step = 0.01\n'
                    f'[instances.ball]\nfmu = "{fmus["both"]}"\n', encoding="utf-8")
    out = _check(capsys, [str(path)])
    assert "\n  plant: model exchange, cvode, rtol 1e-07, max step 0.01 s\n  ball: co-simulation\n" in out, out


def test_info_describes_a_model_exchange_fmu(tmp_path, capsys):
    for src, needs in ((BB2, True), (BB3, False)):
        fmu = me_only(src, tmp_path / f"ME{src.parent.name}.fmu")
        assert main(["info", str(fmu)]) == 0
        out = capsys.readouterr().out
        assert "cannot run here" not in out and "Model Exchange only" not in out, out
        assert (f"\n  model exchange: get/set state: True; serialize state: True; needsCompletedIntegratorStep: "
                f"{needs}; event indicators: 1; continuous states: 2\n") in out, out
        assert "\n  runs here as: model exchange, integrated by the master (cvode; " in out, out
    assert main(["info", str(BB2)]) == 0
    out = capsys.readouterr().out
    assert "\n  co-simulation: variable step: True;" in out and "\n  model exchange: get/set state: True;" in out
    assert "\n  runs here as: co-simulation (or model exchange, integrated by the master: --solver NAME" in out


def test_info_names_both_identifiers_where_they_differ(tmp_path, capsys):
    fmu = _edited(BB2, tmp_path / "two.fmu", lambda t: re.sub(r'(<ModelExchange\s+modelIdentifier=")BouncingBall"',
                                                             r'\1Other"', t))
    assert main(["info", str(fmu)]) == 0
    out = capsys.readouterr().out
    assert "identifier BouncingBall (model exchange: Other))" in out, out


# ------------------------------------------------------------------------------------------ runs
def _x(out: Path) -> tuple[np.ndarray, np.ndarray]:
    sig = np.load(out / "signals.npy")
    return sig["time"], sig["Dahlquist.x"]


def test_run_of_a_model_exchange_only_fmu_and_with_a_solver(tmp_path, capsys):
    """Dahlquist (x' = -x, x(0) = 1) over 1 s at 0.1 s: as model exchange (CVODE, or RK4) it follows
    exp(-t) far closer than its co-simulation interface's own forward Euler."""
    pytest.importorskip("wmr_cosim.cosim.instances.model_exchange")
    me = me_only(DQ2, tmp_path / "Dahlquist.fmu")
    runs = {"me": [str(me)], "cs": [str(DQ2)], "rk4": [str(DQ2), "--solver", "rk4", "--max-step", "0.01"],
            "isolated": [str(DQ2), "--solver", "rk4", "--max-step", "0.01", "--isolate"]}
    err = {}
    for name, argv in runs.items():
        code = main(["run", *argv, "--stop", "1", "--out", str(tmp_path / name), "--quiet"])
        assert code == 0, capsys.readouterr().err
        t, x = _x(tmp_path / name)
        assert len(t) == 11
        err[name] = float(np.max(np.abs(x - np.exp(-t))))
    capsys.readouterr()
    assert err["me"] < 1e-4 and err["rk4"] < 1e-9 and err["cs"] > 1e-2, err
    assert np.array_equal(_x(tmp_path / "isolated")[1], _x(tmp_path / "rk4")[1])   # the child ran model exchange


def test_the_isolated_child_builds_a_model_exchange_instance(tmp_path):
    pytest.importorskip("wmr_cosim.cosim.instances.model_exchange")
    from wmr_cosim.cosim.instances.failure import Call
    from wmr_cosim.cosim.instances.isolation import IsolatedInstance
    from wmr_cosim.cosim.instances.model_exchange import ModelExchange
    from wmr_cosim.cosim.runtime.startup import load_instances

    for isolate in (False, True):
        plan = fmu_plan(DQ2, {"experiment.stop": 1.0}, isolate=isolate, fields={"solver": "euler"})
        (tmp_path / f"w{isolate}").mkdir()
        (tmp_path / f"l{isolate}").mkdir()
        insts = load_instances(plan, tmp_path / f"w{isolate}", tmp_path / f"l{isolate}")
        try:
            (inst,) = insts.values()
            if isolate:
                assert isinstance(inst, IsolatedInstance) and inst.solver == plan.instances["Dahlquist"].solver
                assert inst.call_name(Call.DO_STEP) == "the integration (euler)"
            else:
                assert isinstance(inst, ModelExchange) and inst.solver.name == "euler"
        finally:
            for inst in insts.values():
                inst.shutdown()


def test_a_euler_run_differs_from_rk4_by_the_methods_order(tmp_path, capsys):
    """One integrator step per communication step of 0.1 s: Euler's error is of the order h, RK4's h^4."""
    pytest.importorskip("wmr_cosim.cosim.instances.model_exchange")
    errs = {}
    for solver in ("euler", "rk4"):
        assert main(["run", str(DQ3), "--solver", solver, "--stop", "1", "--out", str(tmp_path / solver),
                     "--quiet"]) == 0, capsys.readouterr().err
        sig = np.load(tmp_path / solver / "signals.npy")
        errs[solver] = float(np.max(np.abs(sig["Dahlquist.x"] - np.exp(-sig["time"]))))
    assert 1e-2 < errs["euler"] < 0.05 and errs["rk4"] < 1e-5, errs


# ------------------------------------------------------------------------------------------ API and SSP
def test_the_api_passes_the_instance_fields_through(fmus, tmp_path):
    sim = Simulation().experiment(stop=0.1, step=0.01).instance("bb", fmus["both"], fields={"solver": "rk4",
                                                                                          "max_step": 0.005})
    ip = sim.check().instances["bb"]
    assert ip.interface == "model-exchange" and ip.solver == SolverSpec("rk4", None, 0.005, DEFAULT_EVENT_TOLERANCE)
    assert Simulation().experiment(stop=0.1, step=0.01).instance("bb", fmus["both"]).check() \
        .instances["bb"].interface == "co-simulation"
    assert Simulation.load(fmus["me"]).check().instances["BouncingBall"].interface == "model-exchange"
    with pytest.raises(ScenarioError) as exc:
        Simulation().instance("bb", fmus["both"], fields={"interface": "me"}).check()
    assert exc.value.field == "instances.bb.interface"


def test_fmu_document_takes_instance_fields_and_names_an_me_only_fmu(fmus):
    doc = fmu_document(fmus["me"], fields={"solver": "euler"})
    assert doc["instances"] == {"BouncingBall": {"solver": "euler", "fmu": str(fmus["me"].resolve())}}


def test_ssp_says_model_exchange_and_reads_it_back(fmus, tmp_path):
    from wmr_cosim.cosim.plan.ssp import export_remarks, export_ssp, load_ssp

    plan = _plan(_toml(tmp_path, fmus["both"], 'interface = "model-exchange"\n'))
    out = export_ssp(plan, tmp_path / "me.ssp")
    assert 'implementation="ModelExchange"' in zipfile.ZipFile(out).read("SystemStructure.ssd").decode()
    assert any(kind == "note" and "bb runs as model exchange" in text for kind, text in export_remarks(plan))
    arch = load_ssp(out)
    try:
        assert arch.scenario.instances["bb"].interface == "model-exchange"
        assert cosim.resolve(arch.scenario).instances["bb"].interface == "model-exchange"
    finally:
        arch.cleanup()
    cs = export_ssp(_plan(_toml(tmp_path, fmus["both"], name="cs.toml")), tmp_path / "cs.ssp")
    assert "implementation=" not in zipfile.ZipFile(cs).read("SystemStructure.ssd").decode()
