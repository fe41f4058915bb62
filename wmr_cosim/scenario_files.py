"""The scenario files shipped with the package, and how a command-line argument names one of them.

The repository's ``scenarios/`` folder is installed as the package ``wmr_cosim.scenarios`` (its ``*.toml``
files as package data), so an installed ``wmr-cosim`` finds the paper's protocol and the examples without
a source checkout.  In a checkout (or an editable install) the folder is ``<checkout>/scenarios`` itself.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path


def folder() -> Path:
    """The folder of the shipped scenario files (``<checkout>/scenarios`` in a source checkout,
    ``<site-packages>/wmr_cosim/scenarios`` when installed from a wheel)."""
    f = resources.files("wmr_cosim.scenarios")
    if not isinstance(f, Path):  # e.g. imported from a zip archive: the scenario loader needs real files
        raise RuntimeError(f"the shipped scenarios are not a folder on disk ({f!r})")
    return f


def shipped_folder() -> Path | None:
    """The folder of the shipped scenario files, which a ``base`` may name; None when they are not files
    on disk."""
    try:
        return folder()
    except (RuntimeError, ModuleNotFoundError):
        return None


def scenario_path(text: str) -> Path:
    """A scenario argument of the command line: the file itself when it exists; otherwise, when the name
    (relative, without ``..``) is a shipped scenario file, such as ``example.toml``, ``paper/g1.toml``
    or, with the checkout's folder name, ``scenarios/g1_learn.toml``, the shipped copy; otherwise the
    path as given (the command then reports it missing)."""
    p = Path(text)
    try:
        exists = p.exists()
    except OSError:   # a name the system cannot look up (too long): the command reports it, in one line
        return p
    if exists or p.is_absolute() or ".." in p.parts:
        return p
    parts = p.parts[1:] if p.parts[:1] == ("scenarios",) else p.parts
    if parts:
        shipped = folder().joinpath(*parts)
        if shipped.is_file():
            return shipped
    return p
