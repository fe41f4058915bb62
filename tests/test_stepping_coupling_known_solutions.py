"""The iterated coupling on systems with a known solution, built from small C FMUs (tests/coupling_fmus.py):

* a two-mass oscillator split across two FMUs, the coupling force with direct feedthrough of the other
  body's position and velocity, against its closed form z(t) = expm(A t) z0;
* a pure algebraic loop of two affine maps with time-varying offsets, against its closed form;

and what ``check`` says of them, the scenario's settings and their refusals, the SSP annotation."""
from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

from wmr_cosim import cli
from wmr_cosim import cosim
from wmr_cosim.cosim.stepping.generated import GaussSeidel, Jacobi
from wmr_cosim.cosim.stepping.settings import IterationSpec
from wmr_cosim.cosim.stepping.iterated import Iterated
from wmr_cosim.cosim.plan.ssp import OWN_NS, export_ssp, load_ssp

from c_fmu_support import build_probe
from cosim_support import write_document
from coupling_fmus import AffineLoop, TwoMass, build_affine, build_mass, two_mass_document


#: A loop whose fixed-point iteration needs more iterations as the run goes on (see its test).
MID_RUN = AffineLoop(0.5, 0.8, (1.0, -1.5, 0.5, 3.0), (-2.0, 0.0, 0.0, 1.0))


@pytest.fixture(scope="module")
def mass_fmus(tmp_path_factory) -> tuple[Path, Path]:
    return build_mass(tmp_path_factory.mktemp("mass"))


@pytest.fixture(scope="module")
def affine_fmu(tmp_path_factory) -> Path:
    return build_affine(tmp_path_factory.mktemp("affine"))


def _run(doc: dict, out: Path, alg) -> np.ndarray:
    plan = cosim.resolve(cosim.parse(doc, "coupling.toml"))
    res = cosim.run(plan, out, progress=False, algorithm=alg)
    assert res.status == "ok", res.message
    return np.load(out / "signals.npy")


def _mass_error(sig: np.ndarray, tm: TwoMass) -> float:
    """The largest error of both positions against the closed form over the run [m]."""
    ref = tm.closed_form(sig["time"])
    return float(max(np.max(np.abs(sig["body.x"] - ref[:, 0])), np.max(np.abs(sig["coupler.x"] - ref[:, 2]))))


def test_the_fmus_alone_are_exact_enough_to_measure_the_coupling(mass_fmus, tmp_path):
    """The FMUs' internal RK4 (10 us) on the uncoupled bodies (kc = dc = 0) meets each body's closed form
    to 1e-9 m: every error measured below is the coupling's."""
    tm = TwoMass(kc=0.0, dc=0.0)
    sig = _run(two_mass_document(mass_fmus, tm, stop=2.0, step=0.01), tmp_path / "free", GaussSeidel())
    assert _mass_error(sig, tm) < 1e-9
    assert np.all(sig["coupler.F"] == 0.0)


def test_iterated_linear_coupling_is_ten_times_better_and_second_order(mass_fmus, tmp_path, capsys):
    """At each macro step h = 10, 5, 2.5, 1.25 ms over 2 s: the iterated coupling with linear inputs (the
    coupling inputs linear over the step, fmi2SetRealInputDerivatives) is at least 10 times closer to the
    closed form than one Gauss-Seidel pass, and its error falls by about 4 per halving (second order), the
    one pass's by about 2 (first order); holding the iterated inputs over the step is first order too."""
    tm = TwoMass()
    steps = [0.01, 0.005, 0.0025, 0.00125]
    table = {"gauss-seidel": [], "iterated, held": [], "iterated, linear": []}
    for h in steps:
        doc = two_mass_document(mass_fmus, tm, stop=2.0, step=h)
        for name, alg in (("gauss-seidel", GaussSeidel()), ("iterated, held", Iterated(IterationSpec("newton"))),
                          ("iterated, linear", Iterated(IterationSpec("newton", inputs="linear")))):
            table[name].append(_mass_error(_run(doc, tmp_path / f"{name[:10]}-{h}", alg), tm))
    with capsys.disabled():
        print("\n  step [s]   " + "".join(f"{k:>18}" for k in table) + "   (largest position error [m])")
        for i, h in enumerate(steps):
            print(f"  {h:<10g}" + "".join(f"{table[k][i]:18.3e}" for k in table))
    gs, held, lin = table["gauss-seidel"], table["iterated, held"], table["iterated, linear"]
    for i in range(len(steps)):
        assert gs[i] >= 10.0 * lin[i], (steps[i], gs[i], lin[i])
    order = lambda e: [math.log2(a / b) for a, b in zip(e, e[1:])]   # noqa: E731
    assert all(1.8 <= p <= 2.2 for p in order(lin)), order(lin)
    assert all(0.8 <= p <= 1.2 for p in order(gs)), order(gs)
    assert all(0.7 <= p <= 1.3 for p in order(held)), order(held)


