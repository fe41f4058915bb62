"""A run's results: the recording written as the run goes, the results folder and its files (the one
table of result formats, CSV, MAT, summary.json), the event table, how a run ended."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .folder import ResultsFolder, RunResult
    from .formats import RECORDING, RESULT_FORMATS, ResultFormat, format_flags, format_help
    from .matfile import MatLayout, layout, write_mat
    from .reading import Recording, ResultsError, read_json, read_signals
    from .recording import OutputLock, atomic_write, make_folder, write_csv, write_json
    from .status import RunStatus

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "folder": ["ResultsFolder", "RunResult"],
    "formats": ["RECORDING", "RESULT_FORMATS", "ResultFormat", "format_flags", "format_help"],
    "matfile": ["MatLayout", "layout", "write_mat"],
    "reading": ["Recording", "ResultsError", "read_json", "read_signals"],
    "recording": ["OutputLock", "atomic_write", "make_folder", "write_csv", "write_json"],
    "status": ["RunStatus"],
})
