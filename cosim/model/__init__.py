"""What the master knows of an FMU before running it: its model description, variables and units, its
binary (read from its bytes), the safe extraction of archives, the kind of a file given to the master."""
from __future__ import annotations

from .archive import DEFAULT_LIMITS, ArchiveLimits, LimitOverrides, check_archive, limit_overrides, safe_extract
from .binary import library_problem
from .description import CO_SIMULATION, MODEL_EXCHANGE, FmuModel, Variable, fmi_version, load_model
from .kinds import FileKind, file_kind, named_kind
from .units import Unit, conversion, lookup, units_of

__all__ = ["ArchiveLimits", "check_archive", "CO_SIMULATION", "conversion", "DEFAULT_LIMITS", "file_kind", "FileKind", "fmi_version", "FmuModel", "library_problem", "limit_overrides", "LimitOverrides", "load_model", "lookup", "MODEL_EXCHANGE", "named_kind", "safe_extract", "Unit", "units_of", "Variable"]