def test_the_affine_loop_is_solved_at_every_step_where_one_pass_drifts(affine_fmu, tmp_path):
    """y1 = 0.5 u1 + 1 + 0.3 t + 0.5 sin 3t, y2 = 0.8 u2 - 2 + 0.2 sin 7t (ac = 0.4): Newton and the fixed
    point meet the closed form to 1e-10 at every row, t = 0 included (the loop solved at initialisation);
    one Gauss-Seidel pass per step lags it by a step, Jacobi by two."""
    loop = AffineLoop(0.5, 0.8, (1.0, 0.3, 0.5, 3.0), (-2.0, 0.0, 0.2, 7.0))
    doc = loop.document(affine_fmu, stop=1.0, step=0.01)

    def error(sig: np.ndarray) -> float:
        y1, y2 = loop.solution(sig["time"])
        return float(max(np.max(np.abs(sig["one.y"] - y1)), np.max(np.abs(sig["two.y"] - y2))))

    for method in ("newton", "fixed-point"):
        sig = _run(doc, tmp_path / method, Iterated(IterationSpec(method, tolerance=1e-12, max_iterations=60)))
        assert len(sig) == 101 and error(sig) <= 1e-10, (method, error(sig))
    assert error(_run(doc, tmp_path / "gs", GaussSeidel())) > 1e-2
    assert error(_run(doc, tmp_path / "j", Jacobi())) > 1e-2


def test_a_loop_that_expands_diverges_under_fixed_point_and_converges_under_newton(affine_fmu, tmp_path):
    """a c = 1.6: the fixed point's error grows by 1.6 per iteration, it fails at initialisation with one
    line naming the loop (status failed); Newton meets the closed form to 1e-10 at every row."""
    loop = AffineLoop(2.0, 0.8, (1.0, 0.3, 0.5, 3.0), (-2.0, 0.0, 0.2, 7.0))
    doc = loop.document(affine_fmu, stop=1.0, step=0.01)
    plan = cosim.resolve(cosim.parse(doc, "loop.toml"))
    res = cosim.run(plan, tmp_path / "fp", progress=False,
                        algorithm=Iterated(IterationSpec("fixed-point", max_iterations=50)))
    assert res.status == "failed" and "\n" not in res.message
    assert "the coupling loop one <-> two did not converge at initialisation" in res.message
    sig = _run(doc, tmp_path / "nw", Iterated(IterationSpec("newton", tolerance=1e-12)))
    y1, y2 = loop.solution(sig["time"])
    assert np.max(np.abs(sig["one.y"] - y1)) <= 1e-10 and np.max(np.abs(sig["two.y"] - y2)) <= 1e-10


def test_a_loop_failing_mid_run_keeps_the_rows_before_it(affine_fmu, tmp_path):
    """The iteration limit met at a later step: b1(t) = 1 - 1.5 t + 0.5 sin 3t (no slope at t = 0), so the
    error of the first guess (the inputs extrapolated from the last two steps) grows with |sin 3t| and
    the fixed point (contracting by sqrt(0.4) per iteration) needs more iterations as t grows; at 33 the
    run ends at a step after the first tens with one line naming the loop, the step and the time; the rows
    up to it are on disk, each solved."""
    doc = MID_RUN.document(affine_fmu, stop=1.0, step=0.01)
    plan = cosim.resolve(cosim.parse(doc, "loop.toml"))
    res = cosim.run(plan, tmp_path / "x", progress=False,
                        algorithm=Iterated(IterationSpec("fixed-point", tolerance=1e-10, max_iterations=33)))
    assert res.status == "failed", res.message
    assert "the coupling loop one <-> two did not converge at step" in res.message and "t = " in res.message
    sig = np.load(tmp_path / "x" / "signals.npy")
    assert 20 <= len(sig) < 101
    loop = MID_RUN
    y1, _ = loop.solution(sig["time"])
    assert np.max(np.abs(sig["one.y"] - y1)) <= 1e-8


