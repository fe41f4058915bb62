"""Scenario documents: TOML files (and the documents an SSP archive or the Python API gives) read into a
:class:`Scenario` with every structural check, the events' conditions, tabulated inputs."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .condition import ConditionError, compile_condition
    from .document import (SET_TABLES, Scenario, apply_overrides, base_path, is_path, load, parse, parse_set,
                           parse_value, read_document, read_toml, settable_table, steps_of)
    from .inputs import InputPlan, read_inputs

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
