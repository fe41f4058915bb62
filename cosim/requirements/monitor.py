"""The online monitor of a requirement: the robustness of each subformula at the communication points
t_k = k h, computed as the run goes (each value as soon as the samples it needs are in), and the verdict
as early as the logic allows.

Every subformula is a stream of robustness values by step index.  An atom's value at k is known at t_k;
``always[a,b]``/``eventually[a,b]`` at k are known once their operand is known at k + b/h (a sliding
minimum/maximum over a monotonic queue: constant time per step); past operators at once; ``until`` and
``since`` with a bound over the window's samples (numpy), ``since`` without a bound by its recurrence.
When the run ends, the values still waiting are computed over the samples there are (the windows cut at
the last point, as rtamt's offline monitor does) and marked incomplete: a verdict never rests on them.

The requirement (see formula.py) is its formula at t = 0.  When the outermost operator is ``always[a,b]``
(or the implicit one of a formula without a temporal operator) its robustness is the lowest value of the
operand over the window, and the verdict "violated" comes at the first negative value (the time it
refers to is the first violation; the sample that decided it may come later by the operand's look-ahead);
when it is ``eventually[a,b]``, the highest value, and "holds" comes at the first value >= 0; otherwise
the formula's value at t = 0 once known.  A window the run ended inside leaves the verdict "undecided";
so does an unbounded ``always`` (over the whole run) when the run ended before its planned stop: it holds
only at the end of a run that reached it.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import StrEnum
from typing import Callable, Sequence

import numpy as np

from .formula import Bool, Checked, Cmp, Logic, Node, Not, Temporal, Until, Var, compile_atom, temporal

INF = math.inf


class Outcome(StrEnum):
    """A requirement's verdict: a str (``Outcome.HOLDS == "holds"``), written to JSON and CSV as its value."""

    HOLDS = "holds"            # decided: every value the window needs is in and the formula holds
    VIOLATED = "violated"      # decided: known to fail, whatever comes after
    UNDECIDED = "undecided"    # the run ended before the window did (or before its planned stop, unbounded)


HOLDS, VIOLATED, UNDECIDED = Outcome.HOLDS, Outcome.VIOLATED, Outcome.UNDECIDED


class _Stream:
    """The robustness values of one subformula by step index, as far as known; ``complete``: the values
    below it rest on complete windows (the others, computed when the run ended, on cut ones)."""

    def __init__(self) -> None:
        self.values: list[float] = []
        self.complete = 0      # values below this index rest on complete windows

    def update(self, final: bool) -> None:
        """Extend the values as far as the operands allow (``final``: the run has ended, compute what
        remains over cut windows)."""
        raise NotImplementedError


class _Atom(_Stream):
    def __init__(self, f: Callable[[float], float]) -> None:
        super().__init__()
        self.f = f

    def push(self, t: float) -> None:
        self.values.append(self.f(t))
        self.complete = len(self.values)

    def update(self, final: bool) -> None:
        pass


class _Not(_Stream):
    def __init__(self, a: _Stream) -> None:
        super().__init__()
        self.a = a

    def update(self, final: bool) -> None:
        self.a.update(final)
        av, out = self.a.values, self.values
        for k in range(len(out), len(av)):
            out.append(-av[k])
        self.complete = self.a.complete


class _Logic(_Stream):
    """``and`` (minimum) or ``or`` (maximum) of every operand, or ``implies`` of two (max(-a, b)), folded
    left to right."""

    def __init__(self, op: str, args: list[_Stream]) -> None:
        super().__init__()
        self.op, self.args = op, args

    def update(self, final: bool) -> None:
        for a in self.args:
            a.update(final)
        out, op = self.values, self.op
        if len(self.args) == 2:   # (the common case, without the inner loop)
            av, bv = self.args[0].values, self.args[1].values
            for k in range(len(out), min(len(av), len(bv))):
                x, y = av[k], bv[k]
                out.append(min(x, y) if op == "and" else max(x, y) if op == "or" else max(-x, y))
            self.complete = min(self.args[0].complete, self.args[1].complete)
            return
        first, *rest = [a.values for a in self.args]
        for k in range(len(out), min(len(v) for v in (first, *rest))):
            x = first[k]
            if op == "implies":
                x = -x
            for v in rest:
                y = v[k]
                x = min(x, y) if op == "and" else max(x, y)
            out.append(x)
        self.complete = min(a.complete for a in self.args)


