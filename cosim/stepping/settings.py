"""The settings of the algorithms that go beyond one pass per fixed step: the iteration of coupling loops
(``[experiment.iteration]``) and the step-size control (``[experiment.adaptive]``).

Both are plain values, checked where they are made (:func:`iteration_spec`; ``stepping.table.adaptive_spec``, which knows
the algorithms the step-size control may take as its step): a bad
value is one :class:`SpecError` (a ValueError) naming the key, which the scenario reader turns into its
one-line error.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from ..messages.suggest import unknown_key
from ..messages.words import count

#: How a loop's coupling inputs are iterated: fixed point with relaxation, or Newton's method with a
#: finite-difference Jacobian (a chord: the Jacobian of a step's first iteration, made anew when the
#: residual stops shrinking).
ITERATION_METHODS = ("fixed-point", "newton")
#: Where Newton's Jacobian comes from: forward differences of the loop's step (one more evaluation per
#: coupling input), or the FMUs' directional derivatives of their outputs by their inputs at the end of the
#: step (no evaluation; the direct, algebraic part of the dependence only: exact for an algebraic loop, an
#: approximation where the outputs also depend on the inputs through the step's dynamics).
JACOBIANS = ("finite-differences", "directional")
#: How a loop's coupling inputs vary over the step while it is iterated: held at the value being iterated
#: (the value at the end of the step, implicit: first order), or linear from the value at the start of the
#: step to it (fmi2SetRealInputDerivatives: second order; only FMUs that can interpolate their inputs).
INPUT_MODES = ("hold", "linear")
#: The keys of ``[experiment.iteration]`` and of ``[experiment.adaptive]`` (all optional).
ITERATION_KEYS = frozenset({"method", "tolerance", "max_iterations", "relaxation", "inputs", "jacobian"})
ADAPTIVE_KEYS = frozenset({"rtol", "atol", "min_step", "max_step", "initial_step", "coupling"})


class SpecError(ValueError):
    """A bad setting: ``key`` (e.g. "experiment.iteration.tolerance") and ``reason``."""

    def __init__(self, key: str, reason: str) -> None:
        super().__init__(f"{key}: {reason}")
        self.key, self.reason = key, reason


@dataclass(frozen=True)
class IterationSpec:
    """Per macro step, the coupling inputs u of every loop are iterated until the residual
    r = G(y(u)) - u meets ``max_i |r_i| / (1 + |G_i|) <= tolerance`` (G: the connections' transforms of the
    outputs that feed the loop), at most ``max_iterations`` evaluations of the loop's step each; every
    evaluation after the first restores the loop's FMUs to the state at the start of the step."""

    method: str = "newton"
    tolerance: float = 1e-10          # [-] mixed absolute/relative, see above
    max_iterations: int = 20          # evaluations of the loop's step per macro step, at least 1
    relaxation: float = 1.0           # fixed point: u <- u + relaxation * r, 0 < relaxation <= 1
    inputs: str = "hold"              # INPUT_MODES
    jacobian: str = "finite-differences"   # JACOBIANS (Newton only)

    def describe(self) -> str:
        relax = f", relaxation {self.relaxation:g}" if self.method == "fixed-point" else ""
        jac = ", Jacobian from directional derivatives" if self.method == "newton" and self.jacobian == "directional" else ""
        return (f"{self.method}{relax}{jac}, tolerance {self.tolerance:g}, at most "
                f"{count(self.max_iterations, 'iteration')}, inputs {self.inputs}")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class AdaptiveSpec:
    """Step-size control by step doubling: each macro step h is taken once whole and once as two halves
    from the same saved state; the coupling variables' difference, in the RMS norm weighted by
    ``atol + rtol * |y|``, is the error estimate; a step whose estimate exceeds 1 is rolled back and taken
    again shorter, the next step chosen by a PI controller between ``min_step`` and ``max_step`` [s].  The
    steps land on every communication point of the experiment's grid (its ``step``: the output interval,
    where the recording, the events and the stop time are)."""

    rtol: float = 1e-4                # [-]
    atol: float = 1e-6                # [unit of each coupling variable]
    min_step: float | None = None     # [s] None: the output interval * 1e-6
    max_step: float | None = None     # [s] None: the output interval
    initial_step: float | None = None  # [s] None: max_step / 10
    coupling: str = field(kw_only=True)   # the step taken: an algorithm's name (stepping.table.adaptive_couplings)

    def resolved(self, interval: float) -> "AdaptiveSpec":
        """The spec with its defaults filled in for the output interval ``interval`` [s]."""
        hmax = self.max_step if self.max_step is not None else interval
        hmin = self.min_step if self.min_step is not None else interval * 1e-6
        h0 = self.initial_step if self.initial_step is not None else hmax / 10.0
        return replace(self, min_step=hmin, max_step=hmax, initial_step=min(max(h0, hmin), hmax))

    def describe(self) -> str:
        r = self
        steps = "".join(f", {k} {v:g} s" for k, v in (("min_step", r.min_step), ("max_step", r.max_step),
                                                       ("initial_step", r.initial_step)) if v is not None)
        return f"{r.coupling} steps, rtol {r.rtol:g}, atol {r.atol:g}{steps}"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def positive(key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise SpecError(key, f"{value!r}: must be a number > 0")
    return float(value)


def iteration_spec(table: dict[str, Any], where: str = "experiment.iteration") -> IterationSpec:
    """An :class:`IterationSpec` from a table of its keys (all optional); ValueError naming a bad key."""
    for k in table:
        if k not in ITERATION_KEYS:
            raise SpecError(f"{where}.{k}", unknown_key(k, ITERATION_KEYS))
    d = IterationSpec()
    method = str(table.get("method", d.method)).lower()
    if method not in ITERATION_METHODS:
        raise SpecError(f"{where}.method", f"{method!r}: must be one of {', '.join(ITERATION_METHODS)}")
    tol = positive(f"{where}.tolerance", table["tolerance"]) if "tolerance" in table else d.tolerance
    n = table.get("max_iterations", d.max_iterations)
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise SpecError(f"{where}.max_iterations", f"{n!r}: must be an integer >= 1")
    relax = positive(f"{where}.relaxation", table["relaxation"]) if "relaxation" in table else d.relaxation
    if relax > 1.0:
        raise SpecError(f"{where}.relaxation", f"{relax!r}: must be in (0, 1]")
    inputs = str(table.get("inputs", d.inputs)).lower()
    if inputs not in INPUT_MODES:
        raise SpecError(f"{where}.inputs", f"{inputs!r}: must be one of {', '.join(INPUT_MODES)}")
    jacobian = str(table.get("jacobian", d.jacobian)).lower()
    if jacobian not in JACOBIANS:
        raise SpecError(f"{where}.jacobian", f"{jacobian!r}: must be one of {', '.join(JACOBIANS)}")
    if jacobian != d.jacobian and method != "newton":
        raise SpecError(f"{where}.jacobian", f"{jacobian!r} is Newton's; method {method!r} uses none")
    return IterationSpec(method, tol, n, relax, inputs, jacobian)


def check_adaptive(spec: AdaptiveSpec, interval: float | None, where: str = "experiment.adaptive") -> None:
    """The step bounds agree with each other and with the output interval [s] (when known)."""
    lo, hi = spec.min_step, spec.max_step
    if lo is not None and hi is not None and lo > hi:
        raise SpecError(f"{where}.min_step", f"{lo!r} s is larger than max_step {hi!r} s")
    if interval is not None:
        if hi is not None and hi > interval * (1 + 1e-12):
            raise SpecError(f"{where}.max_step", f"{hi!r} s is longer than the output interval (experiment.step "
                             f"{interval!r} s), on which every step lands")
        if lo is not None and lo > interval * (1 + 1e-12):
            raise SpecError(f"{where}.min_step", f"{lo!r} s is longer than the output interval (experiment.step "
                             f"{interval!r} s)")
