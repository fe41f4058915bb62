"""Small dense linear algebra done once at set-up (never in a 2 ms hot path), in the standard library only:
this module travels inside the FMUs, whose runtime needs nothing but Python itself.

Matrices are lists of rows of floats.  Every matrix product accumulates each entry in index order with a
fused multiply-add, s = fma(a_ik, b_kj, s) from s = 0 (``math.fma`` from Python 3.13, exact integer
arithmetic rounded once before), so the results are the same on every machine; they are the results of
numpy's matrix product on an x86-64 with FMA (OpenBLAS's kernel), which this module replaced, so the
discretisation of the sensor filter, hence every run, kept its last bit.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

Matrix = list[list[float]]


def _fma_exact(a: float, b: float, c: float) -> float:
    """a * b + c rounded once (what ``math.fma`` does from Python 3.13), from the exact integer ratios."""
    if a == 0.0 or b == 0.0:
        return a * b + c  # the product is an exact (signed) zero: one rounding, IEEE's sign of zero
    try:
        na, da = a.as_integer_ratio()  # denominators are powers of two
        nb, db = b.as_integer_ratio()
        nc, dc = c.as_integer_ratio()
    except (OverflowError, ValueError):  # inf or nan: the IEEE result of the unfused expression
        return a * b + c
    num, den = na * nb, da * db
    if den >= dc:
        num += nc * (den // dc)
    else:
        num = num * (dc // den) + nc
        den = dc
    if num == 0:
        return a * b + c  # an exact zero sum: a * b is exact here, so this is the fused result and sign
    return num / den      # int / int true division: correctly rounded


fma = getattr(math, "fma", _fma_exact)


def matmul(a: Sequence[Sequence[float]], b: Sequence[Sequence[float]]) -> Matrix:
    """The product a b; each entry accumulated with fused multiply-adds in index order from 0."""
    m = len(b)
    p = len(b[0]) if m else 0
    cols = [[float(b[k][j]) for k in range(m)] for j in range(p)]
    out = []
    for row in a:
        r = [float(x) for x in row]
        if len(r) != m:
            raise ValueError(f"matmul: {len(r)} columns times {m} rows")
        line = []
        for col in cols:
            s = 0.0
            for x, y in zip(r, col):
                s = fma(x, y, s)
            line.append(s)
        out.append(line)
    return out


def identity(n: int) -> Matrix:
    """The n x n identity."""
    return [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]


def expm(a: Sequence[Sequence[float]]) -> Matrix:
    """Matrix exponential by scaling and squaring of a degree-18 Taylor polynomial.

    Scaling: s the smallest integer with ||a||_inf / 2^s <= 0.25; then e^a = (sum_{k<=18} (a/2^s)^k / k!)^(2^s),
    each Taylor term computed from the previous one as (term x) / k.  Accurate to a few ulps for the small,
    well-conditioned matrices of the sensor filter; checked against scipy.linalg.expm in the tests.
    """
    n = len(a)
    rows = [[float(v) for v in row] for row in a]
    if any(len(r) != n for r in rows):
        raise ValueError("expm: the matrix must be square")
    norm = max((sum(abs(v) for v in r) for r in rows), default=0.0)
    s = max(0, math.ceil(math.log2(norm / 0.25))) if norm > 0.25 else 0
    d = 2.0 ** s
    x = [[v / d for v in r] for r in rows]
    term = identity(n)
    out = identity(n)
    for k in range(1, 19):
        term = [[v / k for v in r] for r in matmul(term, x)]
        out = [[o + t for o, t in zip(ro, rt)] for ro, rt in zip(out, term)]
    for _ in range(s):
        out = matmul(out, out)
    return out


def zoh(a: Sequence[Sequence[float]], b: Sequence[Sequence[float]], h: float) -> tuple[Matrix, Matrix]:
    """Exact zero-order-hold discretisation of x' = A x + B u over a step h [s]: (Ad, Bd).

    exp([[A, B], [0, 0]] h) = [[Ad, Bd], [0, I]]."""
    n = len(a)
    m = len(b[0]) if n else 0
    aug = [[float(v) * h for v in list(a[i]) + list(b[i])] for i in range(n)] + [[0.0] * (n + m) for _ in range(m)]
    e = expm(aug)
    return [r[:n] for r in e[:n]], [r[n:] for r in e[:n]]
