"""The Jacobian of a Model Exchange FMU at a point (cosim/linearisation/jacobian.py) against analytic ones:
the Reference FMUs' VanDerPol (FMI 2.0 with directional derivatives, and by central differences; FMI 3.0
by central differences) at three states, Dahlquist's A = -k, and the C plant's A and B against the
Jacobian of the paper's (34)-(36) and (23) derived by hand here, at a wheel speed of the G1 run."""
from __future__ import annotations

import math

import numpy as np
import pytest

from wmr_cosim.api import Simulation
from wmr_cosim.cosim import Linearizer, Request
from wmr_cosim.cosim.linearisation.jacobian import CUBE_ROOT_EPS, fd_step

from reference_fmus import fmu as reference_fmu


def _me(name: str, path, stop: float = 5.0, **parameters) -> Simulation:
    return Simulation().instance(name, path, fields={"interface": "model-exchange"}, **parameters) \
        .experiment(start=0.0, stop=stop, step=0.01)


def _vdp_jacobian(x0: float, x1: float, mu: float) -> np.ndarray:
    """x0' = x1, x1' = mu (1 - x0^2) x1 - x0."""
    return np.array([[0.0, 1.0], [-2.0 * mu * x0 * x1 - 1.0, mu * (1.0 - x0 * x0)]])


STATES = [(2.0, 0.0), (-0.7, 1.3), (0.3, -2.4)]


@pytest.mark.parametrize("version,method,expect", [("fmi2", "directional", "directional derivatives"),
                                                   ("fmi2", "differences", "central differences"),
                                                   ("fmi3", "auto", "central differences")])
def test_van_der_pol_at_three_states_equals_its_analytic_jacobian(version, method, expect):
    path = reference_fmu(version, "VanDerPol")
    for x0, x1 in STATES:
        req = Request(at=0.5, outputs=["vdp.x0", "vdp.x1"], method=method, states={"vdp.x0": x0, "vdp.x1": x1})
        lin = Linearizer(_me("vdp", path, mu=1.5).check(), req).run()
        m = lin.model
        assert m.continuous and m.method == f"vdp: {expect}"
        assert m.states == ["vdp.x0", "vdp.x1"]
        np.testing.assert_allclose(m.A, _vdp_jacobian(x0, x1, 1.5), rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(m.C, np.eye(2), atol=1e-9)   # the outputs are the states
        assert m.B.shape == (2, 0) and m.D.shape == (2, 0)


def test_a_point_of_the_run_is_where_the_run_is():
    """Without states given, the point is the run's own state at --at (FMPy's solution there)."""
    from fmpy import simulate_fmu

    path = reference_fmu("fmi2", "VanDerPol")
    lin = Linearizer(_me("vdp", path).check(), Request(at=1.0, outputs=["vdp.x0", "vdp.x1"])).run()
    ref = simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=1.0, output_interval=0.01,
                       relative_tolerance=1e-8)
    x0, x1 = float(ref["x0"][-1]), float(ref["x1"][-1])
    np.testing.assert_allclose(lin.model.A, _vdp_jacobian(x0, x1, 1.0), rtol=1e-4, atol=1e-4)


def test_dahlquist_is_minus_k():
    path = reference_fmu("fmi2", "Dahlquist")
    for k in (1.0, 3.5):
        lin = _me("d", path, k=k).linearize(at=0.3, outputs=["d.x"])   # (the scripting API's way)
        np.testing.assert_allclose(lin.model.A, [[-k]], rtol=1e-8)


def test_the_difference_step_is_the_cube_root_of_eps_of_the_larger_of_value_and_nominal():
    assert fd_step(0.0, 1.0) == pytest.approx(CUBE_ROOT_EPS, rel=1e-12)
    assert fd_step(1000.0, 1.0) == pytest.approx(1000.0 * CUBE_ROOT_EPS, rel=1e-9)
    assert fd_step(1e-3, 50.0) == pytest.approx(50.0 * CUBE_ROOT_EPS, rel=1e-9)
    v = 0.1
    h = fd_step(v, 1.0)
    assert (v + h) - v == h   # exactly representable


