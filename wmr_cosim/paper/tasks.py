"""The tasks file of the paper job (``scenarios/paper.toml`` by default): which protocol file runs each
task of the paper.  Read by the paper job (job.py) and by the robustness study (robustness.py),
which re-runs the same protocols."""
from __future__ import annotations

import os
from pathlib import Path

from .. import scenario_files
from ..components import paper

DEFAULT_MANIFEST = "paper.toml"  # among the shipped scenario files (wmr_cosim.scenarios)


def manifest_path(manifest: str | os.PathLike | None = None) -> Path:
    """The tasks file: ``manifest`` as given, or the shipped ``scenarios/paper.toml`` when None."""
    return Path(manifest) if manifest is not None else scenario_files.folder() / DEFAULT_MANIFEST


def task_files(manifest: str | os.PathLike | None = None) -> dict[str, Path]:
    """{task: protocol file} of the tasks file ``manifest`` (default: the shipped one, see :func:`manifest_path`)."""
    from ..cosim import ScenarioError, read_toml

    path = manifest_path(manifest)
    doc = read_toml(path)
    tasks = doc.get("tasks")
    if not isinstance(tasks, dict) or not tasks:
        raise ScenarioError(str(path), "tasks", "missing: a table task name -> protocol file")
    out = {}
    for name, f in tasks.items():
        if name not in paper.TASKS:
            raise ScenarioError(str(path), f"tasks.{name}", f"unknown task (one of {', '.join(paper.TASKS)})")
        out[name] = (path.parent / f).resolve()
    return out