class _Window(_Stream):
    """min (``always``, ``historically``) or max (``eventually``, ``once``) of the operand over
    [k + lo, k + hi] (future) or [k - hi, k - lo] (past; hi None: from the start), in steps."""

    def __init__(self, lowest: bool, future: bool, lo: int, hi: int | None, a: _Stream) -> None:
        super().__init__()
        self.lowest, self.future, self.lo, self.hi, self.a = lowest, future, lo, hi, a
        self.queue: deque[int] = deque()   # operand indices, their values monotonic
        self.pushed = 0                     # operand indices pushed so far

    def _push(self, j: int) -> None:
        v, q = self.a.values, self.queue
        x = v[j]
        if self.lowest:
            while q and v[q[-1]] >= x:
                q.pop()
        else:
            while q and v[q[-1]] <= x:
                q.pop()
        q.append(j)
        self.pushed = j + 1

    def update(self, final: bool) -> None:
        self.a.update(final)
        av, out, q = self.a.values, self.values, self.queue
        empty = INF if self.lowest else -INF
        while True:
            k = len(out)
            if self.future:
                assert self.hi is not None
                first, last = k + self.lo, k + self.hi
                if last >= len(av) and not (final and k < len(av)):
                    break
                last = min(last, len(av) - 1)
            else:
                if k >= len(av):
                    break
                first = 0 if self.hi is None else k - self.hi
                last = k - self.lo
            while self.pushed <= last:
                self._push(self.pushed)
            while q and q[0] < first:
                q.popleft()
            out.append(av[q[0]] if q and first <= last else empty)
        # complete: k + hi (future) or k - lo (past) below the operand's complete values
        within = self.a.complete - (self.hi or 0) if self.future else self.a.complete + self.lo
        self.complete = max(0, min(len(out), within))


class _Until(_Stream):
    """``a until[lo,hi] b`` (future) or ``a since[lo,hi] b`` (past), in steps (hi None: past, from the
    start)."""

    def __init__(self, future: bool, lo: int, hi: int | None, a: _Stream, b: _Stream) -> None:
        super().__init__()
        self.future, self.lo, self.hi, self.a, self.b = future, lo, hi, a, b

    def update(self, final: bool) -> None:
        self.a.update(final)
        self.b.update(final)
        av, bv, out = self.a.values, self.b.values, self.values
        known = min(len(av), len(bv))
        while True:
            k = len(out)
            if self.future:
                assert self.hi is not None
                if k + self.hi >= known and not (final and k < known):
                    break
                out.append(self._until(k, min(k + self.hi, known - 1), av, bv))
            else:
                if k >= known:
                    break
                out.append(self._since(k, av, bv))
        # complete: a up to k + hi - 1 and b up to k + hi (future); a up to k and b up to k - lo (past)
        ca, cb = self.a.complete, self.b.complete
        hi = self.hi or 0
        within = min(ca - hi + 1, cb - hi) if self.future else min(ca, cb + self.lo)
        self.complete = max(0, min(len(out), within))

    def _until(self, k: int, last: int, av: list[float], bv: list[float]) -> float:
        first = k + self.lo
        if first > last:
            return -INF
        # before[j - k] = min of a over k .. j - 1 (+inf for j = k)
        before = np.minimum.accumulate(np.array(av[k:last], dtype=float)) if last > k else np.empty(0)
        before = np.concatenate(([INF], before))[first - k:last - k + 1]
        return float(np.max(np.minimum(np.array(bv[first:last + 1], dtype=float), before)))

    def _since(self, k: int, av: list[float], bv: list[float]) -> float:
        if self.hi is None and self.lo == 0:   # the recurrence: max(b(k), min(a(k), value(k - 1)))
            prev = self.values[k - 1] if k > 0 else -INF
            return max(bv[k], min(av[k], prev))
        first = 0 if self.hi is None else max(0, k - self.hi)
        last = k - self.lo
        if last < first:
            return -INF
        # after[j - first] = min of a over j + 1 .. k (+inf for j = k)
        seg = np.array(av[first + 1:k + 1], dtype=float)[::-1]
        after = np.concatenate(([INF], np.minimum.accumulate(seg)))[::-1]   # index j - first, j = first..k
        return float(np.max(np.minimum(np.array(bv[first:last + 1], dtype=float), after[:last - first + 1])))


