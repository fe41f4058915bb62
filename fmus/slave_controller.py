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
from wmr_cosim.fmus.fmi_base import POSITIVE, STEP_RTOL, Var, WmrSlave, parameters_of

_P_NAMES = ("11", "12", "13", "22", "23", "33")
#: FMI 3.0 arrays (see Var.array): the critic weights W (3) and the symmetric RLS matrix P (3 x 3).
_W_DOC = "critic weights W of (45)"
_P_DOC = "RLS matrix P of (51), symmetric positive definite"


def _ij(name: str) -> tuple[int, int]:
    return int(name[-2]) - 1, int(name[-1]) - 1


def _weight_parameters() -> list[Var]:
    """The tuples W_init, P_init as scalars (FMI 3.0: as arrays); unit, element range and the array's
    description from their field declarations, a positive range for P's diagonal (P positive definite)."""
    d = ControllerParams()
    w, p = (ControllerParams.__dataclass_fields__[n].metadata for n in ("W_init", "P_init"))
    out = [Var(f"W{i + 1}_init", "Real", "parameter", f"initial critic weight W{i + 1} of (45)", unit=w["unit"],
               range=w["check"].bounds, start=float(d.W_init[i]), array=("W_init", (i,), w["doc"]))
           for i in range(3)]
    out += [Var(f"P{ij}_init", "Real", "parameter",
                f"initial RLS matrix entry P{ij} (P symmetric positive definite)", unit=p["unit"],
                range=POSITIVE if ij[0] == ij[1] else p["check"].bounds, start=float(d.P_init[k]),
                array=("P_init", _ij(ij), p["doc"]))
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
    variable_step = False   # a sampled-data block: its sample period is the communication step
    #: FMI 3.0: its sample period as a periodic input clock (fmi3_base.py): name, interval [s], description
    sample_clock = ("sample", 0.002, "sample clock (period 2 ms): the controller takes its inputs (the measurements) and updates every output at each tick")

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
        self.declare(parameters_of(ControllerParams(), expanded=("W_init", "P_init")) + _weight_parameters() + _INPUTS + outputs)
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
