"""A scenario resolved against its FMUs: every check before the first step, the plan's records, the
coupling structure, the wiring of inputs to outputs, the plan as an SSP archive and back, the plan as one FMU (a
container)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .container import export_fmu
    from .loops import describe_coupling
    from .records import ConnectionPlan, Coupling, EventPlan, InstancePlan, Plan, RecordPlan
    from .resolution import PARAMETERS, resolve, variable
    from .ssp import export_remarks, export_ssp, is_ssp, load_ssp
    from .wiring import RowLayout, Wiring

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
