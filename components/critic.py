"""The ADP H-infinity critic of section 5.1: value function (45), players (46) read through (13),
Hamiltonian (49), regressor (48) and the RLS adaptation (47), (51).

Basis Psi(s) = [s1^2, s1 s2, s2^2] (45), so grad Psi^T W = [2 W1 s1 + W2 s2, W2 s1 + 2 W3 s2].
M^-1 is passed as (i11, i12) (symmetric with equal diagonal, see plant.mass_matrix_inverse); g = -M^-1,
k = M^-1 (41).  The decisions of docs/decisions.md that change the math are arguments here.
All functions are pure and take plain floats.  Units: s [rad/s], u and dF [N.m], V [(rad/s)^2 s].
"""
from __future__ import annotations

import math

_TWO_PI_3 = 2.0 * math.pi / 3.0


def value(w1: float, w2: float, w3: float, s1: float, s2: float) -> float:
    """V_hat = W^T Psi(s) of (45)."""
    return w1 * s1 * s1 + w2 * s1 * s2 + w3 * s2 * s2


def value_gradient(w1: float, w2: float, w3: float, s1: float, s2: float) -> tuple[float, float]:
    """dV_hat/ds = grad Psi(s)^T W."""
    return 2.0 * w1 * s1 + w2 * s2, w2 * s1 + 2.0 * w3 * s2


def player_gains(R: float, gamma: float, player_form: str = "eq13", gamma_power: int = 2) -> tuple[float, float]:
    """(ku, kd) with u = ku M^-1 dV/ds and dF = kd M^-1 dV/ds (the players, below).

    'eq13' (decision 1, default): u = -1/2 R^-1 g^T dV/ds = +1/2 R^-1 M^-1 dV/ds and
    dF = 1/(2 gamma^2) k^T dV/ds = 1/(2 gamma^2) M^-1 dV/ds, as (13) gives with g = -M^-1, k = M^-1.
    'printed': u = +1/2 R^-1 g^T grad Psi W = -1/2 R^-1 M^-1 dV/ds as (46) prints it (positive feedback).
    ``gamma_power`` 2 (decision 2, default) or 1 (as (46) prints gamma).
    """
    ku = 0.5 / R if player_form == "eq13" else -0.5 / R
    kd = 0.5 / (gamma * gamma if gamma_power == 2 else gamma)
    return ku, kd


def players(dv1: float, dv2: float, i11: float, i12: float, ku: float, kd: float) -> tuple[float, float, float, float]:
    """(u1, u2, dF1, dF2) [N.m]: the minimising and maximising players (46) read through (13), from
    dV/ds = (dv1, dv2), M^-1 = [[i11, i12], [i12, i11]] and the gains of :func:`player_gains`."""
    m1 = i11 * dv1 + i12 * dv2
    m2 = i12 * dv1 + i11 * dv2
    return ku * m1, ku * m2, kd * m1, kd * m2


def s_rate_model(add1: float, add2: float, ed1: float, ed2: float, w1: float, w2: float,
                 u1: float, u2: float, df1: float, df2: float, lam: float, i11: float, i12: float,
                 a4: float, f1: float, f2: float, drift: str = "full") -> tuple[float, float]:
    """s_dot = f(s) + g(s) u + k(s) dF of (40)-(41) [rad/s^2], evaluated with measured rates.

    With f_WMR of (39), M^-1 (-C s + f_WMR) = alpha_ddot_d + Lambda e_dot + M^-1 (C(alpha_dot) alpha_dot + F),
    since -C s + C (alpha_dot_d + Lambda e) = C alpha_dot.  ``add`` = desired accelerations [rad/s^2],
    ``ed`` = e_dot [rad/s], ``w`` = measured wheel speeds [rad/s], ``f`` = model friction F(w) [N.m].
    drift: 'full' (decision 9, default), 'no_friction' (F = 0) or 'none' (f(s) = 0).
    """
    if drift == "none":
        r1, r2 = df1 - u1, df2 - u2
        return i11 * r1 + i12 * r2, i12 * r1 + i11 * r2
    c = 2.0 * a4 * (w2 - w1)  # C(alpha_dot) = [[0, c], [-c, 0]] of (35)
    if drift == "no_friction":
        f1 = f2 = 0.0
    r1 = c * w2 + f1 - u1 + df1
    r2 = -c * w1 + f2 - u2 + df2
    return (add1 + lam * ed1 + i11 * r1 + i12 * r2,
            add2 + lam * ed2 + i12 * r1 + i11 * r2)


def regressor(s1: float, s2: float, sd1: float, sd2: float) -> tuple[float, float, float]:
    """sigma = grad Psi(s) s_dot of (48)."""
    return 2.0 * s1 * sd1, s2 * sd1 + s1 * sd2, 2.0 * s2 * sd2


def hamiltonian_weights(Q: float, gamma: float, state_cost_sign: float = 1.0, gamma_power: int = 2) -> tuple[float, float]:
    """(q, g) for :func:`hamiltonian`: q = state_cost_sign Q (decision 3: +1, as (10), (18), (49); -1 as
    (12) prints), g = gamma^2 (decision 4; gamma as (44)/(49) print with gamma_power = 1)."""
    return state_cost_sign * Q, (gamma * gamma if gamma_power == 2 else gamma)


