"""Messages of the master: its errors (one line each), counts in words, "did you mean" suggestions and
the one refusal of an unknown key."""
from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:   # (for the type checker; at run time each name is imported where it is first used)
    from .errors import (CosimError, FmuLoadError, MissingVariableError, OtherFileError, OutputError, RunError,
                         ScenarioError)
    from .suggest import close_names, did_you_mean, unknown_key
    from .words import count

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "errors": ["CosimError", "FmuLoadError", "MissingVariableError", "OtherFileError", "OutputError", "RunError",
               "ScenarioError"],
    "suggest": ["close_names", "did_you_mean", "unknown_key"],
    "words": ["count"],
})
