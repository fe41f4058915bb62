"""The loop as the co-simulation realises it at its communication step, beside the continuous loop.

Where every instance of a system can be linearised continuously (Model Exchange FMUs and memoryless ones),
the loop broken at a connection has a continuous-time model G(s) (:mod:`.interconnection`), and the
master, stepping the same instances at a communication step H, realises a discrete-time one: each block
advanced over a step with its inputs held (the zero-order hold of its continuous model at H) and the
blocks coupled as the algorithm exchanges their signals in a step:

* **Jacobi**: every input over [t_k, t_k+1) is the output it is connected to at t_k;
* **Gauss-Seidel**, in the plan's order: an input whose output belongs to an instance earlier in the order
  gets that output at t_k+1 (its instance has already stepped), the others (fed back against the order)
  the output at t_k.

An output read at t_k+1 is C x[k+1] + D u[k] (the input over the step still set). With the blocks'
inputs of the step before kept as states v[k] = u[k-1] (those a direct feedthrough reads), the loop is, from the injection w at the cut
input to the return r = factor * (its output) read after the step,

    u[k]   = K_old (C x + D v) + K_new (C Ad x + (C Bd + D) u[k]) + E w     (solved for u[k])
    x[k+1] = Ad x + Bd u[k],    v[k+1] = u[k],    r[k] = factor * F (C x[k] + D v[k])

(K_old: the connections read at t_k, K_new: those read at t_k+1; Ad, Bd the zero-order hold's).  Its pulse
response is what the rollback realisation of the same loop measures (:mod:`.realisation`), to the
accuracy of the instances' integrators.  The margins of the two loops side by side give what the
coupling costs: the phase margin lost [deg] at the communication step, and the largest step that keeps
that loss within a budget (bisection over H).

For a small step the loss is the phase of the delays the coupling adds at the gain crossover w_c: the
hold's H / 2 for each block with dynamics, a step H for a memoryless block whose input is read at t_k,
less a step for each connection Gauss-Seidel reads at t_k+1 (an advance): w_c H (n_dyn / 2 + n_mem -
n_new) rad; a loop of one lag and a controller under Jacobi loses 1.5 w_c H.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np
from scipy.linalg import expm

from .interconnection import Link
from .loop import LoopAnalysis, analyse, plain_number
from .model import LinearModel

#: The default budget of the phase margin the coupling may cost [deg] (``--phase-budget``).
PHASE_BUDGET = 5.0
#: The bisection over the step stops when its bracket is this narrow (relative).
STEP_RTOL = 1e-3


def zoh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(Ad, Bd) of x' = A x + B u with u held over a step of ``h`` [s]: the exponential of [[A, B], [0, 0]] h."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def cosimulated_loop(blocks: Sequence[LinearModel], links: Sequence[Link], cut: Link, order: Sequence[str],
                     simultaneous: bool, h: float) -> LinearModel:
    """The discrete-time model at the step ``h`` [s] from the injection at ``cut.dst`` to the return
    ``cut.factor * cut.src`` of the loop as the algorithm steps it (see the module's docstring): Jacobi
    (``simultaneous``) or Gauss-Seidel in ``order`` (instance names: a signal's instance is the part of its
    name before the first ".")."""
    from scipy.linalg import block_diag

    u_names = [u for b in blocks for u in b.inputs]
    y_names = [y for b in blocks for y in b.outputs]
    n_x, n_u = sum(len(b.states) for b in blocks), len(u_names)
    pairs = [zoh(b.A, b.B, h) for b in blocks]
    Ad = block_diag(*[p[0] for p in pairs]).reshape(n_x, n_x)
    Bd = block_diag(*[p[1] for p in pairs]).reshape(n_x, n_u)
    C = block_diag(*[b.C for b in blocks]).reshape(len(y_names), n_x)
    D = block_diag(*[b.D for b in blocks]).reshape(len(y_names), n_u)
    rank = {name: i for i, name in enumerate(order)}
    K_old, K_new = np.zeros((n_u, len(y_names))), np.zeros((n_u, len(y_names)))
    for lk in links:
        if (lk.src, lk.dst) == (cut.src, cut.dst):
            continue
        src, dst = lk.src.split(".", 1)[0], lk.dst.split(".", 1)[0]
        new = not simultaneous and rank[src] < rank[dst]
        (K_new if new else K_old)[u_names.index(lk.dst), y_names.index(lk.src)] += lk.factor
    E = np.zeros((n_u, 1))
    E[u_names.index(cut.dst), 0] = 1.0
    F = np.zeros((1, len(y_names)))
    F[0, y_names.index(cut.src)] = cut.factor
    held = [j for j in range(n_u) if np.any(D[:, j] != 0.0)]   # (inputs read through a direct feedthrough)
    S = np.eye(n_u)[:, held]
    N = np.linalg.inv(np.eye(n_u) - K_new @ (C @ Bd + D))
    Px, Pv, Pw = N @ (K_old @ C + K_new @ C @ Ad), N @ K_old @ D @ S, N @ E
    A = np.block([[Ad + Bd @ Px, Bd @ Pv], [S.T @ Px, S.T @ Pv]])
    B = np.vstack([Bd @ Pw, S.T @ Pw])
    Cz = F @ np.hstack([C, D @ S])
    states = [s for b in blocks for s in b.states] + [f"held({u_names[j]})" for j in held]
    units = {n: u for b in blocks for n, u in zip(b.inputs + b.outputs, b.input_units + b.output_units)}
    return LinearModel(A, B, Cz, np.zeros((1, 1)), states, [cut.dst], [cut.src],
                       [u for b in blocks for u in b.state_units] + [units[u_names[j]] for j in held],
                       [units[cut.dst]], [units[cut.src]], h, blocks[0].t if blocks else 0.0,
                       f"{'Jacobi' if simultaneous else 'Gauss-Seidel'} at {h:g} s (zero-order hold of the blocks)")


@dataclass
class CouplingCost:
    """The continuous loop's margins (``continuous``) beside the co-simulated loop's at the scenario's
    step (``cosimulated``, by ``algorithm``), the phase margin the coupling costs there (``phase_cost``
    [deg], continuous minus co-simulated: negative where the coupling leads), and the largest step
    ``largest_step`` [s] that keeps the cost within ``budget`` [deg] (``limit``: why the search stopped);
    ``loop_at(h)``: the co-simulated loop's analysis at another step h [s]."""

    algorithm: str
    step: float
    continuous: LoopAnalysis
    cosimulated: LoopAnalysis
    phase_cost: float
    budget: float
    largest_step: float
    limit: str
    loop_at: Callable[[float], LoopAnalysis] | None = field(default=None, repr=False, compare=False)

    def summary(self) -> dict[str, Any]:
        num = plain_number
        both = {}
        for name, a in (("continuous", self.continuous), ("cosimulated", self.cosimulated)):
            s = a.summary()
            both[name] = {k: s[k] for k in ("upper_gain_margin", "lower_gain_margin", "phase_margin_deg",
                                            "gain_crossover_rad_s", "phase_crossovers", "gain_crossovers",
                                            "stability_margin", "closed_loop_stable")}
        return {"algorithm": self.algorithm, "step_s": self.step, **both, "phase_cost_deg": num(self.phase_cost),
                "phase_budget_deg": self.budget, "largest_step_s": num(self.largest_step),
                "largest_step_limit": self.limit}


def phase_cost(continuous: LoopAnalysis, cosimulated: LoopAnalysis) -> float:
    """The phase margin [deg] the coupling costs: the continuous loop's less the co-simulated loop's; inf
    where the co-simulated loop is unstable closed or has lost its gain crossover."""
    if not cosimulated.closed_stable or not math.isfinite(cosimulated.phase_margin):
        return math.inf
    return continuous.phase_margin - cosimulated.phase_margin


def coupling_cost(opened: LoopAnalysis, blocks: Sequence[LinearModel], links: Sequence[Link], cut: Link,
                  order: Sequence[str], algorithm: str, simultaneous: bool, step: float,
                  budget: float = PHASE_BUDGET) -> CouplingCost:
    """The co-simulated loop at ``step`` [s] beside the continuous one (``opened``: its analysis) and the
    largest step within ``budget`` [deg] (:func:`largest_step`)."""
    def at(h: float) -> LoopAnalysis:
        return analyse(cosimulated_loop(blocks, links, cut, order, simultaneous, h), cut.src, cut.dst)

    here = at(step)
    if not math.isfinite(opened.phase_margin):
        return CouplingCost(algorithm, step, opened, here, math.nan, budget, math.nan,
                            "the continuous loop has no gain crossover: no phase margin to lose", at)
    h, limit = largest_step(lambda h: phase_cost(opened, at(h)), step, budget, math.pi / opened.gain_crossover)
    return CouplingCost(algorithm, step, opened, here, phase_cost(opened, here), budget, h, limit, at)


def largest_step(cost: Callable[[float], float], h0: float, budget: float, h_max: float) -> tuple[float, str]:
    """The largest step h [s] with ``cost(h) <= budget`` reached from h0 without crossing the budget: doubled
    (or halved) from h0 until the cost crosses it, then bisected to :data:`STEP_RTOL`; at most ``h_max``
    (where the gain crossover reaches the Nyquist frequency pi / h).  With why it stopped."""
    lo, hi = 0.0, math.inf
    h = min(h0, h_max)
    if cost(h) <= budget:
        lo = h
        while hi == math.inf:
            h = min(2.0 * lo, h_max)
            if h <= lo:
                return lo, "the gain crossover at the Nyquist frequency pi / h"
            if cost(h) <= budget:
                lo = h
            else:
                hi = h
    else:
        hi = h
        while lo == 0.0:
            h = hi / 2.0
            if h < h0 * 2.0 ** -40:
                return 0.0, "no step keeps the cost within the budget"
            if cost(h) <= budget:
                lo = h
            else:
                hi = h
    while hi - lo > STEP_RTOL * lo:
        mid = math.sqrt(lo * hi)
        if cost(mid) <= budget:
            lo = mid
        else:
            hi = mid
    return lo, "the budget"
