"""Loops closed across FMUs, linearised (cosim/linearisation/interconnection.py, loop.py): lags and a
proportional controller (tests/c_fmus/lag.c) whose loop gains have margins in closed form; the closed
loop's eigenvalues through the break against the system linearised as a whole; algebraic loops solved in
the interconnection; the same loop in co-simulation, realised from pulse responses."""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

from wmr_cosim.api import Simulation
from wmr_cosim.cosim import CosimError, LinearModel, Linearizer, Request
from wmr_cosim.cosim.linearisation.interconnection import Link, close

from linear_fmus import build_lag

ME = {"interface": "model-exchange"}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, str]:
    out = tmp_path_factory.mktemp("linear-fmus")
    return {"lag": str(build_lag(out)), "gain": str(build_lag(out, gain=True)),
            "lag_dd": str(build_lag(out, directional=True)),
            "gain_dd": str(build_lag(out, gain=True, directional=True))}


def _chain(fmus: dict[str, str], n_lags: int, K: float, tau: float, k: float = 1.0, fields=ME, lag: str = "lag",
           gain: str = "gain") -> Simulation:
    """n lags in series, the last one's output into a proportional controller y = -K u, its output into the
    first lag: the loop gain (negative feedback) is L(s) = K k^n / (tau s + 1)^n."""
    sim = Simulation().experiment(start=0.0, stop=2.0, step=0.01)
    for i in range(n_lags):
        sim.instance(f"lag{i + 1}", fmus[lag], fields=fields, k=k, tau=tau, x0=0.1 * (i + 1))
    sim.instance("ctrl", fmus[gain], fields=fields, kp=-K)
    for i in range(1, n_lags):
        sim.connect(f"lag{i}.y", f"lag{i + 1}.u")
    sim.connect(f"lag{n_lags}.y", "ctrl.u")
    sim.connect("ctrl.y", "lag1.u")
    return sim


@pytest.mark.parametrize("lag,gain", [("lag", "gain"), ("lag_dd", "gain_dd")])
def test_three_lags_and_a_proportional_controller_have_their_closed_form_margins(fmus, lag, gain):
    """L = K / (tau s + 1)^3: the phase crosses -180 deg at w tau = sqrt(3), where |L| = K / 8, so the gain
    margin is 8 / K; |L| = 1 at w tau = sqrt(K^(2/3) - 1), so the phase margin is 180 - 3 atan(that) deg."""
    K, tau = 4.0, 0.5
    lin = Linearizer(_chain(fmus, 3, K, tau, lag=lag, gain=gain).check(),
                     Request(at=0.5, breaks=("ctrl.y", "lag1.u"))).run()
    loop = lin.loop
    assert loop is not None and lin.model.continuous
    assert loop.gain_margin == pytest.approx(8.0 / K, rel=1e-3)
    assert loop.phase_crossover == pytest.approx(math.sqrt(3.0) / tau, rel=1e-3)
    wc = math.sqrt(K ** (2.0 / 3.0) - 1.0)
    assert loop.phase_margin == pytest.approx(180.0 - 3.0 * math.degrees(math.atan(wc)), rel=1e-3)
    assert loop.gain_crossover == pytest.approx(wc / tau, rel=1e-3)
    # the loop through the break closed again: the eigenvalues of the system linearised as a whole, and
    # those of (tau s + 1)^3 + K = 0: s = (-1 + K^(1/3) e^(i pi (2 m + 1) / 3)) / tau
    assert lin.whole_eigenvalues is not None
    roots = np.array([(-1.0 + K ** (1 / 3) * np.exp(1j * math.pi * (2 * m + 1) / 3)) / tau for m in range(3)])
    np.testing.assert_allclose(np.sort_complex(loop.closed_eigenvalues), np.sort_complex(lin.whole_eigenvalues),
                               rtol=1e-9)
    np.testing.assert_allclose(np.sort_complex(loop.closed_eigenvalues), np.sort_complex(roots), rtol=1e-6)
    assert loop.closed_stable == (K < 8.0)


