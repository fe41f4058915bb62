"""Small dense linear algebra done once at set-up (never in a 2 ms hot path)."""
from __future__ import annotations

import numpy as np


def expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring of a degree-18 Taylor polynomial (numpy only).

    Accurate to a few ulps for the small, well-conditioned matrices of the sensor filter; checked
    against scipy.linalg.expm in the tests.
    """
    a = np.asarray(a, dtype=float)
    norm = float(np.max(np.sum(np.abs(a), axis=1))) if a.size else 0.0
    s = max(0, int(np.ceil(np.log2(norm / 0.25))) if norm > 0.25 else 0)
    x = a / (2.0 ** s)
    n = a.shape[0]
    term = np.eye(n)
    out = np.eye(n)
    for k in range(1, 19):
        term = term @ x / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def zoh(a: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of x' = A x + B u over a step h [s]: (Ad, Bd)."""
    n = a.shape[0]
    m = b.shape[1]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = a
    aug[:n, n:] = b
    e = expm(aug * h)
    return e[:n, :n], e[:n, n:]