def _steps(seconds: float, step: float) -> int:
    return int(round(seconds / step))


def _build(n: Node, checked: Checked, read: dict[str, Callable[[], float]], step: float,
           atoms: list[_Atom]) -> _Stream:
    if isinstance(n, (Bool, Var, Cmp)):
        atom = _Atom(compile_atom(n, checked, read))
        atoms.append(atom)
        return atom
    if isinstance(n, Not):
        return _Not(_build(n.a, checked, read, step, atoms))
    if isinstance(n, Logic):
        return _Logic(n.op, [_build(a, checked, read, step, atoms) for a in n.args])
    if isinstance(n, Temporal):
        hi = None if n.hi is None else _steps(n.hi, step)
        return _Window(n.op in ("always", "historically"), n.op in ("always", "eventually"), _steps(n.lo, step),
                       hi, _build(n.a, checked, read, step, atoms))
    assert isinstance(n, Until)
    hi = None if n.hi is None else _steps(n.hi, step)
    return _Until(n.op == "until", _steps(n.lo, step), hi, _build(n.a, checked, read, step, atoms),
                  _build(n.b, checked, read, step, atoms))


def fold_of(node: Node) -> str:
    """How a requirement's verdict folds the robustness of its body over its window: "min" for an outermost
    ``always`` (or a formula without a temporal operator, read as one: every value must be >= 0), "max"
    for an outermost ``eventually`` (one value >= 0 suffices), "single" otherwise (the value at t = 0)."""
    if isinstance(node, Temporal) and node.op in ("always", "eventually"):
        return "min" if node.op == "always" else "max"
    return "single" if temporal(node) else "min"


def formula_fold(formula: str) -> str:
    """:func:`fold_of` the formula written ``formula`` (its text, not checked against any FMU);
    FormulaError where it does not parse."""
    from .formula import parse

    return fold_of(parse(formula))


@dataclass
class Verdict:
    """What a requirement's run says: ``verdict`` (:class:`Outcome`); ``robustness`` (in the unit of its
    comparison) and ``at`` [s], the time it refers to (the lowest value of an ``always``, the highest of an
    ``eventually``, else 0; for an undecided verdict the lowest or highest of the values judged so far;
    both None when no value was judged: the run ended before the window); ``first_violation`` [s] (None if
    none); ``decided_at`` [s], the communication point at which the verdict was known (given for every
    holds and violated; None: undecided); ``window`` [s], the times whose values the verdict rests on (from
    the start of the run; None: to the run's planned stop)."""

    name: str
    formula: str
    verdict: Outcome
    robustness: float | None
    at: float | None
    first_violation: float | None
    decided_at: float | None
    window: tuple[float, float | None] = (0.0, 0.0)   # [s] the times judged (None: to the planned stop)

    def as_dict(self) -> dict[str, object]:
        return {"name": self.name, "formula": self.formula, "verdict": str(self.verdict),
                "robustness": self.robustness, "at": self.at, "first_violation": self.first_violation,
                "decided_at": self.decided_at, "window": list(self.window)}


