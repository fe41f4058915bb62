"""WmrPlant: the plant component (Maggi dynamics (34)-(36) of the drive wheels, pose (23)-(24)) as an
FMI 2.0 co-simulation slave.  All math is in components/plant.py; this file only declares variables.

do_step(t, h) = Plant.step(t, h, u1, u2, tau_d1, tau_d2): the inputs are held over the step and the
outputs are the state at t + h, so no output depends directly on an input (empty dependencies).

fmus/build.py bundles this script with a copy of the components under a unique package name and
rewrites the two ``wmr_cosim`` imports below to it.
"""
from __future__ import annotations

from wmr_cosim.components.plant import PLANT_OUTPUTS, Plant, PlantParams
from wmr_cosim.fmus.fmi_base import FINITE, NON_NEGATIVE, POSITIVE, Var, WmrSlave, parameters_of

_P = {  # PlantParams field: (unit, (min, max), description) / ((min, max), description) / (description,)
    "a1": ("kg.m2", FINITE, "Maggi parameter a1 of M (35); a1..a3 must make M positive definite"),
    "a2": ("kg.m2", FINITE, "Maggi parameter a2 of M (35)"),
    "a3": ("kg.m2", FINITE, "Maggi parameter a3 of M (35)"),
    "a4": ("kg.m2", NON_NEGATIVE, "Maggi parameter a4 of C (35)"),
    "a5": ("N.m", NON_NEGATIVE, "rolling-resistance parameter a5 of friction (36), wheel 1"),
    "a6": ("N.m", NON_NEGATIVE, "rolling-resistance parameter a6 of friction (36), wheel 2"),
    "cF": ("s/rad", POSITIVE, "slope cF of friction (36)"),
    "r": ("m", POSITIVE, "wheel radius r"),
    "l1": ("m", POSITIVE, "half axle length l1"),
    "substeps": ((1, 1_000_000), "RK4 substeps per communication step"),
    "friction_form": ("shape of friction (36): tanh (default, 2 a tanh(cF w/2)) or printed (the paper's exp form)",),
    "x0": ("m", FINITE, "initial x of point A"),
    "y0": ("m", FINITE, "initial y of point A"),
    "beta0": ("rad", FINITE, "initial frame angle beta"),
    "foam_da1": ("N.m", FINITE, "foam: rise of a5 (wheel 1) at full foam level (friction change; tunable)"),
    "foam_da2": ("N.m", FINITE, "foam: rise of a6 (wheel 2) at full foam level (friction change; tunable)"),
    "foam_ramp": ("s", NON_NEGATIVE, "foam: time the foam level ramps from 0 to 1"),
    "foam_on_time": ("foam: reached at time foam_t_on",),
    "foam_t_on": ("s", FINITE, "foam: time it is reached (if foam_on_time)"),
    "foam_on_region": ("foam: reached when point A enters the rectangle foam_x/y_min..max",),
    "foam_x_min": ("m", FINITE, "foam rectangle: x min"),
    "foam_x_max": ("m", FINITE, "foam rectangle: x max"),
    "foam_y_min": ("m", FINITE, "foam rectangle: y min"),
    "foam_y_max": ("m", FINITE, "foam rectangle: y max"),
    "foam_bump": ("N.m", NON_NEGATIVE, "foam: further rise of a5 and a6 during the bump at the foam's edge (0 = off, the default)"),
    "foam_bump_time": ("s", NON_NEGATIVE, "foam: duration of the bump from the moment the foam is reached"),
}
TUNABLE = ("foam_da1", "foam_da2")

_INPUTS = [
    Var("u1", "Real", "input", "drive torque M1 of wheel 1 (right), held over the step", unit="N.m", start=0.0),
    Var("u2", "Real", "input", "drive torque M2 of wheel 2 (left), held over the step", unit="N.m", start=0.0),
    Var("tau_d1", "Real", "input", "external disturbance torque on wheel 1 (opposes positive rotation)",
        unit="N.m", start=0.0),
    Var("tau_d2", "Real", "input", "external disturbance torque on wheel 2 (opposes positive rotation)",
        unit="N.m", start=0.0),
]
_OUT = {  # PLANT_OUTPUTS name: (unit, description)
    "alpha1": ("rad", "wheel angle alpha1 (wheel 1, right)"),
    "alpha2": ("rad", "wheel angle alpha2 (wheel 2, left)"),
    "alpha_dot1": ("rad/s", "wheel speed alpha_dot1"),
    "alpha_dot2": ("rad/s", "wheel speed alpha_dot2"),
    "x_A": ("m", "x of point A"),
    "y_A": ("m", "y of point A"),
    "beta": ("rad", "frame angle beta"),
    "dF1": ("N.m", "true disturbance torque on wheel 1 over the last step: foam + tau_d1"),
    "dF2": ("N.m", "true disturbance torque on wheel 2 over the last step: foam + tau_d2"),
    "foam_level": ("1", "foam level lambda(t) in [0, 1]"),
}


class WmrPlant(WmrSlave):
    description = "Wheeled mobile robot (Pioneer 2-DX): Maggi dynamics (34)-(36) of the drive wheels and pose (23)-(24), RK4"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        outputs = [Var(n, "Real", "output", _OUT[n][1], unit=_OUT[n][0], deps=(), init_deps=())
                   for n in PLANT_OUTPUTS]
        self.declare(parameters_of(PlantParams(), _P, TUNABLE) + _INPUTS + outputs)
        self._build()

    def _build(self):
        plant = Plant(PlantParams(**self.parameter_values()))
        plant.t = self._t0
        self._comp = plant
        self._pstep = plant.step
        self._vals[self._out0:self._out1] = plant.outputs()

    def _retune(self):
        self._comp.p = PlantParams(**self.parameter_values())  # foam_da1, foam_da2 are read at every step

    def _step(self, t, h):
        v = self._vals
        i = self._in0
        u1, u2, d1, d2 = v[i], v[i + 1], v[i + 2], v[i + 3]
        s = u1 + u2 + d1 + d2
        if s - s != 0.0:
            raise ValueError(f"non-finite input: u1 = {u1!r}, u2 = {u2!r}, tau_d1 = {d1!r}, tau_d2 = {d2!r} N.m")
        v[self._out0:self._out1] = self._pstep(t, h, u1, u2, d1, d2)
