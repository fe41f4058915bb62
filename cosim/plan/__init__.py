"""A scenario resolved against its FMUs: every check before the first step, the plan's records, the
coupling structure, the wiring of inputs to outputs, the plan as an SSP archive and back."""
from __future__ import annotations

from .loops import describe as describe_coupling
from .records import ConnectionPlan, Coupling, EventPlan, InstancePlan, Plan, RecordPlan
from .resolution import resolve
from .ssp import export_remarks, export_ssp, is_ssp, load_ssp
from .wiring import RowLayout, Wiring

__all__ = ["ConnectionPlan", "Coupling", "describe_coupling", "EventPlan", "export_remarks", "export_ssp", "InstancePlan", "is_ssp", "load_ssp", "Plan", "RecordPlan", "resolve", "RowLayout", "Wiring"]