def test_a_loop_failing_mid_run_exits_1_with_one_line_and_the_rows_on_disk(affine_fmu, tmp_path, capsys):
    """The same failure from the command line: exit code 1, the error's line naming the loop and the step
    and the run's line saying where the rows are; signals.npy and summary.json written with them."""
    doc = MID_RUN.document(affine_fmu, stop=1.0, step=0.01)
    doc["experiment"].update(algorithm="iterated", iteration={"method": "fixed-point", "max_iterations": 33})
    path = write_document(tmp_path / "fails.toml", doc)
    code, _, err = _cli(capsys, "run", str(path), "--out", str(tmp_path / "o"), "--quiet")
    lines = err.strip().splitlines()
    assert code == 1 and len(lines) == 2, err
    assert lines[0].startswith("wmr-cosim: run failed: the coupling loop one <-> two did not converge at step")
    assert "fails.toml: failed after" in lines[1] and "what was recorded (" in lines[1] and " rows, to t = " in lines[1]
    sig = np.load(tmp_path / "o" / "signals.npy")
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["status"] == "failed" and 20 <= len(sig) < 101


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_check_names_the_loops(mass_fmus, affine_fmu, tmp_path, capsys):
    """The affine ring is an algebraic loop (each output depends directly on its input); the two masses are
    a coupling loop without one (the bodies' outputs do not depend directly on their inputs)."""
    path = write_document(tmp_path / "aff.toml", AffineLoop(0.5, 0.8).document(affine_fmu, stop=1.0, step=0.01))
    code, out, _ = _cli(capsys, "check", str(path))
    assert code == 0
    assert "coupling loop one <-> two: one pass per step" in out
    assert "algebraic loop one.y -> two.u -> two.y -> one.u -> one.y: one pass per step lags it by a step" in out
    doc = AffineLoop(0.5, 0.8).document(affine_fmu, stop=1.0, step=0.01)
    doc["experiment"].update(algorithm="iterated", iteration={"method": "fixed-point", "relaxation": 0.5})
    code, out, _ = _cli(capsys, "check", str(write_document(tmp_path / "it.toml", doc)))
    assert code == 0
    assert "iterated: fixed-point, relaxation 0.5, tolerance 1e-10, at most 20 iterations, inputs hold" in out
    assert "algebraic loop one.y -> two.u -> two.y -> one.u -> one.y: solved at every step" in out
    path = write_document(tmp_path / "m.toml", two_mass_document(mass_fmus, TwoMass(), stop=1.0, step=0.01))
    code, out, _ = _cli(capsys, "check", str(path))
    assert code == 0 and "coupling loop body <-> coupler" in out and "algebraic loop" not in out


def test_an_output_without_declared_dependencies_depends_on_every_input(tmp_path, capsys):
    """FMI: an output whose Unknown has no ``dependencies`` attribute depends on every input (a loop of
    such FMUs is algebraic); ``dependencies=""`` says it depends on none (no algebraic loop)."""
    for name, deps, loop in (("AffineAll", None, True), ("AffineNone", (), False)):
        fmu = build_affine(tmp_path / name, name, deps)
        path = write_document(tmp_path / f"{name}.toml", AffineLoop(0.5, 0.8).document(fmu, stop=0.1, step=0.01))
        code, out, _ = _cli(capsys, "check", str(path))
        assert code == 0 and "coupling loop one <-> two" in out
        assert ("algebraic loop one.y -> two.u -> two.y -> one.u -> one.y" in out) is loop, out


