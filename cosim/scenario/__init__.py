"""Scenario documents: TOML files (and the documents an SSP archive or the Python API gives) read into a
:class:`Scenario` with every structural check, the events' conditions, tabulated inputs."""
from __future__ import annotations

from .condition import ConditionError, compile_condition
from .document import Scenario, apply_overrides, is_path, load, parse, parse_set, parse_value, read_document, steps_of
from .inputs import InputPlan, read_inputs

__all__ = ["apply_overrides", "compile_condition", "ConditionError", "InputPlan", "is_path", "load", "parse", "parse_set", "parse_value", "read_document", "read_inputs", "Scenario", "steps_of"]