def test_a_first_order_plant_under_proportional_control(fmus):
    """L = K k / (tau s + 1): no phase crossover (an infinite gain margin); |L| = 1 at
    w tau = sqrt((K k)^2 - 1), the phase margin 180 - atan(that) deg."""
    K, k, tau = 3.0, 2.0, 0.2
    lin = Linearizer(_chain(fmus, 1, K, tau, k=k).check(), Request(at=0.0, breaks=("ctrl.y", "lag1.u"))).run()
    loop = lin.loop
    assert math.isinf(loop.gain_margin)
    wc = math.sqrt((K * k) ** 2 - 1.0)
    assert loop.phase_margin == pytest.approx(180.0 - math.degrees(math.atan(wc)), rel=1e-3)
    assert loop.gain_crossover == pytest.approx(wc / tau, rel=1e-3)
    np.testing.assert_allclose(loop.closed_eigenvalues, [-(1.0 + K * k) / tau], rtol=1e-6)
    # G from the injection to the return is -K k / (tau s + 1): the broken model as python-control sees it
    G = loop.gain.statespace()
    assert control.dcgain(G) == pytest.approx(-K * k, rel=1e-6)
    # the loop closed, a disturbance added at the controller's input (through its direct feedthrough):
    # lag.y = -K k / (tau s + 1 + K k) of it
    m = Linearizer(_chain(fmus, 1, K, tau, k=k).check(), Request(at=0.0, inputs=["ctrl.u"], outputs=["lag1.y"])).run()
    assert control.dcgain(m.model.statespace()) == pytest.approx(-K * k / (1.0 + K * k), rel=1e-6)


def test_the_interconnection_solves_an_algebraic_loop():
    """Two memoryless blocks in a loop, y1 = a u1 + w, y2 = b y1 into u1: y1 = w / (1 - a b)."""
    b1 = LinearModel(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), [[2.0, 1.0]], [], ["p.u", "p.w"], ["p.y"])
    b2 = LinearModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[0.25]], [], ["q.u"], ["q.y"])
    m = close([b1, b2], [Link("p.y", "q.u"), Link("q.y", "p.u")], ["p.w"], ["p.y"])
    assert m.D[0, 0] == pytest.approx(1.0 / (1.0 - 2.0 * 0.25))
    b2.D[0, 0] = 0.5   # a loop gain of exactly 1: no unique solution
    with pytest.raises(CosimError, match="algebraic loop"):
        close([b1, b2], [Link("p.y", "q.u"), Link("q.y", "p.u")], ["p.w"], ["p.y"])


def test_a_connection_factor_and_an_open_input_on_a_connected_one(fmus):
    """lag1 -> lag2 with a factor 3: from lag1.u to lag2.y, 3 / ((s + 1)(s + 1)); an input named open that a
    connection drives (lag2.u) gets the injection added: 1 / (s + 1) from it."""
    sim = Simulation().experiment(start=0.0, stop=1.0, step=0.01) \
        .instance("lag1", fmus["lag"], fields=ME).instance("lag2", fmus["lag"], fields=ME) \
        .connect("lag1.y", "lag2.u", factor=3.0)
    m = Linearizer(sim.check(), Request(at=0.0, inputs=["lag1.u", "lag2.u"], outputs=["lag2.y"])).run().model
    dc = control.dcgain(m.statespace())
    np.testing.assert_allclose(np.ravel(dc), [3.0, 1.0], rtol=1e-6)


def _gauss_seidel_chain_pulse(K: float, tau: float, h: float, n: int) -> np.ndarray:
    """The pulse response h[1..n] from lag1.u to ctrl.y of the chain as Gauss-Seidel steps it in the plan's
    order (lag1, lag2, lag3, ctrl): each lag advanced by its exact solution x <- a x + (1 - a) u with
    a = exp(-h / tau), its input held at its predecessor's output at the end of the same step; the
    controller's output -K x3 at the end of the step."""
    a = math.exp(-h / tau)
    x = [0.0, 0.0, 0.0]
    out = []
    for k in range(n):
        u = 1.0 if k == 0 else 0.0
        for i in range(3):
            x[i] = a * x[i] + (1.0 - a) * (u if i == 0 else x[i - 1])
        out.append(-K * x[2])
    return np.array(out)


