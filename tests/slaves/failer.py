"""An FMU that fails on purpose at t >= t_fail: mode 'discard' (do_step returns False after logging),
'fatal' (an uncaught exception: fmi2Fatal), 'nan' (a NaN output), 'ok' (never fails)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status


class Failer(Fmi2Slave):
    author = "tests"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.mode = "discard"
        self.t_fail = 0.5
        self.x = 0.0
        self.y = 0.0
        self.register_variable(String("mode", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self.register_variable(Real("t_fail", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self.register_variable(Real("x", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        if current_time >= self.t_fail - 1e-12:
            if self.mode == "discard":
                self.log(f"deliberate failure at t = {current_time}", Fmi2Status.error)
                return False
            if self.mode == "fatal":
                raise RuntimeError("deliberate fatal error")
            if self.mode == "nan":
                self.y = float("nan")
                return True
        self.y = self.x + 1.0
        return True
