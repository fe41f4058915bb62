"""Requirements in signal temporal logic: the formula language and its check (formula.py), the online
monitor with the quantitative semantics (monitor.py)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .formula import Checked, FormulaError, VarInfo, check, parse
    from .monitor import Monitor, Outcome, Verdict, evaluate, fold_of, formula_fold

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "formula": ["Checked", "FormulaError", "VarInfo", "check", "parse"],
    "monitor": ["Monitor", "Outcome", "Verdict", "evaluate", "fold_of", "formula_fold"],
})