def test_the_same_loop_in_co_simulation_realised_from_pulse_responses(fmus):
    """Three lags stepped exactly (the lag's co-simulation step is its exact solution) and the controller:
    the injection-to-return model by rollback has the pulse response of the chain as the master steps it,
    and the closed loop through the break agrees with the system realised as a whole."""
    K, tau, h = 2.0, 0.5, 0.01
    sim = _chain(fmus, 3, K, tau, fields={}).experiment(step=h, stop=4.0)
    lin = Linearizer(sim.check(), Request(at=0.5, breaks=("ctrl.y", "lag1.u"), steps=150)).run()
    G = lin.loop.gain
    assert G.dt == h and not lin.model.continuous and len(G.states) == 3
    expected = _gauss_seidel_chain_pulse(K, tau, h, 100)
    ours = np.array([(G.C @ np.linalg.matrix_power(G.A, k) @ G.B)[0, 0] for k in range(100)])
    np.testing.assert_allclose(ours, expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())
    np.testing.assert_allclose(np.sort_complex(lin.loop.closed_eigenvalues), np.sort_complex(lin.whole_eigenvalues),
                               rtol=1e-6)
    assert lin.loop.closed_stable


def test_going_back_to_a_point_of_a_closed_loop_repeats_it_bit_for_bit(fmus):
    """The first step after the point takes its inputs from the outputs saved with it (the row), whatever
    the run did in between."""
    from wmr_cosim.cosim import Execution

    ex = Execution(_chain(fmus, 2, 1.5, 0.3, fields={}).check(), None)
    ex.initialize()
    try:
        ex.step_to(0.2)
        point = ex.save_point()
        ex.step(30)
        first = [ex.get(r) for r in ("lag1.y", "lag2.y", "ctrl.y")]
        ex.restore_point(point)
        ex.step(30)
        assert [ex.get(r) for r in ("lag1.y", "lag2.y", "ctrl.y")] == first
        ex.free_point(point)
    finally:
        ex.close()


def test_a_connection_that_is_not_real_to_real_is_held_and_said(fmus):
    """A Real -> Boolean connection (a threshold) has no derivative to take: the model says it held it."""
    from reference_fmus import fmu as reference_fmu

    sim = Simulation().experiment(start=0.0, stop=1.0, step=0.01) \
        .instance("lag", fmus["lag"], fields=ME).instance("ft", reference_fmu("fmi2", "Feedthrough"), fields=ME) \
        .connect("lag.y", "ft.Boolean_input", convert=True, threshold=0.5) \
        .connect("ft.Float64_continuous_output", "lag.u")
    lin = Linearizer(sim.check(), Request(at=0.0, inputs=["ft.Float64_continuous_input"], outputs=["lag.y"])).run()
    assert lin.notes == ["lag.y -> ft.Boolean_input (Real to Boolean) is not a real-to-real connection: held as it "
                         "is at the point, not linearised"]
    assert control.dcgain(lin.model.statespace()) == pytest.approx(1.0, rel=1e-6)   # ft passes u through to lag


# ---------------------------------------------------------------- every crossover, the lower gain margin, the poles
def _model(sys, name: str = "G") -> LinearModel:
    """A python-control system as a one-input, one-output LinearModel."""
    n = sys.nstates
    return LinearModel(sys.A, sys.B, sys.C, sys.D, [f"x{i}" for i in range(n)], ["w"], ["r"], dt=float(sys.dt or 0.0))


