"""What the master knows of an FMU before running it: its model description, variables and units, its
binary (read from its bytes), the safe extraction of archives, the kind of a file given to the master."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .archive import DEFAULT_LIMITS, ArchiveLimits, LimitOverrides, check_archive, limit_overrides, safe_extract
    from .binary import PYTHON_FMU, library_problem, runs_python
    from .description import CO_SIMULATION, MODEL_EXCHANGE, FmuModel, Variable, fmi_version, load_model
    from .kinds import FileKind, file_kind, named_kind
    from .units import Unit, conversion, lookup, units_of

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "archive": ["DEFAULT_LIMITS", "ArchiveLimits", "LimitOverrides", "check_archive", "limit_overrides",
                "safe_extract"],
    "binary": ["PYTHON_FMU", "library_problem", "runs_python"],
    "description": ["CO_SIMULATION", "MODEL_EXCHANGE", "FmuModel", "Variable", "fmi_version", "load_model"],
    "kinds": ["FileKind", "file_kind", "named_kind"],
    "units": ["Unit", "conversion", "lookup", "units_of"],
})
