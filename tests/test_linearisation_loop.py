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