def test_every_crossover_and_the_lower_gain_margin_of_a_conditionally_stable_loop():
    """L = K / ((s - 1)(0.1 s + 1)^2): an unstable pole that the feedback stabilises for 1 < K < 16.2 (the
    characteristic polynomial 0.01 s^3 + 0.19 s^2 + 0.8 s + K - 1, Routh). L crosses the negative real axis
    at w = 0 (L = -K: the lower gain margin 1 / K) and at w = sqrt(80) (L = -K / 16.2: the upper 16.2 / K).
    The same loop discretised (zero-order hold, 1 ms) keeps L(z = 1) = -K: the lower margin at w = 0 too."""
    from wmr_cosim.cosim.linearisation.loop import analyse

    K = 4.0
    s = control.tf("s")
    G = -control.ss(K / ((s - 1) * (0.1 * s + 1) ** 2))
    for sysm in (G, control.c2d(G, 1e-3, "zoh")):
        loop = analyse(_model(sysm), "a.y", "b.u")
        ws = [w for w, _ in loop.phase_crossovers]
        gms = [g for _, g in loop.phase_crossovers]
        assert len(ws) == 2 and ws[0] == 0.0, loop.phase_crossovers
        assert loop.lower_gain_margin == pytest.approx(1.0 / K, rel=1e-3) == gms[0]
        # the upper one: exact in continuous time; the hold's half-step lag moves it by O(w h) in discrete time
        assert loop.upper_gain_margin == pytest.approx(16.2 / K, rel=1e-3 if sysm.dt == 0 else 3e-2) == gms[1]
        assert ws[1] == pytest.approx(math.sqrt(80.0), rel=1e-3 if sysm.dt == 0 else 3e-2)
        assert loop.closed_stable
        summary = loop.summary()
        assert [c["kind"] for c in summary["phase_crossovers"]] == ["lower", "upper"]
        assert summary["lower_gain_margin"] == pytest.approx(1.0 / K, rel=1e-3)
        # the unstable open-loop pole, named: s = 1 (z = exp(1e-3))
        assert np.allclose(loop.boundary_poles, [1.0 if sysm.dt == 0 else math.exp(1e-3)], rtol=1e-9)
        assert summary["open_loop_poles_on_or_outside"] == [[pytest.approx(loop.boundary_poles[0].real), 0.0]]


def test_three_lags_list_their_one_phase_crossover_and_no_lower_margin(fmus):
    K, tau = 4.0, 0.5
    loop = Linearizer(_chain(fmus, 3, K, tau).check(), Request(at=0.5, breaks=("ctrl.y", "lag1.u"))).run().loop
    assert [w for w, _ in loop.phase_crossovers] == [pytest.approx(math.sqrt(3.0) / tau, rel=1e-3)]
    assert loop.upper_gain_margin == pytest.approx(8.0 / K, rel=1e-3) and loop.lower_gain_margin == 0.0
    wc = math.sqrt(K ** (2.0 / 3.0) - 1.0)
    assert loop.gain_crossovers == [(pytest.approx(wc / tau, rel=1e-3),
                                     pytest.approx(180.0 - 3.0 * math.degrees(math.atan(wc)), rel=1e-3))]
    assert loop.boundary_poles.size == 0   # three lags at -1 / tau: nothing near the boundary


def _integrator_chain(fmus, fields=ME) -> Simulation:
    """lag1 made an integrator to 1e-9 (x' = (k u - x) / tau with k = tau = 1e9: x' = u - 1e-9 x), two lags
    of 0.5 s and the controller y = -0.5 u: L = 0.5 / (s (0.5 s + 1)^2), stable closed."""
    sim = _chain(fmus, 3, 0.5, 0.5, fields=fields).experiment(stop=4.0)
    return sim.instance("lag1", fmus["lag"], fields=fields, k=1e9, tau=1e9, x0=0.1)


@pytest.mark.parametrize("fields", [ME, {}], ids=["continuous", "realised"])
def test_an_integrator_in_the_loop_is_a_pole_on_the_boundary_and_said(fmus, fields):
    """The continuous model has the integrator at s = -1e-9 (within 1e-6 of the largest pole, 2 /s, of the
    imaginary axis); the realisation from responses (co-simulation) at z = exp(-1e-11), within its 1e-3."""
    from wmr_cosim.runs.linear_model import report, summary

    lin = Linearizer(_integrator_chain(fmus, fields).check(),
                     Request(at=0.5, breaks=("ctrl.y", "lag1.u"), steps=None if fields == ME else 150)).run()
    loop = lin.loop
    assert loop.closed_stable and loop.boundary_poles.size == 1
    if fields == ME:
        assert loop.boundary_poles[0] == pytest.approx(-1e-9, abs=1e-12)
        assert loop.pole_tolerance == pytest.approx(2e-6, rel=1e-6)
    else:
        assert loop.boundary_poles[0] == pytest.approx(1.0, abs=1e-6)
        assert loop.pole_tolerance >= 1e-3
    warning = [line for line in report(lin) if "warning: open-loop poles" in line]
    assert len(warning) == 1 and ("right half plane" if fields == ME else "unit circle") in warning[0]
    assert "(on it, within the accuracy)" in warning[0] and "outside)" not in warning[0]
    assert len(summary(lin)["loop"]["open_loop_poles_on_or_outside"]) == 1


