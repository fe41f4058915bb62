"""Real-time pacing: each communication step is held until its due time on the wall clock, at ``factor``
times real time (1 = real time, 10 = ten times faster).  Steps are never skipped: a step that finishes after
its due time is an overrun, counted with how late it was; the steps after it run without waiting until
the run is back on schedule (the due times are absolute, so lateness never accumulates).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

from ..messages.words import count


@dataclass
class Pacer:
    """Due time of the step ending at simulated time t: ``wall0 + (t - t_start) / factor`` [s]."""

    factor: float
    overruns: int = 0
    late_max_s: float = 0.0
    late_sum_s: float = 0.0
    steps: int = 0
    _wall0: float | None = None
    _t_start: float = 0.0
    _clock: Callable[[], float] = field(default=time.perf_counter, repr=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.factor, (int, float)) and math.isfinite(self.factor) and self.factor > 0):
            raise ValueError(f"real-time factor {self.factor!r}: must be a number > 0")

    def start(self, t_start: float) -> None:
        """The wall clock of simulated time ``t_start`` [s] is now."""
        self._wall0, self._t_start = self._clock(), float(t_start)

    def wait(self, t: float) -> None:
        """A step ending at simulated time ``t`` [s] is done: sleep until its due time, or count it late."""
        if self._wall0 is None:
            self.start(t)
            return
        self.steps += 1
        due = self._wall0 + (t - self._t_start) / self.factor
        now = self._clock()
        if now > due:
            late = now - due
            self.overruns += 1
            self.late_sum_s += late
            self.late_max_s = max(self.late_max_s, late)
            return
        while now < due:   # sleep() may wake early on a signal: sleep again until due
            time.sleep(due - now)
            now = self._clock()

    def summary(self) -> dict[str, float]:
        """The figures summary.json reports under ``real_time``."""
        return {"factor": self.factor, "steps": self.steps, "overruns": self.overruns,
                "late_max_s": round(self.late_max_s, 6),
                "late_mean_s": round(self.late_sum_s / self.overruns, 6) if self.overruns else 0.0}

    def describe(self) -> str:
        """One line for the end of a run."""
        if not self.overruns:
            return f"real time x{self.factor:g}: no overruns in {count(self.steps, 'step')}"
        return (f"real time x{self.factor:g}: {self.overruns} of {self.steps} steps finished late "
                f"(by up to {self.late_max_s * 1e3:.3g} ms, {self.late_sum_s / self.overruns * 1e3:.3g} ms on average)")
