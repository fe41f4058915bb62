"""Messages of the master: its errors (one line each), counts in words, "did you mean" suggestions."""
from __future__ import annotations

from .errors import CosimError, FmuLoadError, OtherFileError, OutputError, RunError, ScenarioError
from .suggest import close_names, did_you_mean
from .words import count

__all__ = ["close_names", "CosimError", "count", "did_you_mean", "FmuLoadError", "OtherFileError", "OutputError", "RunError", "ScenarioError"]
