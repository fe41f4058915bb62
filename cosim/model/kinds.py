"""What a file given to the master is, decided in one place by its suffix (case-insensitive)."""
from __future__ import annotations

import os
from enum import Enum


class FileKind(Enum):
    """A single FMU (``.fmu``), an SSP archive (``.ssp``) or a scenario file (anything else, ``.toml``)."""

    FMU = "fmu"
    SSP = "ssp"
    SCENARIO = "scenario"


_SUFFIXES = {".fmu": FileKind.FMU, ".ssp": FileKind.SSP, ".toml": FileKind.SCENARIO}


def named_kind(path: str | os.PathLike) -> FileKind | None:
    """The kind the name of ``path`` declares (``.fmu``, ``.ssp``, ``.toml``, in any case), None for another
    suffix or none."""
    return _SUFFIXES.get(os.path.splitext(os.fspath(path))[1].lower())


def file_kind(path: str | os.PathLike) -> FileKind:
    """The kind of the file at ``path``, by its suffix: ``X.FMU`` is an FMU as ``x.fmu`` is; a file of
    another suffix is a scenario file."""
    return named_kind(path) or FileKind.SCENARIO
