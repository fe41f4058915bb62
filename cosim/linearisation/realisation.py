"""A discrete-time model at the communication step of anything that can go back to a point of its run
(co-simulation FMUs included): impulse responses taken with rollback, realised by the eigensystem
realisation algorithm (python-control's ``eigensys_realization``).

At the point t_k0 the run is saved (:meth:`cosim.runtime.execution.Execution.save_point`).  For each
injected input j and each sign s of +1 and -1, the run goes back to the point and steps ``n`` times with
s delta added to input j over the first step only (a pulse of one communication step), reading the
outputs at t_k0+1 ... t_k0+n.  The central difference of the two responses divided by 2 delta is the
pulse response h[1..n] of the linearisation around the run's own trajectory (the nominal response
cancels; the truncation error is O(delta^2)).  An input on a connection is injected as:

* a bias added to what the connection carries: the system stays closed (an input no connection or table
  drives is set to its value plus the pulse, then back);
* at a cut connection (``cut``, the input it drives): the input follows the nominal run's values
  (recorded in a first pass from the point, the loop closed) plus the pulse, whatever the loop returns:
  the system opened there.  The cut holds in every response, whichever input is pulsed.

As the master steps it, an input set at t_k acts over [t_k, t_k+1) and an output is read at the end of a
step, so the model maps u[k] to y[k+1]: D = h[0] = 0, and h[k] = C A^(k-1) B (a zero-order hold: the
discretisation of a continuous model with ``c2d(sys, h, "zoh")`` has the same pulse response).
The realised order is the number of Hankel singular values above ``rtol`` times the largest (or given);
the singular values are kept with the model, to print.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..messages.errors import CosimError, RunError
from .model import LinearModel

#: The default pulse, relative to max(|u|, nominal) of the input at the point.
RELATIVE_PULSE = 1e-4
#: Hankel singular values above this fraction of the largest count toward the realised order.
ORDER_RTOL = 1e-3


@dataclass
class Injection:
    """Where a pulse goes in: an input ("instance.variable"), its size [input unit], and whether a
    connection or a table drives it (``wired``)."""

    ref: str
    delta: float
    wired: bool = True


def pulse_responses(ex: Any, injections: Sequence[Injection], outputs: Sequence[str], n: int,
                    cut: str | None = None) -> np.ndarray:
    """The pulse responses h[0..n] (shape: outputs, injections, n + 1) of an execution from its current
    communication point, with the connection into the input ``cut`` opened (see the module's docstring);
    the run is left at the point."""
    if n < 2:
        raise CosimError(f"the responses need at least 2 steps, not {n}")
    t0 = float(ex.time)
    point = ex.save_point()
    try:
        try:
            nominal = _nominal_inputs(ex, point, cut, n) if cut is not None else None
        except RunError as exc:
            raise RunError(f"the run from t = {t0:g} s with the loop closed failed: {exc}", exc.instance,
                           exc.time) from None
        H = np.zeros((len(outputs), len(injections), n + 1))
        for j, inj in enumerate(injections):
            runs = [_checked_response(ex, point, inj, sign, cut, nominal, outputs, n, t0) for sign in (1.0, -1.0)]
            H[:, j, 1:] = (runs[0] - runs[1]) / (2.0 * inj.delta)
        ex.restore_point(point)
    finally:
        ex.free_point(point)
    return H


def _checked_response(ex: Any, point: Any, inj: Injection, sign: float, cut: str | None,
                      nominal: list[float] | None, outputs: Sequence[str], n: int, t0: float) -> np.ndarray:
    """:func:`_response`; RunError naming the pulse where the run fails or an output is not finite."""
    what = f"the response to a pulse of {sign * inj.delta:+g} at {inj.ref} from t = {t0:g} s"
    try:
        y = _response(ex, point, inj, sign, cut, nominal, outputs, n)
    except RunError as exc:
        raise RunError(f"{what} failed (is the pulse too large for the model? --pulse): {exc}", exc.instance,
                       exc.time) from None
    bad = np.argwhere(~np.isfinite(y))
    if bad.size:
        i, k = bad[0]
        raise RunError(f"{what} is not finite: {outputs[i]} = {y[i, k]} at t = {t0 + (k + 1) * ex.clock.step:g} s "
                       "(is the pulse too large for the model? --pulse)", outputs[i].split(".", 1)[0],
                       t0 + (k + 1) * ex.clock.step)
    return y


def _nominal_inputs(ex: Any, point: Any, ref: str, n: int) -> list[float]:
    """The value of input ``ref`` at each of the n steps from the point, the loop closed."""
    ex.restore_point(point)
    values = []
    for _ in range(n):
        ex.step(1)
        values.append(float(ex.get(ref)))   # (the value the input was set to for the step just taken)
    return values


def _response(ex: Any, point: Any, inj: Injection, sign: float, cut: str | None, nominal: list[float] | None,
              outputs: Sequence[str], n: int) -> np.ndarray:
    ex.restore_point(point)
    held = None if inj.wired else float(ex.get(inj.ref))
    y = np.zeros((len(outputs), n))
    for k in range(n):
        pulse = sign * inj.delta if k == 0 else 0.0
        if cut is not None:
            assert nominal is not None
            ex.set(cut, nominal[k] + (pulse if inj.ref == cut else 0.0))
        if inj.ref != cut and k < 2:
            if held is not None:
                ex.set(inj.ref, held + pulse)
            elif k == 0:
                ex.bias(inj.ref, pulse)
            else:
                ex.release(inj.ref)
        ex.step(1)
        for i, ref in enumerate(outputs):
            y[i, k] = float(ex.get(ref))
    if cut is not None:
        ex.release(cut)
    return y


def realise(H: np.ndarray, dt: float, inputs: Sequence[str], outputs: Sequence[str], *, order: int | None = None,
            rtol: float = ORDER_RTOL, t: float = 0.0, input_units: Sequence[str] = (),
            output_units: Sequence[str] = ()) -> LinearModel:
    """The discrete-time model of pulse responses ``H`` (outputs, inputs, n + 1) by the eigensystem
    realisation algorithm; its order ``order``, else the count of Hankel singular values above ``rtol``
    times the largest."""
    import control

    p, m, n1 = H.shape
    rows = (n1 - 1) // 2
    if rows < 1:
        raise CosimError("too few response samples for a realisation")
    sv = _hankel_singular_values(H, rows)
    if order is None:
        order = significant(sv, rtol)
    if order < 0 or (order == 0 and sv.size and sv[0] > 0):
        raise CosimError(f"order {order}: a realisation has a positive order")
    if order > max_order(n1 - 1, p, m):
        raise CosimError(f"order {order} is more than {rows} samples of the responses can realise: take more steps")
    if order == 0:
        A, B, C = np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0))
    else:
        sysd, _ = control.eigensys_realization(H, order, m=rows, n=rows)   # (dt=True: no rescaling of B)
        A, B, C = sysd.A, sysd.B, sysd.C
    return LinearModel(A, B, C, H[:, :, 0], [f"x{i + 1}" for i in range(order)], list(inputs), list(outputs),
                       ["1"] * order, list(input_units), list(output_units), dt, t,
                       f"eigensystem realisation of order {order} from pulse responses of {n1 - 1} steps",
                       sv)


def significant(sv: np.ndarray, rtol: float = ORDER_RTOL) -> int:
    """The count of Hankel singular values above ``rtol`` times the largest: the order realised when none is
    given."""
    return int(np.sum(sv > rtol * sv[0])) if sv.size and sv[0] > 0 else 0


def max_order(n: int, p: int, m: int) -> int:
    """The largest order responses of ``n`` steps from ``m`` inputs to ``p`` outputs can realise (the rank
    of their block Hankel matrix of n // 2 block rows and columns)."""
    return (n // 2) * min(p, m)


def order_note(sv: np.ndarray, order: int, rtol: float = ORDER_RTOL) -> str | None:
    """What an order asked for does against the singular values: a truncation where it discards singular
    values above ``rtol`` times the largest, states of the noise where it takes ones below; None where it is
    the count above."""
    k = significant(sv, rtol)
    if order < k:
        dropped = ", ".join(f"{s:.3g}" for s in sv[order:k])
        return (f"order {order} as asked: a truncation; it discards Hankel singular values above {rtol:g} times "
                f"the largest ({dropped}), which realise order {k}")
    if order > k:
        return (f"order {order} as asked: above the {k} Hankel singular values above {rtol:g} times the largest; "
                f"the {order - k} more states realise singular values down to {sv[order - 1]:.3g}")
    return None


def _hankel_singular_values(H: np.ndarray, rows: int) -> np.ndarray:
    """The singular values of the block Hankel matrix of h[1..2 rows] (the one the realisation factors)."""
    p, m, _ = H.shape
    Hk = np.zeros((rows * p, rows * m))
    for i in range(rows):
        for j in range(rows):
            Hk[i * p:(i + 1) * p, j * m:(j + 1) * m] = H[:, :, i + j + 1]
    return np.linalg.svd(Hk, compute_uv=False)
