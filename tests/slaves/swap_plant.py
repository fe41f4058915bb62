"""A plant FMU "from another toolchain" for the swap test: the same physics (it wraps the project's
Plant component), but its own variable names, and its wheel angles in degrees (declared by the scenario,
since pythonfmu 0.7 writes no units)."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Real

from wmr_cosim.components.plant import Plant


class SwapPlant(Fmi2Slave):
    author = "tests"
    description = "wheeled robot plant with angles in degrees"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.torque_right = 0.0
        self.torque_left = 0.0
        self.phi_right_deg = 0.0
        self.phi_left_deg = 0.0
        self.pos_x = 0.0
        self.pos_y = 0.0
        self.heading = 0.0
        for name in ("torque_right", "torque_left"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("phi_right_deg", "phi_left_deg", "pos_x", "pos_y", "heading"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))
        self.plant = None

    def exit_initialization_mode(self):
        self.plant = Plant()

    def do_step(self, current_time, step_size):
        o = self.plant.step(current_time, step_size, self.torque_right, self.torque_left)
        self.phi_right_deg = math.degrees(o[0])
        self.phi_left_deg = math.degrees(o[1])
        self.pos_x, self.pos_y, self.heading = o[4], o[5], o[6]
        return True
