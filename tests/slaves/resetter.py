"""An FMU that, like 20-sim's, resets its parameters in fmi2SetupExperiment, and logs one message of status
OK at every step (a verbose FMU); its output y is the parameter p."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Resetter(Fmi2Slave):
    author = "tests"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.p = 1.0
        self.y = 1.0
        self.register_variable(Real("p", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def setup_experiment(self, start_time, stop_time, tolerance):
        self.p = 1.0  # parameters back to their defaults, as 20-sim FMUs do

    def exit_initialization_mode(self):
        self.y = self.p

    def do_step(self, current_time, step_size):
        self.log(f"step at t = {current_time}")
        self.y = self.p
        return True