class Monitor:
    """One requirement, monitored online: :meth:`sample` at every communication point (k = 0, 1, ...; the
    bounds are counted in steps of ``step`` [s], the times reported are the samples'), :meth:`finish` at
    the end; :attr:`verdict` at any time, :meth:`signal` the robustness of
    the operand of the outermost ``always``/``eventually`` (else of the formula) by step."""

    def __init__(self, name: str, checked: Checked, read: dict[str, Callable[[], float]], step: float) -> None:
        self.name, self.checked, self.step = name, checked, step
        self.atoms: list[_Atom] = []
        node = checked.node
        self.mode = fold_of(node)
        self.lo: int = 0
        self.hi: int | None = 0
        if isinstance(node, Temporal) and self.mode != "single":
            self.lo = _steps(node.lo, step)
            self.hi = None if node.hi is None else _steps(node.hi, step)
            node = node.a
        self.body = _build(node, checked, read, step, self.atoms)
        self.seen = 0                       # body values looked at (those from lo on folded into the verdict)
        self.best = INF if self.mode == "min" else -INF
        self.best_k = 0
        self.first_violation: float | None = None
        self.decided: Outcome | None = None
        self.decided_at: float | None = None
        self.violated_now = False            # set by the sample that decided "violated"
        self.finished = False
        self.covered = False                 # set by finish: the run reached its planned stop
        self.times: list[float] = []         # [s] the communication point of each sample

    def sample(self, t: float) -> None:
        """The values at the next communication point t [s] (the read functions give them now)."""
        self.violated_now = False
        self.times.append(t)
        for a in self.atoms:
            a.push(t)
        self.body.update(False)
        self._fold(t, self.body.complete)

    def finish(self, covered: bool = True) -> None:
        """The run has ended: the values still waiting are computed over cut windows (never judged).
        ``covered``: the run reached its planned stop; a run that ended early (stopped, violated, failed,
        terminated by an FMU) did not cover an unbounded window, which leaves its verdict undecided."""
        self.body.update(True)
        self.finished = True
        self.covered = covered

    def _fold(self, t: float, upto: int) -> None:
        v = self.body.values
        k = self.seen
        if self.mode == "single":
            if self.decided is None and upto > 0:
                self.best, self.best_k = v[0], 0
                self._decide(HOLDS if v[0] >= 0 else VIOLATED, t, 0)
            self.seen = upto
            return
        end = upto if self.hi is None else min(upto, self.hi + 1)
        for k in range(max(k, self.lo), end):
            x = v[k]
            if (x < self.best) if self.mode == "min" else (x > self.best):
                self.best, self.best_k = x, k
            if self.mode == "min" and x < 0 and self.first_violation is None:
                self.first_violation = self.times[k]
                self._decide(VIOLATED, t, k)
            if self.mode == "max" and x >= 0:
                self._decide(HOLDS, t, k)
        self.seen = max(self.seen, end)
        if self.hi is not None and upto > self.hi:   # the window is complete
            self._decide(HOLDS if self.mode == "min" else VIOLATED, t, self.hi)

    def _decide(self, verdict: Outcome, t: float, k: int) -> None:
        if self.decided is not None:
            return
        self.decided, self.decided_at = verdict, t
        if verdict == VIOLATED:
            self.violated_now = True
            if self.first_violation is None:
                self.first_violation = t if self.mode == "max" else self.times[k]

    @property
    def verdict(self) -> Verdict:
        """The verdict so far (after :meth:`finish`: of the run)."""
        verdict, decided_at = self.decided or UNDECIDED, self.decided_at if self.decided else None
        judged = self.seen > self.lo   # (some value of the window was folded in)
        t0 = self.times[0] if self.times else 0.0
        hi = None if self.hi is None else t0 + self.hi * self.step
        if (self.decided is None and self.mode == "min" and self.hi is None and judged and self.finished
                and self.covered):
            # an unbounded always over a run that reached its planned stop, every judged value >= 0: it holds,
            # known at the run's end; where the operand looks ahead its last points are not judged, and the
            # window ends at the last one that is
            verdict, decided_at = HOLDS, self.times[-1]
            if self.seen < len(self.times):
                hi = self.times[self.seen - 1]
        at = self.times[self.best_k] if judged else None
        return Verdict(self.name, self.checked.text, verdict, self.best if judged else None, at,
                       self.first_violation, decided_at, (t0 + self.lo * self.step, hi))

    def signal(self) -> np.ndarray:
        """The robustness of the body by step index (NaN where it rests on a cut window or is unknown)."""
        out = np.full(len(self.times), np.nan)
        v = self.body.values[:self.body.complete]
        out[:len(v)] = v
        return out


def evaluate(name: str, checked: Checked, time: Sequence[float], signals: dict[str, np.ndarray],
             step: float, covered: bool = True) -> tuple[Verdict, np.ndarray]:
    """The monitor run over recorded signals (``signals[name]``: one value per communication point of
    ``time``; ``covered``: they reach the run's planned stop): the same verdict as online, and the body's
    robustness by step."""
    k = [0]

    def reader(a: np.ndarray) -> Callable[[], float]:
        return lambda: float(a[k[0]])
    read = {v: reader(np.asarray(signals[v], dtype=float)) for v in checked.variables}
    m = Monitor(name, checked, read, step)
    for i, t in enumerate(time):
        k[0] = i
        m.sample(float(t))
    m.finish(covered)
    return m.verdict, m.signal()