# ---------------------------------------------------------------- the continuous loop beside the co-simulated one
def _pulse(G: LinearModel, n: int) -> np.ndarray:
    """h[1..n] = C A^(k-1) B of a discrete-time one-input, one-output model."""
    out, x = [], G.B.copy()
    for _ in range(n):
        out.append((G.C @ x)[0, 0])
        x = G.A @ x
    return np.array(out)


@pytest.mark.parametrize("algorithm,delay", [("gauss-seidel", -0.5), ("jacobi", 2.5)])
def test_the_co_simulated_loop_costs_the_phase_of_its_delays(fmus, algorithm, delay):
    """Three lags (tau = 0.5 s) and a controller (K = 4): at a small step H the co-simulated loop's phase
    margin is the continuous loop's less w_c H d rad, where d counts the steps of delay the coupling adds
    at the gain crossover w_c: H / 2 for each lag's hold, H for the memoryless controller whose input Jacobi
    reads at t_k; Gauss-Seidel in the order lag1, lag2, lag3, ctrl reads three of the four connections at
    t_k+1 (an advance of H each): d = 1.5 + 1 = 2.5 (Jacobi), 1.5 - 3 + 1 = -0.5 (Gauss-Seidel: a lead).
    To 1 % at H = 1 ms (the rest is O(H^2)); the largest step within the budget has the budget's cost."""
    from wmr_cosim.cosim.linearisation.cosimulated import phase_cost

    K, tau, h = 4.0, 0.5, 1e-3
    sim = _chain(fmus, 3, K, tau).experiment(step=h, stop=4.0, algorithm=algorithm)
    lin = Linearizer(sim.check(), Request(at=0.5, breaks=("ctrl.y", "lag1.u"), phase_budget=2.0)).run()
    c = lin.coupling
    assert c is not None and c.algorithm == algorithm and c.step == h and c.budget == 2.0
    wc = math.sqrt(K ** (2.0 / 3.0) - 1.0) / tau
    assert c.continuous.gain_crossover == pytest.approx(wc, rel=1e-6)
    assert c.phase_cost == pytest.approx(math.degrees(wc * h * delay), rel=1e-2)
    assert c.cosimulated.phase_margin == pytest.approx(c.continuous.phase_margin - c.phase_cost, rel=1e-12)
    assert c.cosimulated.gain.dt == h and c.cosimulated.closed_stable
    assert c.cosimulated.gain.inputs == ["lag1.u"] and c.cosimulated.gain.outputs == ["ctrl.y"]
    # the largest step within 2 deg: the cost there is the budget (the bisection's bracket: 0.1 % of the step)
    assert c.limit == "the budget"
    assert phase_cost(c.continuous, c.loop_at(c.largest_step)) == pytest.approx(2.0, rel=1e-2)
    assert phase_cost(c.continuous, c.loop_at(c.largest_step * 1.01)) > 2.0
    if delay > 0:   # a loss growing as w_c H d: the step ~ budget / (w_c d), to the O(H^2) left out
        assert c.largest_step == pytest.approx(math.radians(2.0) / (wc * delay), rel=0.05)


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_the_co_simulated_loop_is_the_one_rollback_measures(fmus, algorithm):
    """The loop the derivation gives at the step (zero-order holds, the algorithm's exchange) has the pulse
    response of the same loop in co-simulation realised by rollback: the lags' co-simulation step is their
    exact solution under a held input, so they agree to the realisation's accuracy (1e-6); and the Model
    Exchange instances stepped by the master's integrator (CVODE) to its tolerance."""
    K, tau, h = 2.0, 0.5, 0.01
    cont = Linearizer(_chain(fmus, 3, K, tau).experiment(step=h, stop=4.0, algorithm=algorithm).check(),
                      Request(at=0.5, breaks=("ctrl.y", "lag1.u"))).run()
    derived = _pulse(cont.coupling.cosimulated.gain, 100)
    # (realised at the derived loop's order: Jacobi's, the lags' and the controller's held input, is 4, more
    # than the singular values' cut keeps of a one-step delay)
    order = len(cont.coupling.cosimulated.gain.states)
    cosim = Linearizer(_chain(fmus, 3, K, tau, fields={}).experiment(step=h, stop=4.0, algorithm=algorithm).check(),
                       Request(at=0.5, breaks=("ctrl.y", "lag1.u"), steps=150, order=order)).run()
    measured = _pulse(cosim.loop.gain, 100)
    np.testing.assert_allclose(derived, measured, rtol=1e-6, atol=1e-8 * np.abs(derived).max())
    if algorithm == "gauss-seidel":   # the closed form of the chain as Gauss-Seidel steps it (above)
        np.testing.assert_allclose(derived, _gauss_seidel_chain_pulse(K, tau, h, 100), rtol=1e-9,
                                   atol=1e-12)
    # the margins of the two agree as well
    assert cont.coupling.cosimulated.phase_margin == pytest.approx(cosim.loop.phase_margin, rel=1e-4)
    assert cont.coupling.cosimulated.upper_gain_margin == pytest.approx(cosim.loop.upper_gain_margin, rel=1e-4)
    # rollback of the Model Exchange loop itself (CVODE between the points, at a tolerance of 1e-10; the
    # pulse 1e-2 relative: the difference of two integrations is the pulse response to ~1e-8 / 1e-2)
    tight = {**ME, "tolerance": 1e-10}
    me = Linearizer(_chain(fmus, 3, K, tau, fields=tight).experiment(step=h, stop=4.0, algorithm=algorithm).check(),
                    Request(at=0.5, breaks=("ctrl.y", "lag1.u"), steps=150, discrete=True, pulse=1e-2,
                            order=order)).run()
    np.testing.assert_allclose(derived, _pulse(me.loop.gain, 100), rtol=1e-5, atol=1e-6 * np.abs(derived).max())