@pytest.mark.parametrize("table, field, words", [
    ({"iteration": {"tolerance": 0.0}}, "experiment.iteration.tolerance", "must be a number > 0"),
    ({"iteration": {"tolerance": -1e-6}}, "experiment.iteration.tolerance", "must be a number > 0"),
    ({"iteration": {"max_iterations": 0}}, "experiment.iteration.max_iterations", "must be an integer >= 1"),
    ({"iteration": {"method": "broyden"}}, "experiment.iteration.method", "must be one of fixed-point, newton"),
    ({"iteration": {"relaxation": 1.5}}, "experiment.iteration.relaxation", "must be in (0, 1]"),
    ({"iteration": {"inputs": "cubic"}}, "experiment.iteration.inputs", "must be one of hold, linear"),
    ({"iteration": {"jacobian": "exact"}}, "experiment.iteration.jacobian",
     "must be one of finite-differences, directional"),
    ({"iteration": {"method": "fixed-point", "jacobian": "directional"}}, "experiment.iteration.jacobian",
     "is Newton's"),
    ({"algorithm": "adaptive", "adaptive": {"min_step": 0.005, "max_step": 0.001}}, "experiment.adaptive.min_step",
     "is larger than max_step"),
    ({"algorithm": "adaptive", "adaptive": {"max_step": 0.02}}, "experiment.adaptive.max_step",
     "is longer than the output interval"),
    ({"algorithm": "adaptive", "adaptive": {"rtol": 0}}, "experiment.adaptive.rtol", "must be a number > 0"),
    ({"algorithm": "adaptive", "adaptive": {"coupling": "newton"}}, "experiment.adaptive.coupling", "must be one of"),
    ({"algorithm": "gauss-seidel", "iteration": {"max_iterations": 0}}, "experiment.iteration.max_iterations",
     "must be an integer >= 1"),     # a table the algorithm does not read is checked all the same
    ({"adaptive": {"rtol": -1e-3}}, "experiment.adaptive.rtol", "must be a number > 0"),
    ({"algorithm": "newton"}, "experiment.algorithm", "must be one of"),
])
def test_bad_settings_are_one_line_each_exit_2(affine_fmu, tmp_path, capsys, table, field, words):
    """Each bad setting, at check and at run: exit code 2, one line naming the file and the field."""
    doc = AffineLoop(0.5, 0.8).document(affine_fmu, stop=1.0, step=0.01)
    doc["experiment"].update({"algorithm": "iterated", **table})
    path = write_document(tmp_path / "bad.toml", doc)
    for command in ("check", "run"):
        code, out, err = _cli(capsys, command, str(path), *(["--out", str(tmp_path / "o"), "--quiet"]
                                                             if command == "run" else []))
        assert code == 2, (command, out, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and f"bad.toml: {field}" in lines[0] and words in lines[0], lines
    assert not (tmp_path / "o").exists()


def test_iteration_on_an_fmu_without_state_is_refused_at_check(tmp_path, capsys):
    """Two probe FMUs (y = p u, canGetAndSetFMUstate not declared) in a ring: one pass per step runs; the
    iterated coupling, which rolls the loop back at each iteration, and the step-size control are refused
    at check naming the instance, exit 2; nothing is run."""
    probe = build_probe(tmp_path / "fmu")
    doc = {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.01},
           "instances": {"p": {"fmu": str(probe), "parameters": {"p": 0.5}}, "q": {"fmu": str(probe)}},
           "connections": [{"from": "p.y", "to": "q.u"}, {"from": "q.y", "to": "p.u"}]}
    code, out, _ = _cli(capsys, "check", str(write_document(tmp_path / "gs.toml", doc)))
    assert code == 0 and "algebraic loop p.y -> q.u -> q.y -> p.u -> p.y" in out
    for algorithm, why in (("iterated", "rolls back the coupling loop p <-> q at every iteration"),
                           ("adaptive", "rolls back every instance when it rejects a step")):
        doc["experiment"]["algorithm"] = algorithm
        path = write_document(tmp_path / f"{algorithm}.toml", doc)
        for command in ("check", "run"):
            code, _, err = _cli(capsys, command, str(path), *(["--out", str(tmp_path / "o"), "--quiet"]
                                                              if command == "run" else []))
            lines = err.strip().splitlines()
            assert code == 2 and len(lines) == 1, (command, err)
            assert f"{algorithm}.toml: instances.p: Probe.fmu cannot get and set its state" in lines[0] and why in lines[0]
        assert not (tmp_path / "o").exists()


def test_the_settings_go_through_the_scenario_file_into_summary_json(affine_fmu, tmp_path, capsys):
    """[experiment.iteration] in a file: the run uses it (counted per loop in summary.json), the same file
    twice gives the same bytes."""
    doc = AffineLoop(2.0, 0.8, (1.0, 0.3, 0.5, 3.0)).document(affine_fmu, stop=0.5, step=0.01)
    doc["experiment"].update(algorithm="iterated", iteration={"method": "newton", "tolerance": 1e-12,
                                                              "max_iterations": 5})
    path = write_document(tmp_path / "it.toml", doc)
    outs = []
    for k in range(2):
        code, _, err = _cli(capsys, "run", str(path), "--out", str(tmp_path / f"o{k}"), "--quiet")
        assert code == 0, err
        outs.append((tmp_path / f"o{k}" / "signals.npy").read_bytes())
    assert outs[0] == outs[1]
    summary = json.loads((tmp_path / "o0" / "summary.json").read_text())
    st = summary["stepping"]
    assert st["algorithm"] == "iterated" and st["iteration"]["tolerance"] == 1e-12
    assert st["iteration"]["max_iterations"] == 5
    (lp,) = st["loops"]
    assert lp["instances"] == ["one", "two"] and lp["steps"] == 50 and lp["max_iterations_per_step"] <= 5
    assert sum(lp["steps_by_iterations"].values()) == 50
    assert sum(int(n) * c for n, c in lp["steps_by_iterations"].items()) == lp["iterations"]
    assert lp["max_residual_accepted"] <= 1e-12


