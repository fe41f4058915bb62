"""The plant against the equations (34)-(36), (23)-(24): M, C, F by hand, RK4's order, steady state."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from wmr_cosim.components import paper
from wmr_cosim.components.friction import friction
from wmr_cosim.components.plant import Plant, mass_matrix, mass_matrix_inverse

A = paper.table1()["a"]
CF = paper.table1()["cF"]


def test_mass_matrix_by_hand():
    # (35): M = [[a1+a2+a3, a1-a2], [a1-a2, a1+a2+a3]] with Table 1's a1..a3
    m11, m12 = mass_matrix(0.0691, 0.0511, 0.0291)
    assert m11 == pytest.approx(0.1493, abs=1e-12)
    assert m12 == pytest.approx(0.0180, abs=1e-12)
    i11, i12 = mass_matrix_inverse(0.0691, 0.0511, 0.0291)
    M = np.array([[m11, m12], [m12, m11]])
    assert np.allclose(np.array([[i11, i12], [i12, i11]]) @ M, np.eye(2), atol=1e-12)


def test_friction_by_hand():
    # (36) printed form at a chosen point: F = a5 (2 - 2 e^{-cF w}) / (1 + e^{-cF w})
    w = 4.848
    e = math.exp(-CF * w)
    by_hand = A[4] * (2 - 2 * e) / (1 + e)
    assert friction(A[4], CF, w) == pytest.approx(by_hand, rel=1e-13)
    assert friction(A[4], CF, w, "printed") == pytest.approx(by_hand, rel=1e-13)
    assert friction(A[4], CF, -w) == pytest.approx(-by_hand, rel=1e-13)  # odd
    assert friction(A[4], CF, 1e9) == pytest.approx(2 * A[4])           # saturates at 2 a5


def test_derivatives_match_maggi_equations_by_hand():
    """(34): M alpha_ddot = u - C(alpha_dot) alpha_dot - F - dF, evaluated by hand with numpy."""
    pl = Plant()
    x = [0.3, -0.2, 3.0, 5.0, 1.0, 2.0, 0.7]
    u1, u2, t1, t2 = 4.0, 3.5, 0.1, -0.2
    d = pl.derivatives(0.0, x, u1, u2, t1, t2)
    a1, a2, a3, a4, a5, a6 = A
    M = np.array([[a1 + a2 + a3, a1 - a2], [a1 - a2, a1 + a2 + a3]])
    w = np.array([3.0, 5.0])
    C = np.array([[0, 2 * a4 * (w[1] - w[0])], [-2 * a4 * (w[1] - w[0]), 0]])
    F = np.array([a5 * (2 - 2 * math.exp(-CF * w[0])) / (1 + math.exp(-CF * w[0])),
                  a6 * (2 - 2 * math.exp(-CF * w[1])) / (1 + math.exp(-CF * w[1]))])
    acc = np.linalg.solve(M, np.array([u1, u2]) - C @ w - F - np.array([t1, t2]))
    assert d[0:2] == [3.0, 5.0]
    assert np.allclose(d[2:4], acc, rtol=1e-13)
    # (23)-(24): v_A = r (w1 + w2)/2, beta_dot = r (w1 - w2) / (2 l1)
    r, l1 = paper.WHEEL_RADIUS_M, paper.HALF_AXLE_M
    v = r * 8.0 / 2
    assert d[4] == pytest.approx(v * math.cos(0.7), rel=1e-14)
    assert d[5] == pytest.approx(v * math.sin(0.7), rel=1e-14)
    assert d[6] == pytest.approx(r * (3.0 - 5.0) / (2 * l1), rel=1e-14)


def _rk4_error(substeps: int) -> float:
    pl = Plant(substeps=substeps)
    h = 0.05
    def u(t):
        return 4.0 + math.sin(t), 3.0 - 0.5 * math.cos(t)
    # reference: the same ODE with the torques held per step, integrated very accurately
    x = list(pl.x)
    ref = np.array(x)
    for k in range(40):
        t = k * h
        u1, u2 = u(t)
        pl.step(t, h, u1, u2)
        sol = solve_ivp(lambda tt, xx, u1=u1, u2=u2: pl.derivatives(tt, list(xx), u1, u2), (t, t + h), ref,
                        method="DOP853", rtol=1e-13, atol=1e-13)
        ref = sol.y[:, -1]
    return float(np.max(np.abs(np.array(pl.x) - ref)))


def test_rk4_is_fourth_order():
    e1, e2 = _rk4_error(1), _rk4_error(2)
    # halving the substep divides the error by 2^4 = 16 for a 4th-order method
    assert 10.0 < e1 / e2 < 24.0, (e1, e2)


def test_steady_wheel_speed_under_constant_torque():
    """Equal constant torques on both wheels: C(alpha_dot) alpha_dot = 0 and the speed settles where u = F(w)."""
    U = 3.0
    pl = Plant()
    h = 0.002
    for k in range(int(30 / h)):
        out = pl.step(k * h, h, U, U)
    w_expected = 2.0 / CF * math.atanh(U / (2 * A[4]))  # u = 2 a5 tanh(cF w / 2)
    assert out[2] == pytest.approx(w_expected, rel=1e-6)
    assert out[3] == pytest.approx(w_expected, rel=1e-6)
    # a straight line along the x axis at v = r w
    assert out[6] == 0.0 and out[5] == 0.0
    assert out[4] > 0.0


def test_turning_sense_wheel1_is_right_wheel():
    pl = Plant()
    for k in range(500):
        out = pl.step(k * 0.002, 0.002, 5.0, 4.0)  # right wheel faster
    assert out[6] > 0.0  # counter-clockwise
    assert out[5] > 0.0


def test_foam_switches_on_at_time_with_ramp():
    da = 0.4
    pl = Plant(foam_on_time=True, foam_t_on=8.38, foam_da1=da, foam_da2=da, foam_ramp=0.1)
    h = 0.002
    levels, dfs = {}, {}
    for k in range(int(9.0 / h)):
        out = pl.step(k * h, h, 4.0, 4.0)
        levels[round((k + 1) * h, 3)] = out[9]
        dfs[round((k + 1) * h, 3)] = (out[7], out[2])
    assert levels[8.378] == 0.0 and levels[8.38] == 0.0
    assert levels[8.43] == pytest.approx(0.5, abs=1e-9)
    assert levels[8.48] == 1.0 and levels[8.9] == 1.0
    df, w = dfs[8.9]
    assert df == pytest.approx(da * 2 * math.tanh(CF * w / 2), rel=1e-14)  # the shape of (36)


def test_foam_raises_the_cruise_torque():
    """At the cruise wheel speed v*/r, raising a5, a6 by 0.4 N.m raises the friction torque by about 0.4 N.m."""
    w = paper.table1()["v_star"] / paper.WHEEL_RADIUS_M
    rise = friction(A[4] + 0.4, CF, w) - friction(A[4], CF, w)
    assert rise == pytest.approx(0.4, rel=0.01)


def test_foam_switches_on_at_region_entry():
    pl = Plant(foam_on_region=True, foam_x_min=0.5, foam_x_max=10, foam_y_min=-1, foam_y_max=1,
               foam_da1=0.4, foam_da2=0.4, foam_ramp=0.0)
    h = 0.002
    t_entry = None
    for k in range(int(20 / h)):
        out = pl.step(k * h, h, 4.3, 4.3)
        if t_entry is None and out[4] >= 0.5:
            t_entry = (k + 1) * h
        if out[9] > 0:
            t_on = (k + 1) * h
            break
    assert t_entry is not None
    # detected at the communication point where A is first inside, applied from the next step
    assert pl.t_foam == pytest.approx(t_entry, abs=1e-12)
    assert t_on == pytest.approx(t_entry + h, abs=1e-12)
    assert pl.region_hit


@pytest.mark.parametrize("x0, y0, inside", [(0.5, -1.0, True), (2.0, 1.0, True), (1.0, 0.0, True),
                                          (0.5 - 1e-12, 0.0, False), (2.0 + 1e-12, 0.0, False),
                                          (1.0, -1.0 - 1e-12, False), (1.0, 1.0 + 1e-12, False)])
def test_the_foam_rectangle_includes_its_edges(x0, y0, inside):
    """A robot starting on the rectangle's edge (or corner) is on the foam from t = 0; just outside, not."""
    pl = Plant(x0=x0, y0=y0, foam_on_region=True, foam_x_min=0.5, foam_x_max=2.0, foam_y_min=-1.0, foam_y_max=1.0,
               foam_da1=0.4, foam_da2=0.4)
    assert pl.region_hit is inside
    assert pl.t_foam == (0.0 if inside else math.inf)


