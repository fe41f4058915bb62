"""Requirements in signal temporal logic: the formula language and its check (formula.py), the online
monitor with the quantitative semantics (monitor.py)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..messages.faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .formula import Checked, FormulaError, VarInfo, check, parse
    from .monitor import Monitor, Outcome, Verdict, evaluate, fold_of, formula_fold

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
