"""A run's results: the recording written as the run goes, the results folder and its files (CSV, MAT,
summary.json), the event table, how a run ended."""
from __future__ import annotations

from .folder import ResultsFolder, RunResult
from .matfile import MatLayout, layout, write_mat
from .recording import OutputLock, atomic_write, make_folder, write_csv, write_json
from .status import RunStatus

__all__ = ["atomic_write", "layout", "make_folder", "MatLayout", "OutputLock", "ResultsFolder", "RunResult", "RunStatus", "write_csv", "write_json", "write_mat"]
