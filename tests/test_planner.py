"""The kinematic planner (26)-(33) and the velocity profile (50)."""
import math

import numpy as np
import pytest
from scipy.integrate import quad

from wmr_cosim.components.planner import (goal_control, lyapunov, lyapunov_rate, polar_error, profile,
                                          profile_integral, profile_rate, sigmoid, wheel_rates)


def _kinematic_run(k1, k2, clip, x0=(0.0, 0.0, 0.0), goal=(2.0, 5.0), T=30.0, dt=0.001):
    """(24) with v* = omega* = 1 and no profile, i.e. (28) driven by (31)-(32), integrated with RK4."""
    def f(q):
        d, p = polar_error(q[0], q[1], q[2], *goal)
        uv, ub = goal_control(d, p, k1, k2, clip)
        return np.array([uv * math.cos(q[2]), uv * math.sin(q[2]), ub])
    q = np.array(x0, dtype=float)
    traj = [q.copy()]
    for _ in range(int(T / dt)):
        a = f(q); b = f(q + dt / 2 * a); c = f(q + dt / 2 * b); d = f(q + dt * c)
        q = q + dt / 6 * (a + 2 * b + 2 * c + d)
        traj.append(q.copy())
    return np.array(traj), dt


def test_lyapunov_function_decreases_along_a_kinematic_run():
    k1, k2 = 0.4, 0.25
    traj, dt = _kinematic_run(k1, k2, clip=False)
    V = []
    rates = []
    for q in traj:
        d, p = polar_error(q[0], q[1], q[2], 2.0, 5.0)
        V.append(lyapunov(d, p))
        rates.append(lyapunov_rate(d, p, k1, k2))
    V = np.array(V)
    assert np.all(np.diff(V) < 0)                   # (33): V_L strictly decreasing
    # the rate of change matches (33) (central differences, away from psi wrapping)
    dV = (V[2:] - V[:-2]) / (2 * dt)
    assert np.allclose(dV, np.array(rates[1:-1]), rtol=1e-5, atol=1e-9)
    assert V[-1] < 1e-3 * V[0]                      # and A converges to G


def test_clipped_planner_still_reaches_the_goal():
    traj, _ = _kinematic_run(0.4, 0.25, clip=True, x0=(0, 0, math.pi), goal=(4.0, 0.0), T=60)
    assert math.hypot(traj[-1, 0] - 4, traj[-1, 1]) < 0.01


def test_polar_error_by_hand():
    d, p = polar_error(0, 0, 0, 2, 5)
    assert d == pytest.approx(math.sqrt(29)) and p == pytest.approx(math.atan2(5, 2))
    d, p = polar_error(1, 1, 3.0, 0, 1)            # goal behind: psi wrapped into [-pi, pi)
    assert p == pytest.approx(math.pi - 3.0)
    d, p = polar_error(0, 0, -3.0, -1, 0.01)
    assert -math.pi <= p < math.pi


def test_goal_control_31_32():
    uv, ub = goal_control(2.0, 0.3, 0.4, 0.25, clip=False)
    assert uv == pytest.approx(0.4 * 2 * math.cos(0.3))
    assert ub == pytest.approx(0.4 * math.sin(0.3) * math.cos(0.3) + 0.25 * 0.3)
    uv, ub = goal_control(20.0, 3.0, 0.4, 0.25, clip=True)
    assert uv == -1.0 and 0 < ub <= 1.0


def test_profile_50():
    assert profile(5.0, 5.0, math.inf, 10) == pytest.approx(0.5)
    assert profile(0.0, 5.0, math.inf, 10) == pytest.approx(1 / (1 + math.exp(50)))
    assert profile(10.0, 5.0, 15.0, 10) == pytest.approx(1.0, abs=1e-10)
    assert profile(30.0, 5.0, 15.0, 10) == pytest.approx(0.0, abs=1e-10)
    assert sigmoid(-1e6) == 0.0 and sigmoid(1e6) == 1.0   # no overflow


def test_profile_rate_and_integral_are_consistent():
    for t in (0.3, 4.9, 5.0, 9.0, 14.99, 16.2):
        fd = (profile(t + 1e-6, 5, 15, 10) - profile(t - 1e-6, 5, 15, 10)) / 2e-6
        assert profile_rate(t, 5, 15, 10) == pytest.approx(fd, rel=1e-6, abs=1e-9)
        integ, _ = quad(lambda s: profile(s, 5, 15, 10), 0, t, limit=200)
        assert profile_integral(t, 5, 15, 10) == pytest.approx(integ, rel=1e-9, abs=1e-12)
    # the line task: 0.4 m/s x (b2 - b1) = 4 m in all
    assert 0.4 * profile_integral(60.0, 5, 15, 10) == pytest.approx(4.0, rel=1e-9)


def test_wheel_rates_23():
    w1, w2 = wheel_rates(0.4, 0.7, 0.0825, 0.16)
    assert w1 == pytest.approx(0.4 / 0.0825 + 0.7 * 0.16 / 0.0825)
    assert w2 == pytest.approx(0.4 / 0.0825 - 0.7 * 0.16 / 0.0825)
