"""How the master and what steps an instance wait for each other, chosen by measuring as the run goes.

Waiting for a partner (a child process's answer, its next request; a thread's) can spin (poll, with the
core kept) or block (sleep in the kernel until woken).  Which is faster depends on the machine's load,
not on the FMUs: on free cores spinning saves the wake-up each way, beside a busy process a partner that
spins takes the core the other needs.  Measured on this 2-core machine: a pipe round trip between two
processes, about 20 us blocking and 5-7 us polling when quiet; G1 with its plant in a child process
beside one busy process, 190 us a step blocking and 630-750 us polling (docs/benchmarks.md).  The results
do not depend on how anyone waits, so the way is measured and the faster taken (:class:`Measured`): the
same logic picks between spinning and blocking for child processes (:class:`Handoff`) and between threads
and the master's thread alone for C FMUs stepped at once (:mod:`~..stepping.parallel`).
"""
from __future__ import annotations

import math
import time
from typing import Any, Protocol


class Measured:
    """Of ``n`` ways to take the same cycle (the results the same each way), the one measured fastest:
    ``PROBE`` cycles each way in turn, the way with the least wall time kept for ``keep`` cycles, then
    measured again.  ``keep`` starts at ``KEEP`` and doubles (up to ``MAX_KEEP``) each time the same way
    wins again, and is ``KEEP`` again when another wins: a machine's load changes during a run, seldom.
    Each way's longest probe is left out, so that one pause (a script's own work between two steps, the
    end of a segment) does not decide; a way whose cycle takes ``GIVE_UP`` times the mean of a way probed
    before it in the round loses the round at once (spinning on a busy machine can cost milliseconds a
    cycle: the callers put their safe way first)."""

    PROBE = 16
    KEEP = 1024
    MAX_KEEP = 32768
    GIVE_UP = 8.0

    def __init__(self, n: int = 2) -> None:
        self.n = n
        self.phase = 0               # cycles into the current round (n * PROBE probing, then keep)
        self.sums = [0.0] * n        # [s] this round's probes
        self.longest = [0.0] * n     # [s] and the longest of them
        self.best = 0                # the way kept
        self.keep = self.KEEP
        self.taken = [0] * n         # cycles taken each way
        self.rounds = 0

    def way(self) -> int:
        """The way the next cycle takes."""
        p = self.phase
        return p // self.PROBE if p < self.n * self.PROBE else self.best

    def quiet(self) -> int:
        """How many of the next cycles only count (the way kept, not measured): their :meth:`took` may be
        left out and given to :meth:`skip` afterwards (the one after them ends the kept phase: it is timed)."""
        probing = self.n * self.PROBE
        return max(0, probing + self.keep - 1 - self.phase) if self.phase >= probing else 0

    def skip(self, n: int) -> None:
        """``n`` cycles taken the kept way, not timed (at most :meth:`quiet`)."""
        self.taken[self.best] += n
        self.phase += n

    def took(self, way: int, seconds: float) -> None:
        """A cycle took ``seconds`` [s] of wall time the way ``way``."""
        self.taken[way] += 1
        p, probing = self.phase, self.n * self.PROBE
        if p >= probing:
            self.phase = p + 1 if p + 1 < probing + self.keep else 0
            return
        self.sums[way] += seconds
        self.longest[way] = max(self.longest[way], seconds)
        self.phase = p + 1
        if way and seconds > self.GIVE_UP * min(self.sums[w] / self.PROBE for w in range(way)):
            self.sums[way] = math.inf   # (this way loses the round)
            self.phase = (way + 1) * self.PROBE
        if self.phase == probing:
            spent = [s - m for s, m in zip(self.sums, self.longest)]
            best = min(range(self.n), key=spent.__getitem__)   # (a tie: the first way)
            self.keep = min(2 * self.keep, self.MAX_KEEP) if self.rounds and best == self.best else self.KEEP
            self.best, self.sums, self.longest = best, [0.0] * self.n, [0.0] * self.n
            self.rounds += 1


#: Steps a child other than the first may take between two ticks (its ticks count nothing but the answers
#: that did not come within the polls).
QUIET = 1 << 20


class Waiter(Protocol):
    """One side of a hand-off that can be told how to wait (:meth:`set_spin`)."""

    def set_spin(self, spin: int) -> None: ...


class Handoff:
    """How a run's child processes and the master wait for each other at a step: spin (poll ``spin``
    times, yielding the core between polls where ``spin`` is negative, then block) or block at once, the
    way chosen by :class:`Measured` over the cycle from one step's request of the first child to its next
    (the master's whole step, its own work included: a partner that spins on a busy machine slows the
    master's work, not only the hand-off)."""

    def __init__(self, spin: int) -> None:
        self.spins = (0, spin)       # the spin count of each way: block (the safe way first), spin
        self.choice = Measured(len(self.spins))
        self.waiters: list[Waiter] = []
        self.current = self.choice.way()
        self.last: float | None = None   # [s] the first child's last request
        self.ran_out = 0             # steps whose answer did not come within the master's spin

    def add(self, waiter: Waiter) -> None:
        """A child of the run (the first one's requests time the cycles)."""
        self.waiters.append(waiter)
        waiter.set_spin(self.spins[self.current])

    def tick(self, waiter: Waiter, skipped: int = 0) -> int:
        """``waiter`` is about to request a step, after ``skipped`` steps it requested without a tick (a
        child served in C ticks only where the way may change): how many of its next steps may go without
        one."""
        if waiter is not self.waiters[0]:
            return QUIET
        self.settle(waiter, skipped)
        now = time.perf_counter()
        if self.last is not None:
            self.choice.took(self.current, now - self.last)
        self.last = now
        way = self.choice.way()
        if way != self.current:
            self.current = way
            for w in self.waiters:
                w.set_spin(self.spins[way])
        return self.choice.quiet()

    def settle(self, waiter: Waiter, skipped: int) -> None:
        """``skipped`` steps ``waiter`` requested without a tick (:meth:`tick`), counted."""
        if skipped and waiter is self.waiters[0]:
            self.choice.skip(skipped)

    def summary(self) -> dict[str, Any]:
        """For summary.json: the spin count, the steps (of the first child) whose answer was waited for
        spinning and blocking, and the answers that did not come within the spin."""
        blocked, spun = self.choice.taken
        return {"spin": self.spins[1], "steps": {"spun": spun, "blocked": blocked}, "spin_ran_out": self.ran_out}
