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

import ctypes
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..instances.failure import Call, Failure
from ..results.recording import MemoryRecorder, NpyRecorder, RecordedRows, RowBuffer
from ..stepping.algorithm import Clock, NativeRecording, Row, StepDone
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


@dataclass
class RecordedGetter:
    """The recorded outputs of one instance of one FMI type other than Float64: ``get(vrs, n, buf, nv)``
    reads them into ``buf``; ``slots`` maps an index in ``buf`` to the row's slot; ``fail(what, status, t)``
    is the instance's error for a failed get."""

    instance: str
    get: Callable[[Any, Any, Any, Any], int]
    vrs: ctypes.Array[ctypes.c_uint]
    n: ctypes.c_size_t                       # value references
    buf: ctypes.Array[Any]                   # of the type's ctypes element
    nv: ctypes.c_size_t                      # values
    slots: list[tuple[int, int]]
    fail: Callable[[str, int, float], Exception]

    def read(self, row: Row) -> int:
        """The values into their slots of the row (doubles, then 64-bit integers); the get's status."""
        s = self.get(self.vrs, self.n, self.buf, self.nv)
        if not s:
            rowd, irow, nd, buf = row.row, row.irow, row.n_double, self.buf
            for e, slot in self.slots:
                if slot < nd:
                    rowd[slot] = buf[e]
                else:
                    irow[slot - nd] = buf[e]
        return s


class Recorder(Observer):
    """The recording: the row of every recorded communication point (every ``decimation``-th, the last,
    and where an FMU ended the simulation), taken from the row buffer where the algorithm leaves the
    outputs, with the recorded outputs of other types read then; converted to the recorded columns and
    types and appended to ``signals.npy`` every FLUSH_ROWS rows (and at the end), checked for non-finite
    values.  :meth:`take` is what the algorithm calls after every step (``stepping.algorithm.StepDone``)."""

    def __init__(self, path: Path | None, columns: list[str], types: list[str], slots: list[int], row: Row,
                 n_int: int, clock: Clock, native: bool = True) -> None:
        """``path``: signals.npy (None: the rows kept in memory); ``native``: a native loop may copy the rows
        itself (False where rows are also taken inside the steps, :meth:`record_at`, so that every row is
        appended in the order of its time)."""
        self.native = native
        self.path, self.columns, self.types, self.slots = path, columns, types, slots
        self.row, self.n_int, self.clock = row, n_int, clock
        self.block = FLUSH_ROWS * clock.decimation
        self.getters: list[RecordedGetter] = []
        self.file: RecordedRows | None = None     # signals.npy or memory, from initialisation on
        self.rows: RowBuffer | None = None

    def open(self, getters: list[RecordedGetter]) -> None:
        """At initialisation, the instances loaded: signals.npy made (no row yet), the getters of the
        recorded outputs of other types than Float64 known, :attr:`take` ready."""
        self.getters = getters
        self.file = NpyRecorder(self.path, self.columns, self.types) if self.path is not None else \
            MemoryRecorder(self.columns, self.types)
        self.rows = RowBuffer(self.file, self.slots, self.row.n_double, self.n_int)
        self.take: StepDone = self._taker()

    @property
    def n_rows(self) -> int:
        """The rows written to signals.npy."""
        return self.file.rows if self.file is not None else 0

    def signals(self) -> np.ndarray:
        """Every row written (an empty time column where the recording never opened)."""
        return np.array(self.file.array()) if self.file is not None else np.zeros(0, dtype=[("time", "f8")])

    def final(self) -> dict[str, float]:
        """The last recorded value of each column ({} without rows)."""
        if self.file is None:
            return {}
        data = self.file.array()
        return {c: data[c][-1].item() for c in self.columns} if len(data) else {}

    def last_time(self) -> float | None:
        """The time of the last row taken and not yet written (None: none)."""
        return self.rows.last_time() if self.rows is not None else None

    def _taker(self) -> StepDone:
        """``take(k, ended)``: the row of t_k when k is recorded (or ``ended``); a Failure where a recorded
        value cannot be read.  A closure over locals: it runs after every step."""
        c, row, rowd, buf, getters = self.clock, self.row, self.row.row, self.row.buf, self.getters
        assert self.rows is not None
        dec, n, t0, h, stop, append = c.decimation, c.n_steps, float(c.start), float(c.step), c.stop, \
            self.rows.chunk.append

        def read_others(k: int) -> Failure | None:
            """The recorded outputs of other types than Float64 into the row."""
            for x in getters:
                s = x.read(row)
                if s:
                    return Failure(k, x.instance, Call.GET_RECORDED, s)
            return None

        def take(k: int, ended: bool) -> Failure | None:
            if k % dec and k != n and not ended:
                return None
            rowd[0] = stop if k == n and stop is not None else t0 + k * h
            if getters:
                fail = read_others(k)
                if fail is not None:
                    return fail
            append(bytes(buf))
            return None
        if self.native:
            take.native = NativeRecording(buf, ctypes.sizeof(buf), dec, n, stop, t0, h,   # type: ignore[attr-defined]
                                          read_others if getters else None, self.rows.extend,
                                          self.rows if self.rows.takes_records else None)
        return take

    def record_at(self, t: float) -> None:
        """The row of the time t [s] now, outside the loop (the start time; where an FMU ended the simulation
        between two points), the recorded outputs of other types read first (RunError naming the instance)."""
        for x in self.getters:
            s = x.read(self.row)
            if s:
                raise x.fail("get outputs (recorded)", s, t)
        self.row.row[0] = t
        assert self.rows is not None
        self.rows.chunk.append(bytes(self.row.buf))

    def boundary(self, k: int) -> int | None:
        return k + self.block - (k % self.block)

    def stepped(self, ex: Observable, k: int) -> None:
        assert self.rows is not None
        if len(self.rows) >= FLUSH_ROWS or k == ex.clock.n_steps:
            self.rows.flush()

    def finished(self, ex: Observable) -> None:
        if self.rows is not None and len(self.rows):
            self.rows.flush()

    def close(self) -> None:
        if self.file is not None:
            self.file.close()


class ProgressBar(Observer):
    """The progress bar on a terminal (:func:`progress_bar`: ``enabled`` None, on a terminal for long runs):
    simulated seconds done of the run's, the rate, and the FMUs' fixed internal steps over the run where
    they declare them (``internal``).  Shown from the start of the run."""

    def __init__(self, enabled: bool | None, clock: Clock, internal: int = 0) -> None:
        self.enabled, self.clock, self.internal = enabled, clock, internal
        self.bar: Any = None

    def started(self, ex: Observable) -> None:
        self.bar = progress_bar(self.enabled, self.clock.n_steps, self.clock.step, self.internal)

    def stepped(self, ex: Observable, k: int) -> None:
        if self.bar is not None:
            self.bar.update(k * self.clock.step - self.bar.n)

    def finished(self, ex: Observable) -> None:
        if self.bar is not None:
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

