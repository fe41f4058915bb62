"""WmrSensor: the sensor chain component (quantised encoders, increment velocity (42), filter (43),
wheel angle) as an FMI 2.0 co-simulation slave.  All math is in components/sensor.py.

exit_initialization_mode calls Sensor.reset(alpha1, alpha2) with the input values;
do_step(t, h) = Sensor.step(h, alpha1, alpha2): the sensor samples its inputs at the END of the step
(a Gauss-Seidel master sets them from the plant's outputs at t + h), so every output of wheel i depends
directly on alpha_i (direct feedthrough), and on nothing of the other wheel.

fmus/build.py bundles this script with a copy of the components under a unique package name and
rewrites the two ``wmr_cosim`` imports below to it.
"""
from __future__ import annotations

from wmr_cosim.components.sensor import SENSOR_OUTPUTS, Sensor, SensorParams
from wmr_cosim.fmus.fmi_base import Var, WmrSlave, parameters_of

_INPUTS = [
    Var("alpha1", "Real", "input", "true wheel angle alpha1 at the end of the step", unit="rad", start=0.0),
    Var("alpha2", "Real", "input", "true wheel angle alpha2 at the end of the step", unit="rad", start=0.0),
]
_OUT = {  # SENSOR_OUTPUTS name: (kind, unit, description, wheel)
    "alpha_m1": ("Real", "rad", "measured wheel angle of wheel 1", 1),
    "alpha_m2": ("Real", "rad", "measured wheel angle of wheel 2", 2),
    "alpha_dot_m1": ("Real", "rad/s", "filtered wheel speed of wheel 1 (43)", 1),
    "alpha_dot_m2": ("Real", "rad/s", "filtered wheel speed of wheel 2 (43)", 2),
    "alpha_dot_inc1": ("Real", "rad/s", "increment velocity (42) of wheel 1 over the last step", 1),
    "alpha_dot_inc2": ("Real", "rad/s", "increment velocity (42) of wheel 2 over the last step", 2),
    "count1": ("Integer", None, "encoder 1 count [counts]", 1),
    "count2": ("Integer", None, "encoder 2 count [counts]", 2),
}


class WmrSensor(WmrSlave):
    description = "Sensor chain of the two drive wheels: quantised encoders, increment velocity (42), filter (43), wheel angle"
    variable_step = False   # a sampled-data block: its sample period is the communication step
    #: FMI 3.0: its sample period as a periodic input clock (fmi3_base.py): name, interval [s], description
    sample_clock = ("sample", 0.002, "sample clock (period 2 ms): the sensor samples its inputs alpha1, alpha2 and updates every output at each tick")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        outputs = []
        for n in SENSOR_OUTPUTS:
            kind, unit, desc, wheel = _OUT[n]
            own = (f"alpha{wheel}",)
            outputs.append(Var(n, kind, "output", desc, unit=unit, variability="discrete", deps=own,
                               init_deps=own if kind == "Integer" else ()))
        self.declare(parameters_of(SensorParams()) + _INPUTS + outputs)
        self._build()

    def _build(self):
        sensor = Sensor(SensorParams(**self.parameter_values()))
        v = self._vals
        sensor.reset(v[self._in0], v[self._in0 + 1])
        self._comp = sensor
        self._sstep = sensor.step
        v[self._out0:self._out1] = sensor.outputs()

    def _step(self, t, h):
        v = self._vals
        i = self._in0
        v[self._out0:self._out1] = self._sstep(h, v[i], v[i + 1])
