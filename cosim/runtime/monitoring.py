"""The scenario's requirements monitored as the run goes (:mod:`cosim.requirements`): each one's online
monitor sampled at every communication point (the start included), a requirement with
``on_violation = "stop"`` ending the run with status "violated" at the communication point at which its
violation is known, the verdicts and the robustness over time at the end."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..plan.records import RequirementPlan
from ..requirements.monitor import Monitor
from ..results.status import RunStatus
from .manipulators import Manipulator
from .views import Manipulable


class RequirementMonitors(Manipulator):
    """A monitor per requirement, compiled over readers of the variables its formula names."""

    def __init__(self, requirements: list[RequirementPlan]) -> None:
        self.requirements = requirements
        self.per_step = True
        self.monitors: list[Monitor] = []

    def started(self, ex: Manipulable) -> None:
        for r in self.requirements:
            read = {ref: ex.reader(inst, var) for ref, (inst, var) in r.reads.items()}
            self.monitors.append(Monitor(r.name, r.checked, read, ex.clock.step))
        self.stepped(ex, 0)

    def stepped(self, ex: Manipulable, k: int) -> None:
        t = ex.clock.time(k)
        for m in self.monitors:   # every monitor sees the point, also the one after a requirement that stops
            m.sample(t)
        for r, m in zip(self.requirements, self.monitors):
            if m.violated_now and r.on_violation == "stop":
                v = m.verdict
                rob = "" if v.robustness is None else f", robustness {v.robustness:.6g}"
                ex.stop(f"requirement {r.name!r} violated at t = {v.first_violation:.6g} s (known at t = {t:.6g} s"
                        f"{rob})", RunStatus.VIOLATED)
                return

    def so_far(self) -> list[dict[str, Any]]:
        """Each requirement's verdict as its monitor has it at the last communication point sampled (what
        :meth:`finish` gives at the end, before the run has ended: an ``always`` not yet violated is
        undecided, its robustness the lowest value judged so far, in the unit of its comparison)."""
        out = []
        for r, m in zip(self.requirements, self.monitors):
            unit = sorted(set(r.checked.unit_of.values()) - {""})
            out.append({**m.verdict.as_dict(), "on_violation": r.on_violation, "description": r.description,
                        "unit": str(unit[0]) if len(unit) == 1 else None})
        return out

    def finish(self, status: RunStatus) -> list[dict[str, Any]]:
        """The verdicts of the run that ended with ``status`` (summary.json's ``requirements``): each monitor
        told the run has ended, and whether it reached its planned stop (status ok: an unbounded ``always``
        can hold; a run that ended early leaves it undecided)."""
        out = []
        for r, m in zip(self.requirements, self.monitors):
            m.finish(covered=status == RunStatus.OK)
            v = m.verdict.as_dict()
            unit = sorted(set(r.checked.unit_of.values()) - {""})
            out.append({**v, "on_violation": r.on_violation, "description": r.description,
                        "unit": unit[0] if len(unit) == 1 else None, "variables": list(r.checked.variables)})
        return out

    def signals(self) -> dict[str, np.ndarray]:
        """Each requirement's robustness over time (of the operand of its outermost always or eventually)
        by communication point, NaN where a window the run cut leaves it unknown."""
        return {r.name: m.signal() for r, m in zip(self.requirements, self.monitors)}
