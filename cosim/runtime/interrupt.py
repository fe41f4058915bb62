"""Ctrl-C during a run.  A Python KeyboardInterrupt raised inside an FMU's own Python code (a pythonfmu
slave runs in this interpreter) would make that FMU report Fatal.  So while stepping, the first SIGINT
only sets a flag, checked between loop segments (every few hundredths of a second); a second one
interrupts at once."""
from __future__ import annotations

import signal
import threading
from types import FrameType
from typing import Any


class Interrupt:
    """The SIGINT handler of one call of the execution (installed only in the main thread), restored by
    :meth:`restore`."""

    def __init__(self) -> None:
        self.flag = False
        self.old: Any = None
        if threading.current_thread() is threading.main_thread():
            self.old = signal.signal(signal.SIGINT, self._handler)

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        if self.flag:
            raise KeyboardInterrupt
        self.flag = True

    def check(self) -> None:
        """KeyboardInterrupt if Ctrl-C was pressed since the handler was installed."""
        if self.flag:
            raise KeyboardInterrupt

    def restore(self) -> None:
        if self.old is not None:
            signal.signal(signal.SIGINT, self.old)
            self.old = None
