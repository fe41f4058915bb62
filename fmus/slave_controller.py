"""WmrController: the controller component (odometry, planner (26)-(32), (50), ADP H-infinity critic
(45)-(51)) as an FMI 2.0 co-simulation slave.  All math is in components/controller.py.

exit_initialization_mode calls Controller.reset(t0, inputs) with the start time and the input values;
do_step(t, h) = Controller.step(t + h, h, inputs): the controller takes the measurements at t + h
(a Gauss-Seidel master sets them from the sensor's outputs at t + h) and its outputs, the torques to
apply from t + h on, depend directly on them (see the dependencies of each output).

The critic's initial weights are parameters W1_init..W3_init, P11_init..P33_init; the learned weights
are outputs W1..W3, P11..P33, so a later run can start from them.

fmus/build.py bundles this script with a copy of the components under a unique package name and
rewrites the two ``wmr_cosim`` imports below to it.
"""
from __future__ import annotations

from wmr_cosim.components.controller import CONTROLLER_OUTPUTS, Controller, ControllerParams
from wmr_cosim.fmus.fmi_base import (DBL_MAX, FINITE, NON_NEGATIVE, POSITIVE, SIGN, STEP_RTOL, Var, WmrSlave,
                                     parameters_of)

_P = {
    "a1": ("kg.m2", FINITE, "nominal Maggi parameter a1 used by the critic; a1..a3 must make M positive definite"),
    "a2": ("kg.m2", FINITE, "nominal Maggi parameter a2"),
    "a3": ("kg.m2", FINITE, "nominal Maggi parameter a3"),
    "a4": ("kg.m2", NON_NEGATIVE, "nominal Maggi parameter a4"),
    "a5": ("N.m", NON_NEGATIVE, "nominal rolling resistance a5 (wheel 1)"),
    "a6": ("N.m", NON_NEGATIVE, "nominal rolling resistance a6 (wheel 2)"),
    "cF": ("s/rad", POSITIVE, "nominal friction slope cF"),
    "r": ("m", POSITIVE, "wheel radius r"),
    "l1": ("m", POSITIVE, "half axle length l1"),
    "friction_form": ("nominal friction shape: tanh (default) or printed",),
    "task": ("task: goal (go to the goal point, Fig. 4) or line (straight line generated offline, Fig. 10)",),
    "x0": ("m", FINITE, "start x of point A assumed by odometry"),
    "y0": ("m", FINITE, "start y of point A assumed by odometry"),
    "beta0": ("rad", FINITE, "start frame angle assumed by odometry"),
    "goal_x": ("m", FINITE, "goal G, x (task goal; tunable)"),
    "goal_y": ("m", FINITE, "goal G, y (task goal; tunable)"),
    "v_star": ("m/s", POSITIVE, "maximum speed v* of point A"),
    "omega_star": ("rad/s", POSITIVE, "maximum turn rate omega* (beta* of Table 1)"),
    "eps_G": ("m", POSITIVE, "goal radius eps_G"),
    "k1": ("1/m", POSITIVE, "kinematic gain k1 of (31)-(32)"),
    "k2": ("1/rad", POSITIVE, "kinematic gain k2 of (32)"),
    "c": ("1/s", POSITIVE, "steepness c of the velocity profile (50)"),
    "b1": ("s", FINITE, "start time b1 of the velocity profile (50)"),
    "line_b2": ("s", FINITE, "stop time b2 of the velocity profile (50), task line"),
    "clip_kinematic": ("clip u_v, u_beta to [-1, 1] (decision 13)",),
    "profile_on_turn": ("scale the turn rate by the profile too (decision 12)",),
    "pose_source": ("pose used by the planner: odometry (default) or true (the x/y/beta_true inputs; decision 14)",),
    "Lambda": ("1/s", POSITIVE, "Lambda of the generalised error s = e_dot + Lambda e (38)"),
    "Q": ("1", NON_NEGATIVE, "state weight Q (multiple of I2)"),
    "R": ("1", POSITIVE, "control weight R (multiple of I2)"),
    "gamma": ("1", POSITIVE, "disturbance attenuation gamma"),
    "W_init": None,
    "P_init": None,
    "xi": ("1", POSITIVE, "adaptation gain xi of (47)"),
    "xi_P": ("1", POSITIVE, "adaptation gain xi_P of (51)"),
    "nu": ("1", POSITIVE, "normalisation nu of (47), (51)"),
    "P0": ("1", NON_NEGATIVE, "P0 of (51): P adapts while the norm of P exceeds it"),
    "adapt": ("adapt the critic weights inside the adaptation window (tunable)",),
    "adapt_t_start": ("s", FINITE, "adaptation window start (tunable)"),
    "adapt_t_end": ("s", (-DBL_MAX, None), "adaptation window end, may be +inf (tunable)"),
    "player_form": ("players: eq13 (default, decision 1) or printed (46)",),
    "player_gamma_power": ((1, 2), "power of gamma in the maximising player: 2 (default) or 1 (decision 2)"),
    "h_state_cost_sign": ("1", SIGN, "sign of the state cost in the Hamiltonian (49): +1 or -1 (decision 3)"),
    "h_gamma_power": ((1, 2), "power of gamma in the Hamiltonian (49): 2 or 1 (decision 4)"),
    "w_update_sign": ("1", SIGN, "sign of the W update (47): +1 or -1 (decision 5)"),
    "p_update_sign": ("1", SIGN, "sign of the P update (51): +1 or -1 (decision 6)"),
    "p_integration": ("P update integration: exact (default) or euler (decision 7)",),
    "sigma1": ("regressor: sigma (default) or normalised (decision 8)",),
    "drift": ("drift model in s_dot: full (default), no_friction or none (decision 9)",),
    "p_norm": ("norm of P compared with P0: min_eig (default), frobenius or max_eig (decision 17)",),
    "freeze_w_with_p": ("stop adapting W when P stops (decision 18)",),
}
TUNABLE = ("goal_x", "goal_y", "adapt", "adapt_t_start", "adapt_t_end", "gamma")
_P_NAMES = ("11", "12", "13", "22", "23", "33")
#: FMI 3.0 arrays (see Var.array): the critic weights W (3) and the symmetric RLS matrix P (3 x 3).
_W_DOC = "critic weights W of (45)"
_P_DOC = "RLS matrix P of (51), symmetric positive definite"


