"""The table of ``wmr-cosim``'s commands: name -> the module that holds the command, in the order ``--help``
lists them.  Each module has ``add_parser(sub, name)`` (the command's options, help and description; it
sets ``func`` to the command's function ``cmd_<name>``) and that function (``args`` -> exit code), with
what the command prints.  Adding a command is one module and one row here."""
from __future__ import annotations

from types import ModuleType

from . import (build, check, direct, export_fmu, export_ssp, falsify, gamma_search, info, linearize, paper, plot, run,
               sweep, view)

COMMANDS: dict[str, ModuleType] = {
    "direct": direct,
    "build": build,
    "run": run,
    "check": check,
    "plot": plot,
    "view": view,
    "export-ssp": export_ssp,
    "export-fmu": export_fmu,
    "info": info,
    "paper": paper,
    "sweep": sweep,
    "gamma-search": gamma_search,
    "falsify": falsify,
    "linearize": linearize,
}