def test_no_foam_when_region_never_entered():
    pl = Plant(foam_on_region=True, foam_x_min=5, foam_x_max=6, foam_y_min=5, foam_y_max=6, foam_da1=1, foam_da2=1)
    for k in range(1000):
        out = pl.step(k * 0.002, 0.002, 4.3, 4.3)
    assert out[9] == 0.0 and out[7] == 0.0


def test_external_disturbance_acts_like_delta_F():
    a = Plant()
    b = Plant(foam_on_time=True, foam_t_on=0.0, foam_ramp=0.0, foam_da1=0.3, foam_da2=0.3)
    h = 0.002
    for k in range(200):
        out_b = b.step(k * h, h, 4.0, 4.0)
        # the same torque as an external input, held per step (approximately equal: dF depends on w)
        tau = 0.3 * 2 * math.tanh(CF * a.x[2] / 2)
        out_a = a.step(k * h, h, 4.0, 4.0, tau, tau)
    # the same sense and size (the held torque lags the speed-dependent one by up to a step)
    assert out_a[2] == pytest.approx(out_b[2], rel=2e-4)
    assert out_a[7] == pytest.approx(tau)


def test_state_round_trip_is_exact():
    a = Plant(foam_on_region=True, foam_x_min=0.1, foam_x_max=1, foam_y_min=-1, foam_y_max=1, foam_da1=0.4, foam_da2=0.2)
    h = 0.002
    for k in range(300):
        a.step(k * h, h, 4.0, 3.9)
    s = a.get_state()
    outs = [a.step(k * h, h, 4.2, 3.7) for k in range(300, 900)]
    a.set_state(s)
    assert [a.step(k * h, h, 4.2, 3.7) for k in range(300, 900)] == outs


