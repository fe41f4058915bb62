"""A run's results: the recording written as the run goes, the results folder and its files (the one
table of result formats, CSV, MAT, summary.json), the event table, how a run ended."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .folder import ResultsFolder, RunResult
    from .formats import RECORDING, RESULT_FORMATS, ResultFormat, format_flags, format_help
    from .matfile import MatLayout, layout, write_mat
    from .reading import Recording, ResultsError, read_json, read_signals
    from .recording import OutputLock, atomic_write, make_folder, write_csv, write_json
    from .status import RunStatus

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