def _ij(name: str) -> tuple[int, int]:
    return int(name[-2]) - 1, int(name[-1]) - 1


def _weight_parameters() -> list[Var]:
    d = ControllerParams()
    out = [Var(f"W{i + 1}_init", "Real", "parameter", f"initial critic weight W{i + 1} of (45)", unit="1",
               range=FINITE, start=float(d.W_init[i]), array=("W_init", (i,), "initial " + _W_DOC))
           for i in range(3)]
    out += [Var(f"P{ij}_init", "Real", "parameter",
                f"initial RLS matrix entry P{ij} (P symmetric positive definite)", unit="1",
                range=POSITIVE if ij[0] == ij[1] else FINITE, start=float(d.P_init[k]),
                array=("P_init", _ij(ij), "initial " + _P_DOC))
            for k, ij in enumerate(_P_NAMES)]
    return out


_INPUTS = [
    Var("alpha_m1", "Real", "input", "measured wheel angle of wheel 1 at the sample", unit="rad", start=0.0),
    Var("alpha_m2", "Real", "input", "measured wheel angle of wheel 2 at the sample", unit="rad", start=0.0),
    Var("alpha_dot_m1", "Real", "input", "measured (filtered) wheel speed of wheel 1", unit="rad/s", start=0.0),
    Var("alpha_dot_m2", "Real", "input", "measured (filtered) wheel speed of wheel 2", unit="rad/s", start=0.0),
    Var("x_true", "Real", "input", "true x of point A (used only if pose_source = true)", unit="m", start=0.0),
    Var("y_true", "Real", "input", "true y of point A (used only if pose_source = true)", unit="m", start=0.0),
    Var("beta_true", "Real", "input", "true frame angle (used only if pose_source = true)", unit="rad", start=0.0),
]

