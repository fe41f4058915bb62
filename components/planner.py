"""The higher control layer: the velocity profile (50), the go-to-goal kinematic control (26)-(32)
and the straight-line trajectory generated offline.

All functions are pure (no state) and take plain floats.  Units: m, rad, s; u_v, u_beta are
dimensionless (scaled by v* [m/s] and omega* [rad/s] in (24)).
"""
from __future__ import annotations

import math

TWO_PI = 2.0 * math.pi


def sigmoid(z: float) -> float:
    """1 / (1 + e^-z), without overflow for any z (including +-inf)."""
    if z >= 0.0:
        return 1.0 / (1.0 + math.exp(-z))
    e = math.exp(z)
    return e / (1.0 + e)


def softplus(z: float) -> float:
    """ln(1 + e^z), without overflow: the integral of sigmoid."""
    return max(z, 0.0) + math.log1p(math.exp(-abs(z)))


def profile(t: float, b1: float, b2: float, c: float) -> float:
    """The velocity profile of (50) without v*: 1/(1+e^-c(t-b1)) - 1/(1+e^-c(t-b2)) [-]; b2 may be inf."""
    return sigmoid(c * (t - b1)) - sigmoid(c * (t - b2))


def profile_rate(t: float, b1: float, b2: float, c: float) -> float:
    """d/dt of :func:`profile` [1/s]."""
    s1 = sigmoid(c * (t - b1))
    s2 = sigmoid(c * (t - b2))
    return c * (s1 * (1.0 - s1) - s2 * (1.0 - s2))


def profile_integral(t: float, b1: float, b2: float, c: float) -> float:
    """The integral of :func:`profile` from 0 to t [s] (closed form, finite b2)."""
    def prim(tt: float) -> float:
        return (softplus(c * (tt - b1)) - softplus(c * (tt - b2))) / c
    return prim(t) - prim(0.0)


def wrap_angle(a: float) -> float:
    """a wrapped to [-pi, pi) [rad]."""
    return (a + math.pi) % TWO_PI - math.pi


def polar_error(x: float, y: float, beta: float, xg: float, yg: float) -> tuple[float, float]:
    """(26)-(27): distance delta_AG [m] from point A (x, y) to G (xg, yg) and bearing psi_G [rad] in [-pi, pi)."""
    dx = xg - x
    dy = yg - y
    return math.hypot(dx, dy), wrap_angle(math.atan2(dy, dx) - beta)


def goal_control(delta: float, psi: float, k1: float, k2: float, clip: bool) -> tuple[float, float]:
    """(31)-(32): u_v = k1 delta cos psi, u_beta = k1 sin psi cos psi + k2 psi, optionally clipped to
    [-1, 1] (decision 13: v*, omega* are maximum velocities)."""
    c = math.cos(psi)
    uv = k1 * delta * c
    ub = k1 * math.sin(psi) * c + k2 * psi
    if clip:
        uv = 1.0 if uv > 1.0 else (-1.0 if uv < -1.0 else uv)
        ub = 1.0 if ub > 1.0 else (-1.0 if ub < -1.0 else ub)
    return uv, ub


def lyapunov(delta: float, psi: float) -> float:
    """(29): V_L = delta^2 / 2 + psi^2 / 2."""
    return 0.5 * delta * delta + 0.5 * psi * psi


def lyapunov_rate(delta: float, psi: float, k1: float, k2: float) -> float:
    """(33): dV_L/dt = -k1 delta^2 cos^2 psi - k2 psi^2 under the unclipped control (31)-(32)."""
    c = math.cos(psi)
    return -k1 * delta * delta * c * c - k2 * psi * psi


def wheel_rates(v: float, beta_dot: float, r: float, l1: float) -> tuple[float, float]:
    """(23): wheel speeds [rad/s] from the speed of point A v [m/s] and the frame's turn rate [rad/s]."""
    return (v + beta_dot * l1) / r, (v - beta_dot * l1) / r
