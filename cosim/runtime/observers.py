"""The observers: what watches the run step by step without changing it (libcosim's ``observer``): the
recording streamed to disk, the progress bar, real-time pacing, and the script's step callbacks.

An observer is an object behind :class:`Observer`.  Its contract:

1. :meth:`~Observer.started` is called once, after initialisation (the row of the start time is in the
   recording), before the first step.
2. :meth:`~Observer.boundary` gives the last step at which a segment that starts at step k may end (so
   that the observer is called there), or None: anywhere.
3. ``per_step`` true: the observer must see every step (segments are then one step long); false: it costs
   nothing inside the loop.
4. :meth:`~Observer.stepped` is called after each segment, at its last step k (``ex.time`` is t_k), in the
   order the observers were added, with a read-only view of the run (:class:`.views.Observable`: the
   grid, the time, ``ex.get``); an error it raises ends the run (a RunError with a time: the steps after
   that time are not counted as done).
5. :meth:`~Observer.finished` is called once when stepping ends, whatever the status.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, Callable

from ..results.recording import NpyRecorder, RowBuffer
from .pacing import Pacer
from .views import Observable

#: Rows recorded between two flushes to disk (and progress updates).
FLUSH_ROWS = 2500


class Observer:
    """What watches the run (see the module's contract)."""

    per_step = False

    def started(self, ex: Observable) -> None:
        pass

    def boundary(self, k: int) -> int | None:
        return None

    def stepped(self, ex: Observable, k: int) -> None:
        pass

    def finished(self, ex: Observable) -> None:
        pass


class Recorder(Observer):
    """The recording: the rows the algorithm appends, converted to the recorded columns and types and
    appended to ``signals.npy`` every FLUSH_ROWS rows (and at the end), checked for non-finite values."""

    def __init__(self, path: Path, columns: list[str], types: list[str], slots: list[int], n_double: int,
                 n_int: int, decimation: int) -> None:
        self.file = NpyRecorder(path, columns, types)
        self.rows = RowBuffer(self.file, slots, n_double, n_int)
        self.block = FLUSH_ROWS * decimation

    def boundary(self, k: int) -> int | None:
        return k + self.block - (k % self.block)

    def stepped(self, ex: Observable, k: int) -> None:
        if len(self.rows) >= FLUSH_ROWS or k == ex.clock.n_steps:
            self.rows.flush()

    def finished(self, ex: Observable) -> None:
        if len(self.rows):
            self.rows.flush()

    def close(self) -> None:
        self.file.close()


class ProgressBar(Observer):
    """The progress bar on a terminal: simulated seconds done of the run's, the rate, and the FMUs' fixed
    internal steps over the run where they declare them."""

    def __init__(self, bar: Any) -> None:
        self.bar = bar

    def stepped(self, ex: Observable, k: int) -> None:
        self.bar.update(k * ex.clock.step - self.bar.n)

    def finished(self, ex: Observable) -> None:
        self.bar.close()   # (tqdm's close may be called again)


def progress_bar(enabled: bool | None, steps: int, h: float, internal: int = 0) -> Any:
    """A tqdm bar for ``steps`` steps of ``h`` [s], or None: on a terminal for runs of more than 5,000
    steps, unless ``enabled`` says (True, False)."""
    if enabled is None:
        enabled = sys.stderr.isatty() and steps > 5000
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    what = f" ({internal:.3g} internal steps)" if internal else ""
    return tqdm(total=steps * h, leave=False, file=sys.stderr, mininterval=0.5, unit="s",
                bar_format="{l_bar}{bar}| t = {n:.4g} of {total:.4g} s" + what + " [{elapsed}<{remaining}, "
                           "{rate_fmt}]")


class Pacing(Observer):
    """Real-time pacing (:class:`.pacing.Pacer`): each step held until its due time."""

    per_step = True

    def __init__(self, pacer: Pacer) -> None:
        self.pacer = pacer
        self.running = False

    def started(self, ex: Observable) -> None:
        """The wall clock of the current communication point is now (called as the first step begins)."""
        self.pacer.start(ex.time)
        self.running = True

    def stepped(self, ex: Observable, k: int) -> None:
        self.pacer.wait(ex.clock.time(k))


class StepCallback(Observer):
    """A function called after every step (the Python API's ``on_step``)."""

    per_step = True

    def __init__(self, fn: Callable[[], Any]) -> None:
        self.fn = fn

    def stepped(self, ex: Observable, k: int) -> None:
        self.fn()

