"""What a file given to the master is, decided in one place by its suffix (case-insensitive)."""
from __future__ import annotations

import os
from enum import Enum


class FileKind(Enum):
    """A single FMU (``.fmu``), an SSP archive (``.ssp``) or a scenario file (anything else, ``.toml``)."""

    FMU = "fmu"
    SSP = "ssp"
    SCENARIO = "scenario"


def file_kind(path: str | os.PathLike) -> FileKind:
    """The kind of the file at ``path``, by its suffix: ``X.FMU`` is an FMU as ``x.fmu`` is."""
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    return {".fmu": FileKind.FMU, ".ssp": FileKind.SSP}.get(suffix, FileKind.SCENARIO)
