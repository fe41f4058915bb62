"""What the master knows of an FMU before running it: its model description, variables and units, its
binary (read from its bytes), the safe extraction of archives, the kind of a file given to the master."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .archive import DEFAULT_LIMITS, ArchiveLimits, LimitOverrides, check_archive, limit_overrides, safe_extract
    from .binary import PYTHON_FMU, library_problem, runs_python
    from .description import CO_SIMULATION, MODEL_EXCHANGE, FmuModel, Variable, fmi_version, load_model
    from .kinds import FileKind, file_kind, named_kind
    from .units import Unit, conversion, lookup, units_of

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
