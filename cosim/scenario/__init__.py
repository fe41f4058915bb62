"""Scenario documents: TOML files (and the documents an SSP archive or the Python API gives) read into a
:class:`Scenario` with every structural check, the events' conditions, tabulated inputs."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .condition import ConditionError, compile_condition
    from .document import (SET_TABLES, Scenario, apply_overrides, base_path, is_path, load, parse, parse_set,
                           parse_value, read_document, read_toml, settable_table, steps_of)
    from .inputs import InputPlan, read_inputs

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "condition": ["ConditionError", "compile_condition"],
    "document": ["SET_TABLES", "Scenario", "apply_overrides", "base_path", "is_path", "load", "parse", "parse_set",
                 "parse_value", "read_document", "read_toml", "settable_table", "steps_of"],
    "inputs": ["InputPlan", "read_inputs"],
})
