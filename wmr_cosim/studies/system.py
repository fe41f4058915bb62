"""The system a study's points run, as the application that starts the study knows it.

The studies (sweeps, falsification) run any system: a scenario names its FMUs by path, or by a model name
that only the application knows (ours: ``WmrPlant`` and the robot's other FMUs, built on demand), and the
application may judge a finished run beyond what the master says (ours: a run of the paper's controller
that ran to its end but diverged).  The application says both here; a study never imports them."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..cosim import RunResult


def no_models(name: str) -> Path | None:
    """The model-name resolver of a system whose scenarios name every FMU by its path: none."""
    return None


@dataclass(frozen=True)
class System:
    """``models``: a model name -> its FMU (None for a name it does not know; called on the driver only,
    the FMUs it gives are shipped to the workers); ``judge``: what a finished run becomes, applied to
    every run of every point as it finishes (on the workers: a module-level function, picklable), None
    for the master's own status."""

    models: Callable[[str], Path | None] = field(default=no_models)
    judge: Callable[[RunResult], RunResult] | None = None