# direct feedthrough: A the measured angles (odometry), T the true pose, wm_i the measured speeds
_A = ("alpha_m1", "alpha_m2")
_T = ("x_true", "y_true", "beta_true")
_POSE = _A + _T
_ALL = _A + ("alpha_dot_m1", "alpha_dot_m2") + _T
_OUT = {  # CONTROLLER_OUTPUTS name: (unit, description, inputs it depends on directly)
    "u1": ("N.m", "control torque for wheel 1 (minimising player), applied from this sample on", _ALL),
    "u2": ("N.m", "control torque for wheel 2 (minimising player)", _ALL),
    "dF_hat1": ("N.m", "worst-case disturbance on wheel 1 (maximising player)", _ALL),
    "dF_hat2": ("N.m", "worst-case disturbance on wheel 2 (maximising player)", _ALL),
    "W1": ("1", "critic weight W1 (learned; final value = start for a later run)", ()),
    "W2": ("1", "critic weight W2 (learned)", ()),
    "W3": ("1", "critic weight W3 (learned)", ()),
    "V_hat": ("1", "value function V_hat = W^T Psi(s) (45)", _ALL),
    "s1": ("rad/s", "generalised error s1 (38)", _POSE + ("alpha_dot_m1",)),
    "s2": ("rad/s", "generalised error s2 (38)", _POSE + ("alpha_dot_m2",)),
    "e1": ("rad", "tracking error e1 = alpha_d1 - alpha_m1 (37)", _POSE),
    "e2": ("rad", "tracking error e2 = alpha_d2 - alpha_m2 (37)", _POSE),
    "edot1": ("rad/s", "velocity tracking error of wheel 1", _POSE + ("alpha_dot_m1",)),
    "edot2": ("rad/s", "velocity tracking error of wheel 2", _POSE + ("alpha_dot_m2",)),
    "H": ("1", "Hamiltonian residual (49)", _ALL),
    "P_norm": ("1", "norm of P compared with P0 in (51)", ()),
    "x_hat": ("m", "x of point A used by the planner", _A + ("x_true",)),
    "y_hat": ("m", "y of point A used by the planner", _A + ("y_true",)),
    "beta_hat": ("rad", "frame angle used by the planner", _A + ("beta_true",)),
    "alpha_d1": ("rad", "desired wheel angle of wheel 1", _POSE),
    "alpha_d2": ("rad", "desired wheel angle of wheel 2", _POSE),
    "alpha_dot_d1": ("rad/s", "desired wheel speed of wheel 1 (23)", _POSE),
    "alpha_dot_d2": ("rad/s", "desired wheel speed of wheel 2 (23)", _POSE),
    "alpha_ddot_d1": ("rad/s2", "desired wheel acceleration of wheel 1", _POSE),
    "alpha_ddot_d2": ("rad/s2", "desired wheel acceleration of wheel 2", _POSE),
    "v_A_d": ("m/s", "desired speed of point A", _POSE),
    "beta_dot_d": ("rad/s", "desired turn rate", _POSE),
    "u_v": ("1", "kinematic control u_v (31)", _POSE),
    "u_beta": ("1", "kinematic control u_beta (32)", _POSE),
    "profile": ("1", "velocity profile (50) without v*", _POSE),
    "adapting": (None, "true while W adapts over the next step", ()),
    "P11": ("1", "RLS matrix entry P11 (learned; final value = start for a later run)", ()),
    "P12": ("1", "RLS matrix entry P12 (learned)", ()),
    "P13": ("1", "RLS matrix entry P13 (learned)", ()),
    "P22": ("1", "RLS matrix entry P22 (learned)", ()),
    "P23": ("1", "RLS matrix entry P23 (learned)", ()),
    "P33": ("1", "RLS matrix entry P33 (learned)", ()),
    "t_goal": ("s", "time eps_G was first reached, -1 before", _POSE),
}


class WmrController(WmrSlave):
    description = ("Controller of the wheeled mobile robot: odometry, kinematic planner (26)-(32), (50) and "
                   "ADP H-infinity critic (45)-(51) with RLS adaptation")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        outputs = []
        for n in CONTROLLER_OUTPUTS:
            unit, desc, deps = _OUT[n]
            if n == "adapting":
                outputs.append(Var(n, "Boolean", "output", desc, variability="discrete", deps=deps))
            else:
                array = (("W", (int(n[1]) - 1,), _W_DOC + " (learned; final value = start for a later run)")
                         if n in ("W1", "W2", "W3") else
                         ("P", _ij(n), _P_DOC + " (learned; final value = start for a later run)")
                         if n[0] == "P" and n[1:] in _P_NAMES else None)
                outputs.append(Var(n, "Real", "output", desc, unit=unit, variability="discrete", deps=deps,
                                   array=array))
        self.declare(parameters_of(ControllerParams(), _P, TUNABLE) + _weight_parameters() + _INPUTS + outputs)
        self._build()

    def _controller_params(self) -> ControllerParams:
        kw = self.parameter_values()
        kw["W_init"] = tuple(kw.pop(f"W{i}_init") for i in (1, 2, 3))
        kw["P_init"] = tuple(kw.pop(f"P{ij}_init") for ij in _P_NAMES)
        return ControllerParams(**kw)

    def _build(self):
        ctrl = Controller(self._controller_params())
        v = self._vals
        self._comp = ctrl
        self._cstep = ctrl.step
        v[self._out0:self._out1] = ctrl.reset(self._t0, *v[self._in0:self._in1])

    def _retune(self):
        self._comp.retune(self._controller_params())  # goal, adaptation window and gamma act from the next sample

    def _step(self, t, h):
        v = self._vals
        x = v[self._in0:self._in1]
        s = sum(x)
        if s - s != 0.0:
            raise ValueError("non-finite input: " + ", ".join(
                f"{v_.name} = {val!r}" for v_, val in zip(self._inputs, x)))
        tn = t + h  # the sample time: (k + 1) h when t = k h, as in the direct loop (see fmi_base.STEP_RTOL)
        tr = round(tn / h) * h
        if tr != tn and abs(tr - tn) <= STEP_RTOL * abs(tn):
            tn = tr
        v[self._out0:self._out1] = self._cstep(tn, h, *x)