def test_no_co_simulated_loop_for_an_algorithm_it_is_not_derived_for(fmus):
    sim = _chain(fmus, 3, 2.0, 0.5).experiment(algorithm="iterated")
    lin = Linearizer(sim.check(), Request(at=0.5, breaks=("ctrl.y", "lag1.u"))).run()
    assert lin.coupling is None
    assert any("the co-simulated loop is derived for one pass per step" in n for n in lin.notes)

def test_a_realisations_options_are_refused_for_a_continuous_model_and_checked_for_one(fmus):
    """steps, order and pulse belong to a realisation from responses: given for a model of Model Exchange
    FMUs they would be ignored, so they are refused (as the command's --steps, --order, --pulse); for a
    realisation, a number of steps that is not whole is refused before the run."""
    sim = Simulation().experiment(start=0.0, stop=1.0, step=0.01).instance("lag1", fmus["lag"], fields=ME)
    for given, option in ((dict(steps=20), "--steps"), (dict(order=1), "--order"), (dict(pulse=0.1), "--pulse")):
        with pytest.raises(CosimError, match=f"{option}: .* a realisation from pulse responses takes it"):
            Linearizer(sim.check(), Request(at=0.1, inputs=["lag1.u"], outputs=["lag1.y"], **given)).check()
    with pytest.raises(CosimError, match="--steps: 20.5: the responses need a whole number"):
        Linearizer(sim.check(), Request(at=0.1, inputs=["lag1.u"], outputs=["lag1.y"], discrete=True,
                                        steps=20.5)).check()
    Linearizer(sim.check(), Request(at=0.1, inputs=["lag1.u"], outputs=["lag1.y"], discrete=True, steps=20,
                                    order=1, pulse=0.1)).check()