def test_ssp_keeps_the_settings_in_its_own_annotation(affine_fmu, tmp_path):
    """An exported iterated system carries algorithm and settings in this master's annotation on the
    DefaultExperiment; read back, the same settings, and the run gives the same rows bit for bit."""
    doc = AffineLoop(2.0, -0.6, (1.0, 0.3, 0.5, 3.0)).document(affine_fmu, stop=0.2, step=0.01)
    doc["experiment"].update(algorithm="iterated", iteration={"method": "fixed-point", "relaxation": 0.45,
                                                              "tolerance": 1e-9, "max_iterations": 200})
    plan = cosim.resolve(cosim.parse(doc, "it.toml"))
    out = export_ssp(plan, tmp_path / "it.ssp")
    from lxml import etree as ET

    root = ET.fromstring(zipfile.ZipFile(out).read("SystemStructure.ssd"))
    (el,) = root.iter(f"{{{OWN_NS}}}Iteration")
    assert el.get("method") == "fixed-point" and float(el.get("relaxation")) == 0.45
    arch = load_ssp(out)
    try:
        sc = arch.scenario
        assert sc.algorithm == "iterated" and sc.iteration == plan.scenario.iteration
        again = cosim.resolve(sc)
        a = cosim.run(plan, tmp_path / "a", progress=False)
        b = cosim.run(again, tmp_path / "b", progress=False)
        assert a.status == b.status == "ok", (a.message, b.message)
        sa, sb = np.load(tmp_path / "a" / "signals.npy"), np.load(tmp_path / "b" / "signals.npy")
        assert sa.tobytes() == sb.tobytes()
    finally:
        arch.cleanup()
    arch = load_ssp(out, algorithm="jacobi")   # (another algorithm asked for: the settings are not its)
    try:
        assert arch.scenario.algorithm == "jacobi" and arch.scenario.iteration is None
    finally:
        arch.cleanup()


def test_the_step_size_control_puts_its_steps_where_the_contact_is(mass_fmus, tmp_path):
    """The two masses with a stiff contact (engaged about 7 % of the time): the step-size control (one
    Gauss-Seidel pass per step, rtol = atol = 1e-4) is closer to the monolithic ODE than the fixed step
    taking as many macro steps as it took (accepted and rejected), it rejects steps and its steps vary by
    more than ten times, and a tighter tolerance gives a smaller error."""
    from scipy.integrate import solve_ivp

    from wmr_cosim.cosim.stepping import table as algorithms
    from wmr_cosim.cosim.stepping.settings import AdaptiveSpec

    tm = TwoMass(x1=0.0, v1=3.0, kk=1e4, gap=0.05, h_int=1e-5)
    doc = two_mass_document(mass_fmus, tm, stop=2.0, step=0.01)
    ode = solve_ivp(tm.rhs, (0.0, 2.0), [tm.x1, tm.v1, tm.x2, tm.v2], method="DOP853", rtol=1e-12, atol=1e-12,
                    dense_output=True, max_step=1e-3)

    def error(sig: np.ndarray) -> float:
        z = ode.sol(sig["time"]).T
        return float(max(np.max(np.abs(sig["body.x"] - z[:, 0])), np.max(np.abs(sig["coupler.x"] - z[:, 2]))))

    plan = cosim.resolve(cosim.parse(doc, "contact.toml"))
    errors, counts = [], []
    for tol in (1e-3, 1e-4):
        res = cosim.run(plan, tmp_path / f"a{tol}", progress=False,
                            algorithm=algorithms.make("adaptive", None,
                                                      AdaptiveSpec(rtol=tol, atol=tol, coupling="gauss-seidel")))
        assert res.status == "ok", res.message
        st = res.summary["stepping"]
        assert st["rejected_steps"] >= 1 and st["smallest_step"] < 0.1 * st["largest_step"]
        errors.append(error(np.load(tmp_path / f"a{tol}" / "signals.npy")))
        counts.append(st["accepted_steps"] + st["rejected_steps"])
    assert errors[1] < 0.6 * errors[0]
    n = counts[1]
    step = 2.0 / n
    fixed = cosim.run(cosim.resolve(cosim.parse(two_mass_document(mass_fmus, tm, stop=2.0, step=step),
                                                        "fixed.toml")), tmp_path / "fixed", progress=False)
    assert fixed.status == "ok", fixed.message
    assert errors[1] < 0.5 * error(np.load(tmp_path / "fixed" / "signals.npy")), (errors[1], n)