def test_bump_at_the_foam_edge_adds_to_a5_a6_for_its_duration():
    """The bump raises a5, a6 by foam_bump in [t_F, t_F + foam_bump_time): the derivative then equals that
    of a plant with a5, a6 raised by the level's da plus the bump, and dF reports it; afterwards it is gone."""
    kw = dict(foam_on_time=True, foam_t_on=1.0, foam_da1=0.4, foam_da2=0.3, foam_ramp=0.0)
    x = [0.0, 0.0, 9.0, 8.0, 0.0, 0.0, 0.0]
    for bump in (2.0, 0.5):
        pl = Plant(foam_bump=bump, foam_bump_time=0.2, **kw)
        for t, extra in ((0.99, None), (1.0, bump), (1.19, bump), (1.2, 0.0)):
            got = pl.derivatives(t, x, 4.0, 4.0)
            if extra is None:
                ref = Plant().derivatives(t, x, 4.0, 4.0)
            else:
                ref = Plant(a5=A[4] + 0.4 + extra, a6=A[5] + 0.3 + extra).derivatives(t, x, 4.0, 4.0)
            assert got == pytest.approx(ref, rel=1e-13, abs=1e-13), (bump, t)
    pl = Plant(foam_bump=2.0, foam_bump_time=0.2, **kw)
    h = 0.002
    off = Plant(**kw)
    for k in range(int(1.6 / h)):
        a = pl.step(k * h, h, 4.0, 4.0)
        b = off.step(k * h, h, 4.0, 4.0)
        t1 = (k + 1) * h
        if 1.0 + h < t1 < 1.2 - h:   # dF carries the bump during it
            assert a[7] == pytest.approx(2.0 * (0.4 + 2.0) * math.tanh(CF * a[2] / 2), rel=1e-12)
        elif t1 < 1.0:
            assert a == b                # identical before the foam
    assert a[2] < b[2]                   # the bump has slowed the wheels for good
    with pytest.raises(ValueError, match="foam_bump"):
        Plant(foam_bump=-1.0)


def test_no_bump_is_bit_identical():
    kw = dict(foam_on_time=True, foam_t_on=0.5, foam_da1=0.4, foam_da2=0.4, foam_ramp=0.1)
    a, b = Plant(**kw), Plant(foam_bump=0.0, foam_bump_time=5.0, **kw)
    h = 0.002
    for k in range(500):
        assert a.step(k * h, h, 4.0, 3.9) == b.step(k * h, h, 4.0, 3.9)


def test_state_restored_into_a_new_plant_after_the_foam_region_was_hit():
    """A state taken on the foam (entered by region) restored into a fresh plant gives the same outputs at
    once and the same run afterwards: the time, the region hit and the foam onset are part of the state."""
    kw = dict(foam_on_region=True, foam_x_min=0.02, foam_x_max=5, foam_y_min=-1, foam_y_max=1,
              foam_da1=0.4, foam_da2=0.2, foam_ramp=0.3)
    a = Plant(**kw)
    h = 0.002
    k = 0
    while a.outputs()[9] == 0.0:     # until the foam level rises
        a.step(k * h, h, 4.0, 3.9)
        k += 1
    for _ in range(20):
        a.step(k * h, h, 4.0, 3.9)
        k += 1
    s = a.get_state()
    assert s["region_hit"] is True and 0.0 < a.outputs()[9] < 1.0
    b = Plant(**kw)
    b.set_state(s)
    assert b.get_state() == s          # every part of the state, the region's flag too
    assert b.outputs() == a.outputs()
    assert [b.step(j * h, h, 4.2, 3.7) for j in range(k, k + 300)] == \
        [a.step(j * h, h, 4.2, 3.7) for j in range(k, k + 300)]
