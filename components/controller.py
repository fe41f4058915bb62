"""The controller of Fig. 4 (go-to-goal) and Fig. 10 (offline trajectory): odometry, the kinematic
planner, the desired wheel motion (23), the errors (37)-(38) and the ADP H-infinity critic with its two
players (45)-(51).

It is a sampled-data block: :meth:`Controller.step` takes the measurements at time t (wheel angles and
filtered speeds from the sensor) and returns the torques to apply from t on.  The adaptation laws are
integrated by forward Euler over the step that follows a sample, i.e. the update computed at t_k is applied
at t_{k+1} with h = t_{k+1} - t_k, before the control at t_{k+1} is formed.

Every reading of the paper that had to be decided (docs/decisions.md) is a parameter with the default
that makes the loop behave as the paper reports.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from . import paper
from .critic import (eig_sym3, hamiltonian, hamiltonian_weights, p_norm, player_gains, players, regressor,
                     rls_step, s_rate_model, value)
from .friction import FRICTION_FORMS, shape_function
from .planner import goal_control, polar_error, profile, profile_integral, profile_rate, wheel_rates
from .plant import mass_matrix_inverse
from .params import (boolean, choice, finite, finite_or_inf, non_negative, one_of_int, param, positive, sign, validate,
                     vector)
from .validation import ParameterError, mass_matrix_pd

_T1 = paper.table1()
_LINE = paper.results()["line_task"]

TASKS = ("goal", "line")
PLAYER_FORMS = ("eq13", "printed")
P_NORMS = ("min_eig", "frobenius", "max_eig")
P_INTEGRATIONS = ("exact", "euler")
SIGMA1_FORMS = ("sigma", "normalised")
DRIFTS = ("full", "no_friction", "none")
POSE_SOURCES = ("odometry", "true")

#: Names of the values returned by :meth:`Controller.step` / :meth:`Controller.outputs`, in order.
CONTROLLER_OUTPUTS = (
    "u1", "u2",                      # control: wheel torques [N.m] (minimising player)
    "dF_hat1", "dF_hat2",            # worst-case disturbance (maximising player) [N.m]
    "W1", "W2", "W3",                # critic weights
    "V_hat",                         # value function (45)
    "s1", "s2",                      # generalised error (38) [rad/s]
    "e1", "e2",                      # tracking error (37) [rad]
    "edot1", "edot2",                # velocity tracking error [rad/s]
    "H",                             # Hamiltonian residual (49)
    "P_norm",                        # the norm of P compared with P0 in (51)
    "x_hat", "y_hat", "beta_hat",    # pose used by the planner [m, m, rad]
    "alpha_d1", "alpha_d2",          # desired wheel angles [rad]
    "alpha_dot_d1", "alpha_dot_d2",  # desired wheel speeds [rad/s]
    "alpha_ddot_d1", "alpha_ddot_d2",  # desired wheel accelerations [rad/s^2]
    "v_A_d", "beta_dot_d",           # desired speed of A [m/s] and turn rate [rad/s]
    "u_v", "u_beta",                 # kinematic control (31)-(32) [-]
    "profile",                       # velocity profile (50) without v* [-]
    "adapting",                      # 1 while W adapts over the next step, else 0
    "P11", "P12", "P13", "P22", "P23", "P33",  # RLS matrix P
    "t_goal",                        # time eps_G was first reached [s], -1 before
)


@dataclass
class ControllerParams:
    """Parameters of the controller (Table 1 defaults): each field's unit, accepted values and meaning are in
    its declaration.  The tunable ones (the goal, the adaptation switch and window, gamma) may change
    during a run (:meth:`Controller.retune`)."""

    # nominal model used by the critic's drift f(s) and M^-1
    a1: float = param(_T1["a"][0], unit="kg.m2", check=finite,
                      doc="nominal Maggi parameter a1 used by the critic; a1..a3 must make M positive definite")
    a2: float = param(_T1["a"][1], unit="kg.m2", check=finite, doc="nominal Maggi parameter a2")
    a3: float = param(_T1["a"][2], unit="kg.m2", check=finite, doc="nominal Maggi parameter a3")
    a4: float = param(_T1["a"][3], unit="kg.m2", check=non_negative, doc="nominal Maggi parameter a4")
    a5: float = param(_T1["a"][4], unit="N.m", check=non_negative, doc="nominal rolling resistance a5 (wheel 1)")
    a6: float = param(_T1["a"][5], unit="N.m", check=non_negative, doc="nominal rolling resistance a6 (wheel 2)")
    cF: float = param(_T1["cF"], unit="s/rad", check=positive, doc="nominal friction slope cF")
    r: float = param(paper.WHEEL_RADIUS_M, unit="m", check=positive, doc="wheel radius r")
    l1: float = param(paper.HALF_AXLE_M, unit="m", check=positive, doc="half axle length l1")
    friction_form: str = param("tanh", check=choice(*FRICTION_FORMS),
                               doc="nominal friction shape: tanh (default) or printed")
    # task
    task: str = param("goal", check=choice(*TASKS),
                      doc="task: goal (go to the goal point, Fig. 4) or line (straight line generated offline, "
                          "Fig. 10)")
    x0: float = param(_T1["start"][0], unit="m", check=finite, doc="start x of point A assumed by odometry")
    y0: float = param(_T1["start"][1], unit="m", check=finite, doc="start y of point A assumed by odometry")
    beta0: float = param(0.0, unit="rad", check=finite, doc="start frame angle assumed by odometry")
    goal_x: float = param(_T1["goals"]["G1"][0], unit="m", check=finite, tunable=True,
                          doc="goal G, x (task goal; tunable)")
    goal_y: float = param(_T1["goals"]["G1"][1], unit="m", check=finite, tunable=True,
                          doc="goal G, y (task goal; tunable)")
    v_star: float = param(_T1["v_star"], unit="m/s", check=positive, doc="maximum speed v* of point A")
    omega_star: float = param(_T1["omega_star"], unit="rad/s", check=positive,
                              doc="maximum turn rate omega* (beta* of Table 1)")
    eps_G: float = param(_T1["eps_G"], unit="m", check=positive, doc="goal radius eps_G")
    k1: float = param(_T1["k1"], unit="1/m", check=positive, doc="kinematic gain k1 of (31)-(32)")
    k2: float = param(_T1["k2"], unit="1/rad", check=positive, doc="kinematic gain k2 of (32)")
    c: float = param(_T1["c"], unit="1/s", check=positive, doc="steepness c of the velocity profile (50)")
    b1: float = param(_T1["b1"], unit="s", check=finite, doc="start time b1 of the velocity profile (50)")
    line_b2: float = param(_LINE["b2"], unit="s", check=finite,
                           doc="stop time b2 of the velocity profile (50), task line")
    clip_kinematic: bool = param(True, check=boolean, doc="clip u_v, u_beta to [-1, 1] (decision 13)")
    profile_on_turn: bool = param(True, check=boolean, doc="scale the turn rate by the profile too (decision 12)")
    pose_source: str = param("odometry", check=choice(*POSE_SOURCES),
                             doc="pose used by the planner: odometry (default) or true (the x/y/beta_true "
                                 "inputs; decision 14)")
    # critic
    Lambda: float = param(_T1["Lambda"], unit="1/s", check=positive,
                          doc="Lambda of the generalised error s = e_dot + Lambda e (38)")
    Q: float = param(_T1["Q"], unit="1", check=non_negative, doc="state weight Q (multiple of I2)")
    R: float = param(_T1["R"], unit="1", check=positive, doc="control weight R (multiple of I2)")
    gamma: float = param(_T1["gamma"], unit="1", check=positive, tunable=True,
                         doc="disturbance attenuation gamma")
    W_init: tuple[float, float, float] = param(tuple(_T1["W0"]), unit="1", check=vector(3, finite),
                                               doc="initial critic weights W of (45)")
    P_init: tuple[float, ...] = param((_T1["P_init"], 0.0, 0.0, _T1["P_init"], 0.0, _T1["P_init"]), unit="1",
                                      check=vector(6, finite, "p11 p12 p13 p22 p23 p33"),
                                      doc="initial RLS matrix P of (51), symmetric positive definite")
    xi: float = param(_T1["xi"], unit="1", check=positive, doc="adaptation gain xi of (47)")
    xi_P: float = param(_T1["xi_P"], unit="1", check=positive, doc="adaptation gain xi_P of (51)")
    nu: float = param(_T1["nu"], unit="1", check=positive, doc="normalisation nu of (47), (51)")
    P0: float = param(_T1["P0"], unit="1", check=non_negative,
                      doc="P0 of (51): P adapts while the norm of P exceeds it")
    adapt: bool = param(True, check=boolean, tunable=True,
                        doc="adapt the critic weights inside the adaptation window (tunable)")
    adapt_t_start: float = param(_T1["adaptation_window"][0], unit="s", check=finite, tunable=True,
                                 doc="adaptation window start (tunable)")
    adapt_t_end: float = param(_T1["adaptation_window"][1], unit="s", check=finite_or_inf, tunable=True,
                               doc="adaptation window end, may be +inf (tunable)")
    # the decisions of docs/decisions.md (numbered in the docs)
    player_form: str = param("eq13", check=choice(*PLAYER_FORMS),
                             doc="players: eq13 (default, decision 1) or printed (46)")
    player_gamma_power: int = param(2, check=one_of_int(1, 2),
                                    doc="power of gamma in the maximising player: 2 (default) or 1 (decision 2)")
    h_state_cost_sign: float = param(1.0, unit="1", check=sign,
                                     doc="sign of the state cost in the Hamiltonian (49): +1 or -1 (decision 3)")
    h_gamma_power: int = param(2, check=one_of_int(1, 2), doc="power of gamma in the Hamiltonian (49): 2 or 1 (decision 4)")
    w_update_sign: float = param(1.0, unit="1", check=sign, doc="sign of the W update (47): +1 or -1 (decision 5)")
    p_update_sign: float = param(-1.0, unit="1", check=sign, doc="sign of the P update (51): +1 or -1 (decision 6)")
    p_integration: str = param("exact", check=choice(*P_INTEGRATIONS),
                               doc="P update integration: exact (default) or euler (decision 7)")
    sigma1: str = param("sigma", check=choice(*SIGMA1_FORMS),
                        doc="regressor: sigma (default) or normalised (decision 8)")
    drift: str = param("full", check=choice(*DRIFTS),
                       doc="drift model in s_dot: full (default), no_friction or none (decision 9)")
    p_norm: str = param("min_eig", check=choice(*P_NORMS),
                        doc="norm of P compared with P0: min_eig (default), frobenius or max_eig (decision 17)")
    freeze_w_with_p: bool = param(True, check=boolean, doc="stop adapting W when P stops (decision 18)")

    def __post_init__(self) -> None:
        validate(self, "controller")
        if eig_sym3(*self.P_init)[2] <= 0.0:
            raise ParameterError(f"controller parameter P_init = {self.P_init!r}: must be positive definite")
        mass_matrix_pd("controller", self.a1, self.a2, self.a3)
        if self.adapt_t_end < self.adapt_t_start:
            raise ParameterError(
                f"controller parameter adapt_t_end = {self.adapt_t_end!r}: before adapt_t_start = {self.adapt_t_start!r}")
        if self.task == "goal" and math.hypot(self.goal_x - self.x0, self.goal_y - self.y0) <= self.eps_G:
            raise ParameterError(
                f"controller parameter goal (goal_x, goal_y) = ({self.goal_x!r}, {self.goal_y!r}): "
                f"equals the start ({self.x0!r}, {self.y0!r}) within eps_G = {self.eps_G!r}")
        if self.task == "line" and not self.line_b2 > self.b1:
            raise ParameterError(f"controller parameter line_b2 = {self.line_b2!r}: must be after b1 = {self.b1!r}")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


class Controller:
    """Odometry + planner + ADP critic.  Call :meth:`reset` with the first measurements, then :meth:`step`."""

    def __init__(self, params: ControllerParams | None = None, **overrides: Any) -> None:
        if params is None:
            params = ControllerParams(**overrides)
        elif overrides:
            params = ControllerParams(**{**params.as_dict(), **overrides})
        self.p = params
        p = params
        self._i11, self._i12 = mass_matrix_inverse(p.a1, p.a2, p.a3)
        self._g = shape_function(p.friction_form)
        self._v_over_r = p.v_star / p.r
        self._ku, self._kd = player_gains(p.R, p.gamma, p.player_form, p.player_gamma_power)
        self._hq, self._hg = hamiltonian_weights(p.Q, p.gamma, p.h_state_cost_sign, p.h_gamma_power)
        self._kf = 0.5 * p.cF
        self.reset(0.0, 0.0, 0.0, 0.0, 0.0)

    def retune(self, params: ControllerParams) -> None:
        """New values of the parameters that may change during a run (the goal, the adaptation switch and
        window, and gamma): the gains of the players (46) and the weights of the Hamiltonian (49), which
        depend on gamma, are recomputed; the state (W, P, odometry) is kept."""
        p = self.p = params
        self._ku, self._kd = player_gains(p.R, p.gamma, p.player_form, p.player_gamma_power)
        self._hq, self._hg = hamiltonian_weights(p.Q, p.gamma, p.h_state_cost_sign, p.h_gamma_power)

    # ------------------------------------------------------------------ state
    def reset(self, t: float, am1: float, am2: float, wm1: float, wm2: float,
              xt: float = 0.0, yt: float = 0.0, bt: float = 0.0) -> tuple[float, ...]:
        """Initial state at time t [s] from the first measurements; returns the outputs at t (no adaptation yet)."""
        p = self.p
        self.W = list(p.W_init)
        self.P = list(p.P_init)
        self.pn = p_norm(self.P, p.p_norm)
        self.pose = [p.x0, p.y0, p.beta0]
        self.am_prev = [am1, am2]
        self.ad = [0.0, 0.0]            # desired angles
        self.add_prev = [0.0, 0.0]      # desired speeds at the previous sample
        self.b2 = math.inf if p.task == "goal" else p.line_b2
        self.t_goal = -1.0
        self.pending = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # sigma_1 (3), H, adapt_w, adapt_p of the last sample
        self.first = True
        self.out: tuple[float, ...] = ()
        return self.step(t, 0.0, am1, am2, wm1, wm2, xt, yt, bt)

    def get_state(self) -> dict[str, Any]:
        """All internal state as JSON-serialisable plain values."""
        return {"W": list(self.W), "P": list(self.P), "pn": self.pn, "pose": list(self.pose),
                "am_prev": list(self.am_prev), "ad": list(self.ad), "add_prev": list(self.add_prev),
                "b2": self.b2 if math.isfinite(self.b2) else None, "t_goal": self.t_goal,
                "pending": list(self.pending), "out": list(self.out)}

    def set_state(self, s: dict[str, Any]) -> None:
        """Restore a state returned by :meth:`get_state`."""
        self.W = [float(v) for v in s["W"]]
        self.P = [float(v) for v in s["P"]]
        self.pn = float(s["pn"])
        self.pose = [float(v) for v in s["pose"]]
        self.am_prev = [float(v) for v in s["am_prev"]]
        self.ad = [float(v) for v in s["ad"]]
        self.add_prev = [float(v) for v in s["add_prev"]]
        self.b2 = math.inf if s["b2"] is None else float(s["b2"])
        self.t_goal = float(s["t_goal"])
        self.pending = [float(v) for v in s["pending"]]
        self.first = False   # (True only inside reset's own first step: never in a state)
        self.out = tuple(float(v) for v in s["out"])

    # ------------------------------------------------------------------ one sample
    def step(self, t: float, h: float, am1: float, am2: float, wm1: float, wm2: float,
             xt: float = 0.0, yt: float = 0.0, bt: float = 0.0) -> tuple[float, ...]:
        """The sample at time t [s], h [s] after the previous one, from the measured wheel angles am_i [rad]
        and speeds wm_i [rad/s] (and the true pose xt, yt [m], bt [rad], used only if pose_source = 'true').

        Returns the outputs named by :data:`CONTROLLER_OUTPUTS`; u1, u2 are to be applied from t on.
        """
        p = self.p
        W, P = self.W, self.P
        i11, i12 = self._i11, self._i12
        # ---- adaptation over the step that just ended, from the previous sample (47), (51)
        pend = self.pending
        if pend[4] or pend[5]:
            rls_step(W, P, pend[0], pend[1], pend[2], pend[3], h, p.xi, p.xi_P, p.nu,
                     pend[4] != 0.0, pend[5] != 0.0, p.w_update_sign, p.p_update_sign, p.p_integration)
            if pend[5]:
                self.pn = p_norm(P, p.p_norm)
        # ---- odometry of point A from the measured wheel angles, midpoint rule on (23)-(24)
        pose = self.pose
        da1 = am1 - self.am_prev[0]
        da2 = am2 - self.am_prev[1]
        self.am_prev = [am1, am2]
        ds = 0.5 * p.r * (da1 + da2)
        db = 0.5 * p.r * (da1 - da2) / p.l1
        bm = pose[2] + 0.5 * db
        pose[0] += ds * math.cos(bm)
        pose[1] += ds * math.sin(bm)
        pose[2] += db
        if p.pose_source == "odometry":
            x, y, beta = pose
        else:
            x, y, beta = xt, yt, bt
        # ---- desired wheel motion
        if p.task == "goal":
            delta, psi = polar_error(x, y, beta, p.goal_x, p.goal_y)          # (26)-(27)
            if self.t_goal < 0.0 and delta < p.eps_G:                         # decision 15: b2 = t_G + 1
                self.t_goal = t
                self.b2 = t + 1.0
            uv, ub = goal_control(delta, psi, p.k1, p.k2, p.clip_kinematic)  # (31)-(32)
            prof = profile(t, p.b1, self.b2, p.c)                             # (50)
            vd = p.v_star * prof * uv
            bd = p.omega_star * (prof if p.profile_on_turn else 1.0) * ub    # decision 12
            add1, add2 = wheel_rates(vd, bd, p.r, p.l1)                      # (23)
            if self.first:
                addd1 = addd2 = 0.0
            else:
                ad = self.ad
                ad[0] += 0.5 * h * (self.add_prev[0] + add1)                 # trapezoidal integral
                ad[1] += 0.5 * h * (self.add_prev[1] + add2)
                addd1 = (add1 - self.add_prev[0]) / h                       # backward difference
                addd2 = (add2 - self.add_prev[1]) / h
            ad1, ad2 = self.ad
        else:  # straight line along the initial heading, generated offline in closed form
            uv, ub = 1.0, 0.0
            prof = profile(t, p.b1, self.b2, p.c)
            vd = p.v_star * prof
            bd = 0.0
            add1 = add2 = self._v_over_r * prof
            addd1 = addd2 = self._v_over_r * profile_rate(t, p.b1, self.b2, p.c)
            ad1 = ad2 = self._v_over_r * profile_integral(t, p.b1, self.b2, p.c)
            self.ad = [ad1, ad2]
        self.add_prev = [add1, add2]
        self.first = False
        # ---- errors (37)-(38)
        lam = p.Lambda
        e1, e2 = ad1 - am1, ad2 - am2
        ed1, ed2 = add1 - wm1, add2 - wm2
        s1, s2 = ed1 + lam * e1, ed2 + lam * e2
        # ---- players (46) read through (13), value (45)
        w1, w2, w3 = W
        dv1, dv2 = 2.0 * w1 * s1 + w2 * s2, w2 * s1 + 2.0 * w3 * s2
        u1, u2, df1, df2 = players(dv1, dv2, i11, i12, self._ku, self._kd)
        # ---- regressor (48) and Hamiltonian (49) with the nominal model (decision 9)
        g, k = self._g, self._kf
        f1 = 2.0 * p.a5 * g(k * wm1)
        f2 = 2.0 * p.a6 * g(k * wm2)
        sd1, sd2 = s_rate_model(addd1, addd2, ed1, ed2, wm1, wm2, u1, u2, df1, df2, lam, i11, i12,
                                p.a4, f1, f2, p.drift)
        sg1, sg2, sg3 = regressor(s1, s2, sd1, sd2)
        H = hamiltonian(w1, w2, w3, sg1, sg2, sg3, s1, s2, u1, u2, df1, df2, self._hq, p.R, self._hg)
        # ---- what adapts over the next step: window, and (51) with decisions 17, 18
        active = p.adapt and p.adapt_t_start <= t < p.adapt_t_end
        p_live = self.pn > p.P0
        adapt_p = active and p_live
        adapt_w = active and (p_live or not p.freeze_w_with_p)
        if p.sigma1 == "normalised":
            nn = sg1 * sg1 + sg2 * sg2 + sg3 * sg3 + 1.0
            sg1, sg2, sg3 = sg1 / nn, sg2 / nn, sg3 / nn
        self.pending = [sg1, sg2, sg3, H, 1.0 if adapt_w else 0.0, 1.0 if adapt_p else 0.0]
        self.out = (u1, u2, df1, df2, w1, w2, w3, value(w1, w2, w3, s1, s2), s1, s2, e1, e2, ed1, ed2, H,
                    self.pn, x, y, beta, ad1, ad2, add1, add2, addd1, addd2, vd, bd, uv, ub,
                    prof, 1.0 if adapt_w else 0.0, P[0], P[1], P[2], P[3], P[4], P[5], self.t_goal)
        return self.out

    def outputs(self) -> tuple[float, ...]:
        """The outputs of the last sample, named by :data:`CONTROLLER_OUTPUTS`."""
        return self.out