def test_iterated_and_adaptive_through_isolated_instances_are_bit_for_bit(mass_fmus, tmp_path):
    """The body hosted in a child process: the iterated coupling with linear inputs (input derivatives
    through the child) and the step-size control over it (rollbacks included) give the in-process rows."""
    from wmr_cosim.cosim.stepping import table as algorithms
    from wmr_cosim.cosim.stepping.settings import AdaptiveSpec

    tm = TwoMass(x1=0.0, v1=3.0, kk=1e4, gap=0.05, h_int=1e-5)
    lin = IterationSpec("newton", inputs="linear")
    for name, make in (("iterated", lambda: Iterated(lin)),
                       ("adaptive", lambda: algorithms.make("adaptive", lin, AdaptiveSpec(rtol=1e-3, atol=1e-3,
                                                                                       coupling="iterated")))):
        doc = two_mass_document(mass_fmus, tm, stop=0.5, step=0.01)
        base = _run(doc, tmp_path / f"{name}-in", make())
        doc["instances"]["body"]["isolate"] = True
        iso = _run(doc, tmp_path / f"{name}-iso", make())
        assert iso.tobytes() == base.tobytes(), name


def test_newton_with_the_fmus_directional_derivatives(affine_fmu, mass_fmus, tmp_path):
    """jacobian = "directional": Newton's Jacobian from fmi2GetDirectionalDerivative (dy/du = a), no
    evaluation spent on it: the affine loops (a c = 0.4 and 1.6) meet the closed form to 1e-10 at every row
    with at most the finite-difference run's iterations (its Jacobian is exact) and fewer evaluations of
    the loop, hosted in a child process bit for bit; refused at check for FMUs that do not declare directional derivatives."""
    from wmr_cosim.cosim.messages.errors import ScenarioError

    for a1 in (0.5, 2.0):
        loop = AffineLoop(a1, 0.8, (1.0, 0.3, 0.5, 3.0), (-2.0, 0.0, 0.2, 7.0))
        doc = loop.document(affine_fmu, stop=1.0, step=0.01)
        plan = cosim.resolve(cosim.parse(doc, "dd.toml"))
        counts = {}
        rows = {}
        for jac in ("finite-differences", "directional"):
            res = cosim.run(plan, tmp_path / f"{a1}-{jac}", progress=False,
                                algorithm=Iterated(IterationSpec("newton", tolerance=1e-12, jacobian=jac)))
            assert res.status == "ok", res.message
            (counts[jac],) = res.summary["stepping"]["loops"]
            rows[jac] = np.load(tmp_path / f"{a1}-{jac}" / "signals.npy")
            y1, y2 = loop.solution(rows[jac]["time"])
            assert np.max(np.abs(rows[jac]["one.y"] - y1)) <= 1e-10 and np.max(np.abs(rows[jac]["two.y"] - y2)) <= 1e-10
        fd, dd = counts["finite-differences"], counts["directional"]
        assert dd["iterations"] <= fd["iterations"] and dd["jacobians"] >= 1
        assert dd["loop_evaluations"] == dd["iterations"]   # (no evaluation spent on a Jacobian)
        assert dd["loop_evaluations"] < fd["loop_evaluations"] - 2 * fd["jacobians"] + 1
        doc["instances"]["one"]["isolate"] = True
        iso = _run(doc, tmp_path / f"{a1}-iso", Iterated(IterationSpec("newton", tolerance=1e-12, jacobian="directional")))
        assert iso.tobytes() == rows["directional"].tobytes()
    doc = two_mass_document(mass_fmus, TwoMass(), stop=0.1, step=0.01)
    doc["experiment"].update(algorithm="iterated", iteration={"jacobian": "directional"})
    with pytest.raises(ScenarioError) as err:
        cosim.resolve(cosim.parse(doc, "m.toml"))
    assert err.value.field == "experiment.iteration.jacobian" and "body (MassForce.fmu, co-simulation) does not" in str(err.value)