# ---------------------------------------------------------------- the C plant against (34)-(36), (23)
def _plant_jacobian(p: dict[str, float], w1: float, w2: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """A and B of the states (alpha1, alpha2, w1, w2, xA, yA, beta) and inputs (u1, u2), by hand:
    M w' = u - C(w) w - F(w) (34) with M, C of (35) and F_i = a_{4+i} (2 - 2 e^{-cF w}) / (1 + e^{-cF w})
    = 2 a_{4+i} tanh(cF w / 2) (36); v = r (w1 + w2) / 2, beta' = r (w1 - w2) / (2 l1) from (23);
    xA' = v cos(beta), yA' = v sin(beta) (24)."""
    a1, a2, a3, a4 = p["inertia_a1"], p["inertia_a2"], p["inertia_a3"], p["coriolis_a4"]
    a5, a6, cF, r, l1 = p["roll_res_right"], p["roll_res_left"], p["slope_cF"], p["wheel_radius"], p["half_track"]
    M = np.array([[a1 + a2 + a3, a1 - a2], [a1 - a2, a1 + a2 + a3]])
    Minv = np.linalg.inv(M)
    # d(C(w) w)/dw with C(w) w = [2 a4 (w2 - w1) w2, -2 a4 (w2 - w1) w1]
    dCw = np.array([[-2 * a4 * w2, 2 * a4 * (2 * w2 - w1)], [-2 * a4 * (w2 - 2 * w1), -2 * a4 * w1]])

    def dF(a: float, w: float) -> float:   # d/dw of 2 a tanh(cF w / 2)
        return a * cF / math.cosh(cF * w / 2) ** 2
    dw = -Minv @ (dCw + np.diag([dF(a5, w1), dF(a6, w2)]))
    A = np.zeros((7, 7))
    A[0, 2] = A[1, 3] = 1.0
    A[2:4, 2:4] = dw
    v = r * (w1 + w2) / 2
    A[4, 2] = A[4, 3] = r / 2 * math.cos(beta)
    A[5, 2] = A[5, 3] = r / 2 * math.sin(beta)
    A[4, 6], A[5, 6] = -v * math.sin(beta), v * math.cos(beta)
    A[6, 2], A[6, 3] = r / (2 * l1), -r / (2 * l1)
    B = np.zeros((7, 2))
    B[2:4, :] = Minv
    return A, B


def test_the_c_plant_at_a_wheel_speed_of_g1_equals_the_hand_jacobian_of_34_to_36():
    # the wheel speeds and heading of the G1 learning run with the C plant (scenarios/g1_c_plant.toml) at
    # t = 10 s: 48.558 and 44.029 rpm, 66.740 deg; set as the point
    w1, w2, beta = 48.55819882632741 * math.pi / 30, 44.02932544416437 * math.pi / 30, math.radians(66.74018412473444)
    states = {"plant.state_omega_right": w1, "plant.state_omega_left": w2, "plant.state_heading": beta}
    sim = _me("plant", "WmrCPlant", torque_right=0.8, torque_left=0.7)
    plan = sim.check()
    params = {v.name: float(v.start) for v in plan.instances["plant"].model.variables.values()
              if v.causality == "parameter" and v.type == "Real"}
    req = Request(at=0.2, inputs=["plant.torque_right", "plant.torque_left"],
                  outputs=["plant.omega_right", "plant.omega_left"], states=states)
    m = Linearizer(plan, req).run().model
    assert m.method == "plant: central differences"   # the C plant gives no directional derivatives
    A, B = _plant_jacobian(params, w1, w2, beta)
    scale_A = np.abs(A).max()
    np.testing.assert_allclose(m.A, A, rtol=1e-6, atol=1e-6 * scale_A)
    np.testing.assert_allclose(m.B, B, rtol=1e-6, atol=1e-9)
    # outputs in rpm of states in rad/s: the unit conversion is in C
    np.testing.assert_allclose(m.C[:, 2:4], np.eye(2) * 60 / (2 * math.pi), rtol=1e-6)
    assert m.output_units == ["rpm", "rpm"] and m.input_units == ["N.m", "N.m"]
    assert m.state_units[2:4] == ["rad/s", "rad/s"]
