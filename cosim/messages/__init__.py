"""Messages of the master: its errors (one line each), counts in words, "did you mean" suggestions and
the one refusal of an unknown key; and, as the bottom layer every face can import, the lazy faces
(:mod:`.faces`: each face's exports listed once)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from .faces import attach

if TYPE_CHECKING:   # the face's exports, listed once: at run time each is imported where first used
    from .errors import (CosimError, FmuLoadError, MissingVariableError, OtherFileError, OutputError, RunError,
                         ScenarioError)
    from .suggest import close_names, did_you_mean, unknown_key
    from .words import count

__getattr__, __dir__ = attach(__name__, __file__)   # the names imported above; __all__ too
