"""The run's event table (summary.json's ``events``, the result's ``events``): every event, in the order
of time, with where it came from and what it did.  Each entry has ``time`` [s], ``source`` (the
scenario's ``events[i]``, or the instance), ``kind`` and ``what`` (one line):

- ``scenario``: a timed event of the scenario, and ``condition``: one whose condition fired (their
  entries also keep ``event`` (the index), ``action``, ``variable``, ``value``; a condition's ``when``
  and ``condition_time``, the time it became true);
- ``time``, ``state``, ``step``, ``input``: the events of a model exchange instance, handled by the
  master's integrator (a time event the FMU scheduled, an event indicator crossing zero,
  completedIntegratorStep asking for event mode, new inputs moving an indicator across zero);
- ``terminate``: an FMU ended the simulation;
- a value a driver gave while the run went (:meth:`cosim.runtime.execution.Execution.give`): the kind and
  the source are the driver's (``live`` for the live view), with ``action``, ``variable``, ``value``.

At most :data:`MAX_ENTRIES` entries are kept (the first ones); the summary counts those left out."""
from __future__ import annotations

from typing import Any

from ..plan.records import EventPlan

#: The most entries a table keeps (an FMU with a time event every millisecond has 50,000 in 50 s).
MAX_ENTRIES = 10_000

#: What each kind of instance event is, in words.
INSTANCE_KINDS = {
    "time": "time event (the time the FMU scheduled)",
    "state": "state event (an event indicator crossed zero)",
    "step": "step event (completedIntegratorStep asked for event mode)",
    "input": "input event (new inputs moved an event indicator across zero)",
}


def scenario_entry(ev: EventPlan, t: float, fired: float | None) -> dict[str, Any]:
    """The entry of the scenario's event ``ev`` acting at ``t`` [s]; ``fired``: the time [s] its condition
    became true (None for a timed event)."""
    entry: dict[str, Any] = {"time": t, "source": f"events[{ev.index}]",
                             "kind": "scenario" if fired is None else "condition", "event": ev.index,
                             "action": ev.action}
    what = ev.action
    if ev.ref is not None:
        entry["variable"] = ev.ref
        what += f" {ev.ref}"
    if ev.value is not None:
        entry["value"] = ev.value
        what += f" = {ev.value!r}"
    if fired is not None:
        entry["when"] = ev.when
        entry["condition_time"] = fired
        what += f" (when {ev.when}: true at t = {fired:.9g} s)"
    entry["what"] = what
    return entry


def given_entry(ev: EventPlan, t: float, source: str) -> dict[str, Any]:
    """The entry of the event ``ev`` a driver (``source``, e.g. ``live``) gave while the run went, acting at
    ``t`` [s]: as a timed event's entry, its source and kind the driver's."""
    entry = scenario_entry(ev, t, None)
    del entry["event"]
    entry.update(source=source, kind=source)
    return entry


def instance_entries(name: str, handled: list[tuple[float, str]]) -> list[dict[str, Any]]:
    """The entries of the events instance ``name`` handled, (time [s], kind) each."""
    return [{"time": t, "source": name, "kind": kind, "what": INSTANCE_KINDS.get(kind, kind)} for t, kind in handled]


def ended_entry(name: str, t: float) -> dict[str, Any]:
    """The entry of FMU ``name`` ending the simulation at ``t`` [s]."""
    return {"time": t, "source": name, "kind": "terminate", "what": "the FMU ended the simulation"}


def table(scenario_log: list[dict[str, Any]], instances: list[dict[str, Any]]) -> tuple[list[dict[str, Any]], int]:
    """The scenario's entries and the instances' in the order of time (at one time, the instances'
    first: an event an FMU handled at t ended the step that reached t, before the scenario's events act
    on the step from t), at most :data:`MAX_ENTRIES`; and how many were left out."""
    merged = sorted(instances + scenario_log, key=lambda e: e["time"])
    return merged[:MAX_ENTRIES], max(0, len(merged) - MAX_ENTRIES)