def hamiltonian(w1: float, w2: float, w3: float, sg1: float, sg2: float, sg3: float,
                s1: float, s2: float, u1: float, u2: float, df1: float, df2: float,
                q: float, R: float, g: float) -> float:
    """H of (49) = W^T sigma + s^T Q s + u^T R u - gamma^2 dF^T dF, with (q, g) from :func:`hamiltonian_weights`."""
    return (w1 * sg1 + w2 * sg2 + w3 * sg3 + q * (s1 * s1 + s2 * s2)
            + R * (u1 * u1 + u2 * u2) - g * (df1 * df1 + df2 * df2))


def eig_sym3(p11: float, p12: float, p13: float, p22: float, p23: float, p33: float) -> tuple[float, float, float]:
    """Eigenvalues (largest, middle, smallest) of a symmetric 3x3 matrix, closed form (Smith 1961)."""
    q = (p11 + p22 + p33) / 3.0
    off = p12 * p12 + p13 * p13 + p23 * p23
    d11, d22, d33 = p11 - q, p22 - q, p33 - q
    p2 = d11 * d11 + d22 * d22 + d33 * d33 + 2.0 * off
    if p2 <= 0.0:
        return q, q, q
    p = math.sqrt(p2 / 6.0)
    # r = det((P - qI)/p) / 2
    det = (d11 * (d22 * d33 - p23 * p23) - p12 * (p12 * d33 - p23 * p13)
           + p13 * (p12 * p23 - d22 * p13))
    r = det / (2.0 * p * p * p)
    r = 1.0 if r > 1.0 else (-1.0 if r < -1.0 else r)
    phi = math.acos(r) / 3.0
    e1 = q + 2.0 * p * math.cos(phi)
    e3 = q + 2.0 * p * math.cos(phi + _TWO_PI_3)
    return e1, 3.0 * q - e1 - e3, e3


def p_norm(P: list[float], kind: str = "min_eig") -> float:
    """The 'norm' of P compared with P0 in (51) (decision 17).

    P as 6 floats [p11, p12, p13, p22, p23, p33].  'min_eig' (default): the smallest eigenvalue;
    'frobenius': the Frobenius norm; 'max_eig': the spectral norm (largest eigenvalue, P > 0).
    """
    if kind == "frobenius":
        p11, p12, p13, p22, p23, p33 = P
        return math.sqrt(p11 * p11 + p22 * p22 + p33 * p33 + 2.0 * (p12 * p12 + p13 * p13 + p23 * p23))
    e = eig_sym3(*P)
    return e[2] if kind == "min_eig" else e[0]


def rls_step(W: list[float], P: list[float], sg1: float, sg2: float, sg3: float, H: float, h: float,
             xi: float, xi_P: float, nu: float, adapt_w: bool, adapt_p: bool,
             w_sign: float = 1.0, p_sign: float = -1.0, p_integration: str = "exact") -> None:
    """One step of h [s] of the adaptation laws (47) and (51), in place on W (3 floats) and P (6 floats).

    dW/dt = w_sign xi P sigma_1 / (1 + nu sigma_1^T P sigma_1) H  (decision 5: the printed + sign),
    dP/dt = p_sign xi_P P sigma_1 sigma_1^T P / (1 + nu sigma_1^T P sigma_1)  (decision 6: minus).
    W by forward Euler.  P (decision 7) 'exact': the inverse gains h xi_P sigma sigma^T / d exactly, i.e.
    the Sherman-Morrison update P - c P s s^T P / (1 + c s^T P s), c = h xi_P / d, which keeps P > 0;
    'euler': forward Euler (overshoots to an indefinite P when xi_P h / nu > 1).
    Both use P and sigma at the start of the step.
    """
    p11, p12, p13, p22, p23, p33 = P
    ps1 = p11 * sg1 + p12 * sg2 + p13 * sg3
    ps2 = p12 * sg1 + p22 * sg2 + p23 * sg3
    ps3 = p13 * sg1 + p23 * sg2 + p33 * sg3
    sps = sg1 * ps1 + sg2 * ps2 + sg3 * ps3
    d = 1.0 + nu * sps
    if adapt_w:
        k = h * w_sign * xi * H / d
        W[0] += k * ps1
        W[1] += k * ps2
        W[2] += k * ps3
    if adapt_p:
        if p_integration == "exact" and p_sign < 0.0:
            c = h * xi_P / d
            k = -c / (1.0 + c * sps)
        else:
            k = h * p_sign * xi_P / d
        P[0] = p11 + k * ps1 * ps1
        P[1] = p12 + k * ps1 * ps2
        P[2] = p13 + k * ps1 * ps3
        P[3] = p22 + k * ps2 * ps2
        P[4] = p23 + k * ps2 * ps3
        P[5] = p33 + k * ps3 * ps3
