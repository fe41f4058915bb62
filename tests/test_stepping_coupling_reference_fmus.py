"""The algorithms that iterate coupling loops and control the step, on the Modelica Reference FMUs: an
algebraic loop through two Feedthrough FMUs (y = u) closed by connections with factors and offsets, whose
solution is known in closed form; FMI 2.0 and 3.0, isolated and Model Exchange instances; the output grid
of the step-size control."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim import cosim
from wmr_cosim.cosim.stepping import table as algorithms
from wmr_cosim.cosim.stepping.generated import GaussSeidel
from wmr_cosim.cosim.stepping.settings import AdaptiveSpec, IterationSpec
from wmr_cosim.cosim.stepping.iterated import Iterated

from reference_fmus import REF

OUT, IN = "Float64_continuous_output", "Float64_continuous_input"


def ring(version: str, a: float, b: float, c: float, d: float, *, stop: float = 0.1, step: float = 0.01,
         fields: dict[str, Any] | None = None) -> cosim.Plan:
    """Two Feedthrough FMUs in a ring: B.u = a A.y + b, A.u = c B.y + d; ``fields`` added to instance A."""
    fmu = str(REF / version / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": stop, "step": step},
           "instances": {"A": {"fmu": fmu, **(fields or {})}, "B": {"fmu": fmu}},
           "connections": [{"from": f"A.{OUT}", "to": f"B.{IN}", "factor": a, "offset": b},
                           {"from": f"B.{OUT}", "to": f"A.{IN}", "factor": c, "offset": d}],
           "record": {"variables": [f"A.{OUT}", f"B.{OUT}"]}}
    return cosim.resolve(cosim.parse(doc, "ring.toml"))


def solution(a: float, b: float, c: float, d: float) -> tuple[float, float]:
    """y_A = c (a y_A + b) + d."""
    ya = (c * b + d) / (1.0 - a * c)
    return ya, a * ya + b


def run(plan: cosim.Plan, out: Path, alg: Any) -> tuple[cosim.RunResult, np.ndarray]:
    res = cosim.run(plan, out, progress=False, algorithm=alg)
    sig = np.load(out / "signals.npy") if (out / "signals.npy").is_file() else np.zeros(0)
    return res, sig


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_newton_solves_a_loop_that_one_pass_and_fixed_point_cannot(version, tmp_path):
    """|ac| = 1.6: one Gauss-Seidel pass per step runs away, the fixed point diverges (one line naming the
    loop, at initialisation, nothing silently wrong), Newton meets the closed form to 1e-12 on every row."""
    a, b, c, d = 2.0, 1.0, 0.8, -3.0
    ya, yb = solution(a, b, c, d)
    plan = ring(version, a, b, c, d)
    res, sig = run(plan, tmp_path / "gs", GaussSeidel())
    assert res.status == "ok" and abs(sig[f"A.{OUT}"][-1] - ya) > 100.0
    res, sig = run(plan, tmp_path / "fp", Iterated(IterationSpec("fixed-point", max_iterations=40)))
    assert res.status == "failed"
    assert "the coupling loop A <-> B did not converge at initialisation" in res.message and "\n" not in res.message
    res, sig = run(plan, tmp_path / "nw", Iterated(IterationSpec("newton")))
    assert res.status == "ok", res.message
    assert len(sig) == 11
    assert np.max(np.abs(sig[f"A.{OUT}"] - ya)) < 1e-12 and np.max(np.abs(sig[f"B.{OUT}"] - yb)) < 1e-12
    loops = res.summary["stepping"]["loops"]
    assert loops[0]["instances"] == ["A", "B"] and loops[0]["steps"] == 10
    assert loops[0]["max_residual_accepted"] <= 1e-10


def test_fixed_point_converges_where_it_contracts_and_relaxation_widens_that(tmp_path):
    """ac = 0.4: plain fixed point meets 1e-10 at every row while one pass per step is still off at the
    first rows; ac = -1.2: plain fixed point diverges (the iteration over both inputs has eigenvalues
    +-i sqrt(1.2)), relaxed by 0.45 it converges (|1 - w + w i sqrt(1.2)| = 0.74)."""
    a, b, c, d = 0.5, 1.0, 0.8, -3.0
    ya, _ = solution(a, b, c, d)
    plan = ring("fmi2", a, b, c, d)
    _, gs = run(plan, tmp_path / "gs", GaussSeidel())
    res, fp = run(plan, tmp_path / "fp", Iterated(IterationSpec("fixed-point", max_iterations=60)))
    assert res.status == "ok", res.message
    assert np.max(np.abs(fp[f"A.{OUT}"] - ya)) <= 1e-9
    assert abs(gs[f"A.{OUT}"][1] - ya) > 1e-6   # (one pass per step approaches it step by step)
    a, c = 2.0, -0.6
    ya, _ = solution(a, b, c, d)
    plan = ring("fmi2", a, b, c, d)
    res, _ = run(plan, tmp_path / "fp2", Iterated(IterationSpec("fixed-point", max_iterations=60)))
    assert res.status == "failed" and "did not converge" in res.message
    res, fr = run(plan, tmp_path / "fr", Iterated(IterationSpec("fixed-point", relaxation=0.45, max_iterations=200)))
    assert res.status == "ok", res.message
    assert np.max(np.abs(fr[f"A.{OUT}"] - ya)) <= 1e-9


def test_a_loop_that_never_converges_ends_the_run_at_its_step_with_the_rows_kept(tmp_path):
    """ac = 1 with b c + d != 0 has no solution: at initialisation the Newton step meets a singular
    Jacobian; one line, status failed."""
    plan = ring("fmi2", 1.0, 1.0, 1.0, 1.0)
    res, _ = run(plan, tmp_path / "x", Iterated(IterationSpec("newton")))
    assert res.status == "failed"
    assert "A <-> B" in res.message and ("singular" in res.message or "did not converge" in res.message)


def test_isolated_and_model_exchange_instances_iterate_to_the_same_rows(tmp_path):
    """Instance A hosted in a child process, or run through its Model Exchange interface: the rows equal
    the in-process co-simulation ones bit for bit (Feedthrough's output is its input: no integration)."""
    a, b, c, d = 2.0, 1.0, 0.8, -3.0
    alg = IterationSpec("newton")
    _, base = run(ring("fmi2", a, b, c, d), tmp_path / "base", Iterated(alg))
    res, iso = run(ring("fmi2", a, b, c, d, fields={"isolate": True}), tmp_path / "iso", Iterated(alg))
    assert res.status == "ok", res.message
    assert iso.tobytes() == base.tobytes()
    res, me = run(ring("fmi2", a, b, c, d, fields={"interface": "model-exchange", "solver": "rk4"}),
                  tmp_path / "me", Iterated(alg))
    assert res.status == "ok", res.message
    assert np.max(np.abs(me[f"A.{OUT}"] - base[f"A.{OUT}"])) < 1e-12


def test_iterated_without_a_loop_is_gauss_seidel_bit_for_bit(tmp_path):
    """A chain (VanDerPol -> Feedthrough -> Feedthrough): no loop to iterate; the plain-Python pass makes
    the generated loop's calls with its values."""
    vdp, ft = str(REF / "fmi2" / "VanDerPol.fmu"), str(REF / "fmi2" / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": 2.0, "step": 0.01},
           "instances": {"v": {"fmu": vdp}, "f": {"fmu": ft}, "g": {"fmu": ft}},
           "connections": [{"from": "v.x0", "to": f"f.{IN}", "factor": 3.0},
                           {"from": f"f.{OUT}", "to": f"g.{IN}", "offset": 1.0}],
           "record": {"variables": ["v.x0", "v.x1", f"f.{OUT}", f"g.{OUT}"], "decimation": 3}}
    plan = cosim.resolve(cosim.parse(doc, "chain.toml"))
    _, gs = run(plan, tmp_path / "gs", GaussSeidel())
    res, it = run(plan, tmp_path / "it", Iterated())
    assert res.status == "ok" and res.summary["stepping"]["loops"] == []
    assert it.tobytes() == gs.tobytes()


def test_the_step_size_control_lands_on_the_output_grid_and_counts_its_steps(tmp_path):
    """Whatever steps it takes inside, the rows are at start + k * step and at the stop time exactly."""
    a, b, c, d = 2.0, 1.0, 0.8, -3.0
    ya, _ = solution(a, b, c, d)
    plan = ring("fmi2", a, b, c, d, stop=0.3, step=0.03)
    res, sig = run(plan, tmp_path / "ad", algorithms.make("adaptive", IterationSpec("newton"),
                                                          AdaptiveSpec(initial_step=0.007, coupling="iterated")))
    assert res.status == "ok", res.message
    assert list(sig["time"]) == [k * 0.03 for k in range(11)]
    st = res.summary["stepping"]
    assert st["accepted_steps"] >= 10 and st["rejected_steps"] == 0
    assert st["instance_steps"] == 2 * 3 * st["accepted_steps"]
    assert np.max(np.abs(sig[f"A.{OUT}"] - ya)) < 1e-12


def test_the_step_size_control_refuses_to_go_below_its_smallest_step(tmp_path):
    """Gauss-Seidel over the diverging ring: every step's estimate is far above the tolerance; at
    min_step the run ends with one line naming the step-size control and the time."""
    plan = ring("fmi2", 2.0, 1.0, 0.8, -3.0)
    res, _ = run(plan, tmp_path / "ad",
                 algorithms.make("adaptive", None, AdaptiveSpec(min_step=1e-4, coupling="gauss-seidel")))
    assert res.status == "failed"
    assert res.message.startswith("A: step-size control") or "step-size control" in res.message
    assert "min_step" in res.message and "\n" not in res.message


def _vdp_chain(version: str, fields: dict[str, Any] | None = None) -> cosim.Plan:
    """VanDerPol -> Feedthrough over 2 s, recorded every 0.1 s; ``fields`` added to the VanDerPol instance."""
    vdp, ft = str(REF / version / "VanDerPol.fmu"), str(REF / version / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": 2.0, "step": 0.1},
           "instances": {"v": {"fmu": vdp, **(fields or {})}, "f": {"fmu": ft}},
           "connections": [{"from": "v.x0", "to": f"f.{IN}"}],
           "record": {"variables": ["v.x0", "v.x1", f"f.{OUT}"]}}
    return cosim.resolve(cosim.parse(doc, "vdp.toml"))


def test_the_step_size_control_rolls_back_model_exchange_isolated_and_fmi3_instances(tmp_path):
    """VanDerPol through its Model Exchange interface, one RK4 step per macro step, under the step-size
    control (rtol = atol = 1e-8): the step doubling estimates RK4's error, so steps are rejected and rolled
    back (the FMU's state and the integrator restored); the rows meet CVODE at rtol 1e-11 to 1e-6; hosted
    in a child process it gives the in-process rows bit for bit; FMI 3.0 gives the FMI 2.0 rows within
    1e-9."""
    me = {"interface": "model-exchange", "solver": "rk4"}
    spec = AdaptiveSpec(rtol=1e-8, atol=1e-8, coupling="gauss-seidel")
    base_res, base = run(_vdp_chain("fmi2", me), tmp_path / "base", algorithms.make("adaptive", None, spec))
    assert base_res.status == "ok", base_res.message
    st = base_res.summary["stepping"]
    assert st["rejected_steps"] >= 1 and st["accepted_steps"] > 40
    _, ref = run(_vdp_chain("fmi2", {"solver": "cvode", "tolerance": 1e-11}), tmp_path / "ref", GaussSeidel())
    assert np.max(np.abs(base["v.x0"] - ref["v.x0"])) < 1e-6 and np.max(np.abs(base["v.x1"] - ref["v.x1"])) < 1e-6
    assert np.array_equal(base[f"f.{OUT}"], base["v.x0"])
    res, iso = run(_vdp_chain("fmi2", {**me, "isolate": True}), tmp_path / "iso",
                   algorithms.make("adaptive", None, spec))
    assert res.status == "ok", res.message
    assert iso.tobytes() == base.tobytes()
    res, f3 = run(_vdp_chain("fmi3", me), tmp_path / "f3", algorithms.make("adaptive", None, spec))
    assert res.status == "ok", res.message
    assert np.max(np.abs(f3["v.x0"] - base["v.x0"])) < 1e-9 and np.max(np.abs(f3["v.x1"] - base["v.x1"])) < 1e-9


@pytest.mark.parametrize("version, fields, key, why", [
    ("fmi3", {}, "inputs", "A (Feedthrough.fmu, co-simulation) does not"),
    ("fmi2", {"interface": "model-exchange", "solver": "rk4"}, "inputs", "A (Feedthrough.fmu, model-exchange) does not"),
    ("fmi2", {}, "jacobian", "A (Feedthrough.fmu, co-simulation) does not"),
    ("fmi3", {}, "jacobian", "A (Feedthrough.fmu, co-simulation) does not"),
])
def test_what_an_instance_cannot_give_is_refused_at_check(version, fields, key, why):
    """FMI 3.0 has no input derivatives, and a Model Exchange instance holds its inputs: the iterated
    coupling with linear inputs is refused naming the loop and the instance (it would run first order);
    Feedthrough declares no directional derivatives: Newton's directional Jacobian is refused alike."""
    from wmr_cosim.cosim.messages.errors import ScenarioError

    fmu = str(REF / version / "Feedthrough.fmu")
    table = {"inputs": "linear"} if key == "inputs" else {"jacobian": "directional"}
    doc = {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.01, "algorithm": "iterated",
                          "iteration": table},
           "instances": {"A": {"fmu": fmu, **fields}, "B": {"fmu": fmu}},
           "connections": [{"from": f"A.{OUT}", "to": f"B.{IN}"}, {"from": f"B.{OUT}", "to": f"A.{IN}",
                                                                  "factor": 0.5}]}
    with pytest.raises(ScenarioError) as err:
        cosim.resolve(cosim.parse(doc, "ring.toml"))
    assert err.value.field == f"experiment.iteration.{key}"
    assert "coupling loop A <-> B" in str(err.value) and why in str(err.value)
