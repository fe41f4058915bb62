"""One Model Exchange FMU linearised at its current point: the Jacobian

    A = df/dx,  B = df/du,  C = dg/dx,  D = dg/du     of  x' = f(x, u, t),  y = g(x, u, t)

at the FMU's states x, chosen inputs u and time t as they are now (after a run to the operating point, or
states and inputs given), from the FMU's directional derivatives (fmi2GetDirectionalDerivative, one call
per known: the states, then the inputs) where its model exchange interface provides them, else from
central finite differences.

Central differences: the column of a known v is (F(v + h) - F(v - h)) / (2 h), with
h = eps^(1/3) max(|v|, nominal) made exactly representable ((v + h) - v): the step that balances the
truncation error (h^2 / 6 F''') against the rounding error (eps F / h) (Nocedal & Wright, Numerical
Optimization, 8.1); the nominal is the FMU's (fmi2GetNominalsOfContinuousStates for a state, the
``nominal`` attribute for an input, else 1).  The FMU is left at the point it was found (states and
inputs restored; its integrator restarts at the next step).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from ..messages.errors import RunError
from .model import LinearModel

#: eps^(1/3): the relative step of central differences.
CUBE_ROOT_EPS = float(np.finfo(float).eps) ** (1.0 / 3.0)
DIRECTIONAL, DIFFERENCES = "directional derivatives", "central differences"
#: How the Jacobian is taken: "auto" (directional derivatives where provided), or one of the two.
METHODS = ("auto", "directional", "differences")


@dataclass
class Signal:
    """A state, input or output of one FMU: its name as the model reports it ("plant.torque_right"), its
    value reference, unit (the FMU's declared unit, "" where none) and nominal value."""

    name: str
    vr: int
    unit: str = ""
    nominal: float = 1.0


def fd_step(v: float, nominal: float) -> float:
    """The central-difference step for a known at value ``v`` (see the module's docstring)."""
    h = CUBE_ROOT_EPS * max(abs(v), abs(nominal) if nominal else 1.0)
    return (v + h) - v


def central_column(put: Callable[[float], None], v: float, nominal: float,
                   evaluate: Callable[[], Sequence[float]]) -> np.ndarray:
    """The central difference (F(v + h) - F(v - h)) / 2h of ``evaluate`` by one known at ``v``, which
    ``put`` sets (and sets back to ``v`` after), with the step of :func:`fd_step`."""
    h = fd_step(v, nominal)
    cols = []
    for sign in (1.0, -1.0):
        put(v + sign * h)
        cols.append(np.array(evaluate(), dtype=float))
    put(v)
    return (cols[0] - cols[1]) / (2.0 * h)


def states_of(md: Any, prefix: str, unit_of: Callable[[str], str]) -> tuple[list[Signal], list[int]]:
    """The states of a model description in the order of its derivatives (the state vector's order) and
    the value references of the derivatives."""
    states, ders = [], []
    for d in md.derivatives:
        s = d.variable.derivative
        if s is None:
            raise RunError(f"{prefix}: the derivative {d.variable.name} names no state")
        states.append(Signal(f"{prefix}.{s.name}", int(s.valueReference), unit_of(s.name)))
        ders.append(int(d.variable.valueReference))
    return states, ders


def jacobian(inst: Any, states: Sequence[Signal], der_vrs: Sequence[int], inputs: Sequence[Signal],
             outputs: Sequence[Signal], method: str = "auto") -> tuple[np.ndarray, str]:
    """[[A, B], [C, D]] of a Model Exchange instance (:class:`cosim.instances.model_exchange.ModelExchange`)
    at its current point, and the method used ("directional derivatives" | "central differences")."""
    if method not in METHODS:
        raise ValueError(f"method {method!r}: one of {', '.join(METHODS)}")
    use_dd = method == "directional" or (method == "auto" and inst.provides_directional_derivative)
    if use_dd and not inst.provides_directional_derivative:
        raise RunError(f"{inst.name}: its model exchange interface provides no directional derivatives "
                       "(take central differences)", inst.name)
    if use_dd:
        return _by_directional_derivatives(inst, states, der_vrs, inputs, outputs), DIRECTIONAL
    return _by_differences(inst, states, inputs, outputs), DIFFERENCES


def _by_directional_derivatives(inst: Any, states: Sequence[Signal], der_vrs: Sequence[int],
                                inputs: Sequence[Signal], outputs: Sequence[Signal]) -> np.ndarray:
    knowns = [s.vr for s in states] + [u.vr for u in inputs]
    unknowns = list(der_vrs) + [y.vr for y in outputs]
    J = np.zeros((len(unknowns), len(knowns)))
    for j in range(len(knowns)):
        seed = [0.0] * len(knowns)
        seed[j] = 1.0
        status, col = inst.directional_derivative(unknowns, knowns, seed)
        if status > 1:
            raise inst.fail_status(f"fmi{inst.fmi_version}GetDirectionalDerivative", status, inst.t)
        J[:, j] = col
    # an output that is itself a state (one value reference) has the unit row: not asked of the FMU, some of
    # which (the Reference FMUs' VanDerPol) give 0 there
    for i, y in enumerate(outputs):
        if y.vr in knowns[:len(states)]:
            J[len(der_vrs) + i, :] = 0.0
            J[len(der_vrs) + i, knowns.index(y.vr)] = 1.0
    return J


def _by_differences(inst: Any, states: Sequence[Signal], inputs: Sequence[Signal],
                    outputs: Sequence[Signal]) -> np.ndarray:
    x0 = list(inst.continuous_states())
    in_vrs, out_vrs = [u.vr for u in inputs], [y.vr for y in outputs]
    u0 = inst.get_reals(in_vrs) if in_vrs else []
    nominals = inst.state_nominals() if x0 else []

    def evaluate() -> list[float]:
        return list(inst.state_derivatives()) + (list(inst.get_reals(out_vrs)) if out_vrs else [])

    def put_state(j: int) -> Callable[[float], None]:
        return lambda value: inst.set_continuous_states(x0[:j] + [value] + x0[j + 1:])

    def put_input(j: int) -> Callable[[float], None]:
        return lambda value: inst.set_continuous_inputs([in_vrs[j]], [value])

    J = np.zeros((len(x0) + len(out_vrs), len(x0) + len(in_vrs)))
    try:
        for j, v in enumerate(x0):
            J[:, j] = central_column(put_state(j), v, nominals[j], evaluate)
        for j, v in enumerate(u0):
            J[:, len(x0) + j] = central_column(put_input(j), v, inputs[j].nominal, evaluate)
    finally:
        if x0:
            inst.set_continuous_states(x0)
        if u0:
            inst.set_continuous_inputs(in_vrs, u0)
    return J


def linear_model(J: np.ndarray, states: Sequence[Signal], inputs: Sequence[Signal], outputs: Sequence[Signal],
                 t: float, method: str) -> LinearModel:
    """The :class:`LinearModel` of a Jacobian [[A, B], [C, D]] (continuous time)."""
    n = len(states)
    return LinearModel(J[:n, :n], J[:n, n:], J[n:, :n], J[n:, n:], [s.name for s in states],
                       [u.name for u in inputs], [y.name for y in outputs], [s.unit for s in states],
                       [u.unit for u in inputs], [y.unit for y in outputs], 0.0, t, method)
