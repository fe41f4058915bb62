"""WmrPlant: the plant component (Maggi dynamics (34)-(36) of the drive wheels, pose (23)-(24)) as an
FMI 2.0 co-simulation slave.  All math is in components/plant.py, and the parameters' units, ranges and
descriptions are in PlantParams' field declarations; this file only declares the inputs and outputs.

do_step(t, h) = Plant.step(t, h, u1, u2, tau_d1, tau_d2): the inputs are held over the step and the
outputs are the state at t + h, so no output depends directly on an input (empty dependencies).

fmus/build.py bundles this script with a copy of the components under a unique package name and
rewrites the two ``wmr_cosim`` imports below to it.
"""
from __future__ import annotations

from wmr_cosim.components.plant import PLANT_OUTPUTS, Plant, PlantParams
from wmr_cosim.fmus.fmi_base import Var, WmrSlave, parameters_of

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
        self.declare(parameters_of(PlantParams()) + _INPUTS + outputs)
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
