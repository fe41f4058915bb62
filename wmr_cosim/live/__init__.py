"""The live view of a run: a run served, while it goes, by an HTTP and WebSocket API (and a page) to watch
and steer it (pause, step, pace, set values that replay exactly); docs/live.md.

This face exports what the command line and the Python API use; the server's libraries (the ``live``
extra) are imported only by a live run.
"""
from __future__ import annotations

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "run": ["LiveError", "LiveOptions", "missing_libraries", "replay_document", "run_live"],
    "view": ["serve_results"],
})
