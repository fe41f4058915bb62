"""Threads that live for a run and step instances in this process at once (``[experiment] workers``).

A C FMU's step is a foreign call; through a view of its library that lets go of the GIL for the call
(:attr:`~..instances.contract.FastPath.threaded_step`), several such steps run at once on as many cores.
:class:`Lanes` keeps ``n`` threads for the whole run (not one per step); each waits on a lock of its own
until the master hands it work, runs it, and hands the answer back on another lock.  Waiting on a lock
lets go of the GIL, so a waiting thread costs the master nothing; a hand-off there and back is a lock
release and a wake-up each way (about 20 us measured here on 2 cores with nothing to do in between).
"""
from __future__ import annotations

import threading
from typing import Any, Callable


class Lanes:
    """``n`` threads, each running what it is handed (:meth:`start`) until :meth:`close`."""

    def __init__(self, n: int, name: str = "cosim-lane") -> None:
        self.n = n
        self._go = [threading.Lock() for _ in range(n)]
        self._done = [threading.Lock() for _ in range(n)]
        for lock in (*self._go, *self._done):
            lock.acquire()
        self._work: list[Callable[[], Any] | None] = [None] * n
        self._answer: list[Any] = [None] * n
        self._error: list[BaseException | None] = [None] * n
        self._closed = False
        self._threads = [threading.Thread(target=self._serve, args=(j,), name=f"{name}-{j + 1}", daemon=True)
                         for j in range(n)]
        for t in self._threads:
            t.start()

    def _serve(self, j: int) -> None:
        go, done = self._go[j], self._done[j]
        while True:
            go.acquire()
            work = self._work[j]
            if work is None:   # closed
                return
            try:
                self._answer[j] = work()
            except BaseException as exc:   # (handed back to the master, which raises it)
                self._error[j] = exc
            done.release()

    def start(self, j: int, work: Callable[[], Any]) -> None:
        """Lane ``j`` runs ``work()``; :meth:`wait` for its answer before handing it more."""
        self._work[j] = work
        self._error[j] = None
        self._go[j].release()

    def wait(self, j: int) -> Any:
        """The answer of lane ``j``'s work (its exception raised here)."""
        self._done[j].acquire()
        err = self._error[j]
        if err is not None:
            raise err
        return self._answer[j]

    def close(self) -> None:
        """End the threads (each finishes what it runs first)."""
        if self._closed:
            return
        self._closed = True
        for j in range(self.n):
            self._work[j] = None
            self._go[j].release()
        for t in self._threads:
            t.join()
