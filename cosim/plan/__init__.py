"""A scenario resolved against its FMUs: every check before the first step, the plan's records, the
coupling structure, the wiring of inputs to outputs, the plan as an SSP archive and back."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .loops import describe_coupling
    from .records import ConnectionPlan, Coupling, EventPlan, InstancePlan, Plan, RecordPlan
    from .resolution import PARAMETERS, resolve, variable
    from .ssp import export_remarks, export_ssp, is_ssp, load_ssp
    from .wiring import RowLayout, Wiring

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "loops": ["describe_coupling"],
    "records": ["ConnectionPlan", "Coupling", "EventPlan", "InstancePlan", "Plan", "RecordPlan"],
    "resolution": ["PARAMETERS", "resolve", "variable"],
    "ssp": ["export_remarks", "export_ssp", "is_ssp", "load_ssp"],
    "wiring": ["RowLayout", "Wiring"],
})
