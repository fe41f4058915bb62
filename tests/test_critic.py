"""The ADP critic against (13), (41), (45)-(51), computed literally with numpy."""

import numpy as np
import pytest

from wmr_cosim.components import critic
from wmr_cosim.components.plant import mass_matrix_inverse

A = (0.0691, 0.0511, 0.0291)
M = np.array([[A[0] + A[1] + A[2], A[0] - A[1]], [A[0] - A[1], A[0] + A[1] + A[2]]])
I11, I12 = mass_matrix_inverse(*A)
W = np.array([0.08, 0.06, 0.07])
S = np.array([1.3, -0.4])


def grad_psi(s):
    """grad Psi(s) of Psi = [s1^2, s1 s2, s2^2]: 3 x 2."""
    return np.array([[2 * s[0], 0.0], [s[1], s[0]], [0.0, 2 * s[1]]])


def test_value_and_gradient():
    assert critic.value(*W, *S) == pytest.approx(W @ np.array([S[0] ** 2, S[0] * S[1], S[1] ** 2]))
    assert np.allclose(critic.value_gradient(*W, *S), grad_psi(S).T @ W)


def test_players_match_13_with_g_minus_Minv():
    R, gamma = 0.5, 11.0
    g = -np.linalg.inv(M)
    k = np.linalg.inv(M)
    dV = grad_psi(S).T @ W
    u = -0.5 / R * g.T @ dV                 # (13)
    d = 1 / (2 * gamma ** 2) * k.T @ dV     # (13)
    out = critic.players(*dV, I11, I12, *critic.player_gains(R, gamma))
    assert np.allclose(out[:2], u, rtol=1e-13)
    assert np.allclose(out[2:], d, rtol=1e-13)
    # the disturbance player is R / gamma^2 = 1/242 of the control: "250 times lower"
    assert out[0] / out[2] == pytest.approx(242.0)
    printed = critic.players(*dV, I11, I12, *critic.player_gains(R, gamma, player_form="printed", gamma_power=1))
    assert np.allclose(printed[:2], -u) and np.allclose(printed[2:], d * gamma)


def test_s_rate_is_40_41():
    """s_dot = f(s) + g u + k dF with f = M^-1 (-C s + f_WMR), f_WMR = M (add + L e_dot) + C (ad + L e) + F."""
    a4, lam = 0.0014, 5.0
    ad_dot = np.array([4.0, 3.0]); add = np.array([0.5, -0.2])
    w = np.array([3.8, 3.3]); e = np.array([0.2, -0.1])
    ed = ad_dot - w
    s = ed + lam * e
    F = np.array([4.1, 3.9]); u = np.array([4.5, 3.6]); dF = np.array([0.02, 0.015])
    C = np.array([[0, 2 * a4 * (w[1] - w[0])], [-2 * a4 * (w[1] - w[0]), 0]])
    Minv = np.linalg.inv(M)
    fwmr = M @ (add + lam * ed) + C @ (ad_dot + lam * e) + F
    sdot = Minv @ (-C @ s + fwmr) - Minv @ u + Minv @ dF
    got = critic.s_rate_model(add[0], add[1], ed[0], ed[1], w[0], w[1], u[0], u[1], dF[0], dF[1], lam,
                              I11, I12, a4, F[0], F[1])
    assert np.allclose(got, sdot, rtol=1e-12)
    none = critic.s_rate_model(*add, *ed, *w, *u, *dF, lam, I11, I12, a4, *F, drift="none")
    assert np.allclose(none, Minv @ (dF - u))
    # without the friction model: (40)-(41) with F = 0
    fwmr0 = M @ (add + lam * ed) + C @ (ad_dot + lam * e)
    no_f = critic.s_rate_model(*add, *ed, *w, *u, *dF, lam, I11, I12, a4, *F, drift="no_friction")
    assert np.allclose(no_f, Minv @ (-C @ s + fwmr0) - Minv @ u + Minv @ dF, rtol=1e-12)
    assert not np.allclose(no_f, got)


