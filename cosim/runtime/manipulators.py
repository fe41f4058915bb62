"""The manipulators: what changes the system's variables between steps (libcosim's ``manipulator``):
the scenario's timed events, its condition events, and the script's set/release.

A manipulator is an object behind :class:`Manipulator`.  Its contract:

1. :meth:`~Manipulator.started` is called once, after initialisation, before the first step.
2. :meth:`~Manipulator.next_action` gives the first step k' >= k before which it will act, or None; the
   execution ends the segment that starts at step k there, so an action is never late and the loop
   runs uninterrupted between actions.
3. :meth:`~Manipulator.act` is called before every segment, from step k; it acts on what is due then and
   returns whether the copies of some Real input changed (the algorithm then takes the new ones).
4. ``per_step`` true: the manipulator must see every step (:meth:`~Manipulator.stepped` after each one,
   the segments then one step long); false: it costs nothing inside the loop.
5. A stop event raises :class:`EventStop` from :meth:`~Manipulator.act`; the execution ends the run
   cleanly there.

All of them act through one :class:`Actuator`, which knows how a value reaches a variable (the wiring's
copies for a Real input or an output feeding connections; the FMU for a parameter or an input no
connection drives) and writes the event log.

Tabulated inputs (CSV tables, ``cosim.scenario.inputs``) are not a manipulator: their values change at every step,
so a manipulator would make every segment one step long; they are put in place inside the algorithm's
loop instead (``InstanceIO.feed``, built by ``wiring.table_feeder``), at no cost to a plan without them.
"""
from __future__ import annotations

import heapq
import math
from typing import TYPE_CHECKING, Any, Callable

from ..messages.errors import CosimError
from ..model.description import Variable
from ..plan.records import EventPlan, Plan
from ..plan.wiring import Wiring, discrete_event_value
from ..results.event_log import given_entry, scenario_entry
from ..scenario.condition import compile_condition
from .views import Manipulable

if TYPE_CHECKING:
    from ..instances.contract import FmuInstance


class EventStop(Exception):
    """A stop event (``events[index]``) ended the run before the step from t (step k)."""

    def __init__(self, index: int, t: float, k: int) -> None:
        super().__init__(index, t, k)
        self.index, self.t, self.k = index, t, k


class Actuator:
    """How a value reaches a variable between steps, and the event log."""

    def __init__(self, plan: Plan, instances: dict[str, "FmuInstance"], wiring: Wiring) -> None:
        self.plan, self.instances, self.wiring = plan, instances, wiring
        self.log: list[dict[str, Any]] = []            # every event that acted (see .event_log)
        self.discrete: dict[tuple[str, int], Any] = {}  # values set on non-Real inputs, held until the next

    def event(self, ev: EventPlan, k: int, t: float, fired: float | None, source: str | None = None) -> bool:
        """One event's action before the step from t_k [s], written to the event log; whether the copies
        changed.  ``fired``: the time its condition became true; ``source``: a driver's event (its entry's
        source and kind), not one of the scenario's."""
        self.log.append(scenario_entry(ev, t, fired) if source is None else given_entry(ev, t, source))
        if ev.action == "stop":
            raise EventStop(ev.index, t, k)
        assert ev.instance is not None and ev.var is not None
        if ev.action == "set":
            self.instances[ev.instance].set_values([(ev.var, ev.value)])
            return False
        if ev.var.type == "Real":
            if ev.action == "override" and ev.var.causality == "input" and \
                    not self.wiring.is_wired(ev.instance, ev.var.vr, "input"):
                # (an input no copy carries: a driver's override, the FMU holding it; the scenario's events
                # on such inputs have copies of held values from the plan on)
                return self.set(ev.instance, ev.var, ev.value)
            return self.wiring.apply(ev)
        self._discrete_event(ev)
        return False

    def _discrete_event(self, ev: EventPlan) -> None:
        """An event on an Integer, Enumeration, Boolean or String input: set now, held until the next."""
        assert ev.instance is not None and ev.var is not None
        value = discrete_event_value(self.plan, self.discrete, ev)
        if value is not None:
            self.instances[ev.instance].set_values([(ev.var, value)])

    def set(self, inst: str, var: Variable, value: Any) -> bool:
        """Set a variable between steps (the value already checked against its type and range): a tunable
        parameter; a Real input or an output feeding connections is overridden until :meth:`release`; an
        input no connection or table drives is set on the FMU, which holds it.  Whether the copies changed."""
        ref = f"{inst}.{self.plan.instances[inst].our_name(var)}"
        if var.causality == "parameter":
            if var.variability != "tunable":
                raise CosimError(f"{ref} is a {var.variability} parameter: only tunable parameters change during "
                                 "a run")
            self.instances[inst].set_values([(var, value)])
            return False
        if var.is_float64 and var.causality in ("input", "output") and self.wiring.is_wired(inst, var.vr,
                                                                                          var.causality):
            return self.wiring.act(inst, var.vr, var.causality, "override", value)
        if var.causality == "input":
            if any(c.dst == inst and c.dst_var.vr == var.vr for c in self.plan.connections) or \
                    any(ip.instance == inst and ip.var.vr == var.vr for ip in self.plan.inputs):
                raise CosimError(f"{ref} is driven by a connection or a table: it cannot be set")
            self.instances[inst].set_values([(var, value)])
            self.discrete[(inst, var.vr)] = value
            return False
        if var.causality == "output":
            raise CosimError(f"{ref} is an output that feeds no connection: setting it would change nothing")
        raise CosimError(f"{ref} is {var.causality}: only inputs, outputs feeding connections and tunable "
                         "parameters can be set between steps")

    def bias(self, inst: str, var: Variable, value: float) -> bool:
        """Add ``value`` to a connected Real input or an output feeding connections until :meth:`release`
        (on top of a bias or an override before); whether the copies changed."""
        if not (var.is_float64 and var.causality in ("input", "output") and self.wiring.is_wired(inst, var.vr,
                                                                                              var.causality)):
            ref = f"{inst}.{self.plan.instances[inst].our_name(var)}"
            raise CosimError(f"{ref} is no Real input or output on a connection: only those take a bias")
        return self.wiring.act(inst, var.vr, var.causality, "bias", value)

    def release(self, inst: str, var: Variable) -> bool:
        """End an override set by :meth:`set` or a :meth:`bias` (the value follows its source again); whether
        the copies changed."""
        if var.is_float64 and self.wiring.is_wired(inst, var.vr, var.causality):
            return self.wiring.act(inst, var.vr, var.causality, "reset", None)
        return False


