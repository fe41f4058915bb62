"""Linear blocks closed through the system's connections: one continuous-time model of the system.

Each block i is x_i' = A_i x_i + B_i u_i, y_i = C_i x_i + D_i u_i (a Model Exchange FMU linearised, or a
memoryless one: no state, y_i = D_i u_i) over all its connected inputs and outputs.  Stacked, x' = A x + B u,
y = C x + D u with block-diagonal matrices; the connections say u = K y + E w, where K[i, j] is the
connection's factor from output j to input i (its unit conversion folded in; its offset is a constant and
drops out of the linearisation) and E injects the open inputs w: an open input that a connection also
drives gets w added to what the connection carries (a disturbance at that point); an input whose
connection is broken gets w alone.  The outputs z = F y pick the open outputs.  With M = (I - D K)^-1 (the
algebraic loops through the blocks' direct feedthrough, solved in the interconnection):

    y  = M (C x + D E w)
    x' = (A + B K M C) x + B (K M D + I) E w
    z  = F M C x + F M D E w
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.linalg import block_diag

from ..messages.errors import CosimError
from .model import LinearModel

#: The condition number of I - D K beyond which an algebraic loop is taken as having no unique solution.
SINGULAR_LOOP = 1e12


@dataclass(frozen=True)
class Link:
    """A connection between blocks: ``src`` output -> ``dst`` input ("instance.variable"), value_in =
    factor * value_out (+ an offset, which the linearisation does not see)."""

    src: str
    dst: str
    factor: float = 1.0


def close(blocks: Sequence[LinearModel], links: Sequence[Link], inputs: Sequence[str], outputs: Sequence[str],
          broken: Sequence[Link] = ()) -> LinearModel:
    """The system of ``blocks`` closed through ``links`` but those ``broken``, from the open ``inputs`` to
    the ``outputs`` (names of the blocks' inputs and outputs), as one continuous-time model."""
    u_names = [u for b in blocks for u in b.inputs]
    y_names = [y for b in blocks for y in b.outputs]
    u_at, y_at = _index(u_names, "input"), _index(y_names, "output")
    A = block_diag(*[b.A for b in blocks]) if blocks else np.zeros((0, 0))
    B = block_diag(*[b.B for b in blocks])
    C = block_diag(*[b.C for b in blocks])
    D = block_diag(*[b.D for b in blocks])
    A, B, C, D = (np.atleast_2d(m).reshape(shape) for m, shape in
                  ((A, (len(A), len(A))), (B, (len(A), len(u_names))), (C, (len(y_names), len(A))),
                   (D, (len(y_names), len(u_names)))))
    cut = {(lk.src, lk.dst) for lk in broken}
    K = np.zeros((len(u_names), len(y_names)))
    for lk in links:
        if (lk.src, lk.dst) not in cut:
            K[u_at[lk.dst], y_at[lk.src]] += lk.factor
    E = np.zeros((len(u_names), len(inputs)))
    for j, name in enumerate(inputs):
        E[_find(u_at, name, "input"), j] = 1.0
    F = np.zeros((len(outputs), len(y_names)))
    for i, name in enumerate(outputs):
        F[i, _find(y_at, name, "output")] = 1.0
    loop = np.eye(len(y_names)) - D @ K
    if len(y_names) and np.linalg.cond(loop) > SINGULAR_LOOP:
        raise CosimError("an algebraic loop of the linearised system has no unique solution (I - D K is "
                         "singular: a loop gain of exactly 1 through direct feedthrough)")
    M = np.linalg.inv(loop) if len(y_names) else loop
    Ac = A + B @ K @ M @ C
    Bc = B @ (K @ M @ D + np.eye(len(u_names))) @ E
    Cc = F @ M @ C
    Dc = F @ M @ D @ E
    units = {n: u for b in blocks for n, u in zip(b.inputs + b.outputs, b.input_units + b.output_units)}
    first = blocks[0] if blocks else None
    return LinearModel(Ac, Bc, Cc, Dc, [s for b in blocks for s in b.states], list(inputs), list(outputs),
                       [u for b in blocks for u in b.state_units], [units[n] for n in inputs],
                       [units[n] for n in outputs], 0.0, first.t if first else 0.0,
                       ", ".join(sorted({b.method for b in blocks if b.method})))


def _index(names: list[str], kind: str) -> dict[str, int]:
    at: dict[str, int] = {}
    for i, n in enumerate(names):
        if n in at:
            raise CosimError(f"the {kind} {n} belongs to two blocks")
        at[n] = i
    return at


def _find(at: dict[str, int], name: str, kind: str) -> int:
    if name not in at:
        raise CosimError(f"{name} is no {kind} of the linearised blocks")
    return at[name]