def test_regressor_and_hamiltonian_49():
    sd = np.array([0.3, -0.7])
    sig = grad_psi(S) @ sd
    assert np.allclose(critic.regressor(*S, *sd), sig)
    u = np.array([1.0, 2.0]); dF = np.array([0.01, 0.02])
    Q, R, g = 1.0, 0.5, 11.0
    Hh = W @ sig + Q * S @ S + R * u @ u - g ** 2 * dF @ dF
    assert critic.hamiltonian(*W, *sig, *S, *u, *dF, *critic.hamiltonian_weights(Q, g)[:1], R,
                              critic.hamiltonian_weights(Q, g)[1]) == pytest.approx(Hh, rel=1e-14)
    # the printed readings: -x'Qx (12) and gamma instead of gamma^2 (44)/(49)
    q, gg = critic.hamiltonian_weights(Q, g, state_cost_sign=-1.0, gamma_power=1)
    assert (q, gg) == (-Q, g)


def test_eigenvalues_of_symmetric_3x3():
    rng = np.random.default_rng(3)
    for _ in range(200):
        B = rng.normal(size=(3, 3))
        P = B @ B.T * 10 ** rng.uniform(-4, 2) + np.diag(rng.uniform(1e-5, 1, 3))
        e = critic.eig_sym3(P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2])
        ref = np.linalg.eigvalsh(P)[::-1]
        assert np.allclose(e, ref, rtol=1e-8, atol=1e-12 * ref[0])
    assert critic.eig_sym3(100, 0, 0, 100, 0, 100) == (100, 100, 100)


def test_p_norms():
    P = [3.0, 0.5, 0.0, 2.0, 0.1, 1.0]
    Pm = np.array([[3, .5, 0], [.5, 2, .1], [0, .1, 1]])
    assert critic.p_norm(P, "min_eig") == pytest.approx(np.linalg.eigvalsh(Pm)[0])
    assert critic.p_norm(P, "max_eig") == pytest.approx(np.linalg.eigvalsh(Pm)[-1])
    assert critic.p_norm(P, "frobenius") == pytest.approx(np.linalg.norm(Pm))


def test_rls_step_47_51():
    """W by Euler on (47) with the printed + sign; P exactly: P_new^-1 = P^-1 + h xi_P sig sig^T / d."""
    h, xi, xiP, nu, Hh = 0.002, 1.2, 80.0, 0.1, 0.37
    P = np.array([[100, 1, 0], [1, 90, 2], [0, 2, 80.0]])
    sig = np.array([0.5, -0.2, 0.9])
    d = 1 + nu * sig @ P @ sig
    Wl, Pl = list(W), [P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]]
    critic.rls_step(Wl, Pl, *sig, Hh, h, xi, xiP, nu, True, True)
    assert np.allclose(Wl, W + h * xi * P @ sig / d * Hh, rtol=1e-13)
    Pn = np.array([[Pl[0], Pl[1], Pl[2]], [Pl[1], Pl[3], Pl[4]], [Pl[2], Pl[4], Pl[5]]])
    assert np.allclose(np.linalg.inv(Pn), np.linalg.inv(P) + h * xiP * np.outer(sig, sig) / d, rtol=1e-9)
    # Euler instead: P - h xi_P P sig sig^T P / d
    Pl2 = [P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]]
    critic.rls_step(list(W), Pl2, *sig, Hh, h, xi, xiP, nu, False, True, p_integration="euler")
    Pe = P - h * xiP * P @ np.outer(sig, sig) @ P / d
    assert np.allclose(Pl2, [Pe[0, 0], Pe[0, 1], Pe[0, 2], Pe[1, 1], Pe[1, 2], Pe[2, 2]], rtol=1e-13)


def test_exact_p_update_stays_positive_definite_where_euler_does_not():
    """Decision 7: xi_P h / nu = 1.6 > 1, so Euler overshoots P to an indefinite matrix."""
    sig = (30.0, 0.0, 0.0)
    Pe = [100.0, 0, 0, 100.0, 0, 100.0]
    Px = list(Pe)
    for _ in range(5):
        critic.rls_step([0, 0, 0], Pe, *sig, 0.0, 0.002, 1.2, 80.0, 0.1, False, True, p_integration="euler")
        critic.rls_step([0, 0, 0], Px, *sig, 0.0, 0.002, 1.2, 80.0, 0.1, False, True)
    assert critic.eig_sym3(*Pe)[2] < 0.0
    assert critic.eig_sym3(*Px)[2] > 0.0