class Manipulator:
    """What changes variables between steps (see the module's contract)."""

    per_step = False

    def started(self, ex: Manipulable) -> None:
        pass

    def next_action(self, k: int) -> int | None:
        return None

    def act(self, ex: Manipulable, k: int) -> bool:
        return False

    def stepped(self, ex: Manipulable, k: int) -> None:
        pass


class TimedEvents(Manipulator):
    """Events at given times, each before the step from its communication point: the scenario's, or
    (``source``) those a driver gives while the run goes (:meth:`.execution.Execution.give` appends them to
    ``events``), their entries in the event log the driver's."""

    def __init__(self, actuator: Actuator, events: list[EventPlan], source: str | None = None) -> None:
        self.actuator, self.events, self.i, self.source = actuator, events, 0, source

    def next_action(self, k: int) -> int | None:
        return self.events[self.i].step if self.i < len(self.events) else None

    def act(self, ex: Manipulable, k: int) -> bool:
        changed = False
        while self.i < len(self.events) and self.events[self.i].step <= k:
            changed = self.actuator.event(self.events[self.i], k, ex.clock.time(k), None, self.source) or changed
            self.i += 1
        return changed


class ConditionEvents(Manipulator):
    """The scenario's events on conditions (``when``), evaluated at every communication point: an event
    whose condition has become true acts ``delay`` later, before the step from the first communication
    point at or after it."""

    def __init__(self, actuator: Actuator, events: list[EventPlan]) -> None:
        self.actuator, self.events = actuator, events
        self.per_step = bool(events)
        self.preds: list[Callable[[float], bool]] = []
        self.state = [False] * len(events)
        self.fired = [False] * len(events)
        self.pending: list[tuple[int, int, EventPlan, float]] = []   # (step, sequence, event, time it fired)
        self.seq = 0

    def started(self, ex: Manipulable) -> None:
        """The predicates compiled; the conditions at the start time (an event whose condition holds there
        fires before the first step)."""
        for ev in self.events:
            read = {ref: ex.reader(inst, var) for ref, (inst, var) in ev.reads.items()}
            self.preds.append(compile_condition(ev.condition, read))
        self.stepped(ex, 0)

    def stepped(self, ex: Manipulable, k: int) -> None:
        clock = ex.clock
        t = clock.time(k)
        for j, (ev, pred) in enumerate(zip(self.events, self.preds)):
            now = pred(t)
            if now and not self.state[j] and not (ev.trigger == "once" and self.fired[j]):
                self.fired[j] = True
                kd = k if ev.delay == 0 else int(math.ceil((t + ev.delay - clock.start) / clock.step - 1e-9))
                if kd < clock.n_steps:
                    self.seq += 1
                    heapq.heappush(self.pending, (kd, self.seq, ev, t))
            self.state[j] = now

    def next_action(self, k: int) -> int | None:
        return self.pending[0][0] if self.pending else None

    def act(self, ex: Manipulable, k: int) -> bool:
        changed = False
        while self.pending and self.pending[0][0] <= k:
            _, _, ev, fired = heapq.heappop(self.pending)
            changed = self.actuator.event(ev, k, ex.clock.time(k), fired) or changed
        return changed


class ScriptChanges(Manipulator):
    """The script's set and release between steps (the Python API): applied at once on the FMU or the
    copies; the copies taken by the algorithm before the next step."""

    def __init__(self, actuator: Actuator) -> None:
        self.actuator, self.dirty = actuator, False

    def set(self, inst: str, var: Variable, value: Any) -> None:
        self.dirty = self.actuator.set(inst, var, value) or self.dirty

    def bias(self, inst: str, var: Variable, value: float) -> None:
        self.dirty = self.actuator.bias(inst, var, value) or self.dirty

    def release(self, inst: str, var: Variable) -> None:
        self.dirty = self.actuator.release(inst, var) or self.dirty

    def act(self, ex: Manipulable, k: int) -> bool:
        changed, self.dirty = self.dirty, False
        return changed
