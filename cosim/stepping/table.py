"""The table of algorithms: every name a scenario may give (``[experiment] algorithm``), the class that
steps it, and what it can do and needs.  The scenario's checks, the resolver, ``check``'s output, the SSP
export and the execution read these rows; nothing else in the master names an algorithm.

Adding an algorithm is one module (a class behind :class:`.algorithm.Algorithm`) and one row here.

A row says (each a fact the checks and the execution act on):

* ``one_pass``: one pass over the instances per step (Gauss-Seidel, Jacobi): may run instances at their own
  rates (:class:`.multirate.MultiRate`) and be the step the step-size control takes;
* ``simultaneous``: every instance steps from the outputs of the previous step (Jacobi's order);
* ``workers``: instances that do not feed each other in a step may step at once (``[experiment] workers``,
  :mod:`.parallel`): every instance under Jacobi, each level's under Gauss-Seidel;
* ``solves_loops``: solves every coupling loop at every step (and the algebraic loops through it), rolling
  back the loop's instances: they must get and set their state;
* ``varies_step``: varies every instance's communication step and rolls every instance back when it
  rejects one: each instance must accept steps of any length and get and set its state;
* ``table``: the table of settings it reads, ``[experiment.NAME]`` (:class:`SettingsTable`: its name, its
  keys, how it is read, where the SSP export keeps it): the scenario reader, ``--set``, the SSP export and
  import and scenario.json loop over the rows' tables; the step-size control also reads the table of the
  step it takes (``[experiment.iteration]`` under ``coupling = "iterated"``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from ..messages.suggest import unknown_key
from .adaptive import Adaptive
from .algorithm import Algorithm
from .generated import GaussSeidel, Jacobi
from .iterated import Iterated
from .multirate import MultiRate
from .parallel import ParallelGaussSeidel, ParallelJacobi
from .settings import (ADAPTIVE_KEYS, ITERATION_KEYS, AdaptiveSpec, IterationSpec, SpecError, check_adaptive,
                       iteration_spec, positive)

GAUSS_SEIDEL, JACOBI, ITERATED, ADAPTIVE = "gauss-seidel", "jacobi", "iterated", "adaptive"
#: The names of the tables of settings (``[experiment.iteration]``, ``[experiment.adaptive]``).
ITERATION_TABLE, ADAPTIVE_TABLE = "iteration", ADAPTIVE


@dataclass(frozen=True)
class SettingsTable:
    """A table of settings an algorithm reads, ``[experiment.NAME]``: its ``name``, its ``keys`` (all
    optional), ``read(table, interval)``: the settings (a spec with ``as_dict()``) from a table of them,
    checked (SpecError naming a bad key; ``interval``: the output interval [s] where known); ``tag``: its
    element in this master's SSP annotation, whose attributes are words (``words``), integers
    (``integers``) or numbers (the other keys)."""

    name: str
    keys: frozenset[str]
    read: Callable[[dict[str, Any], float | None], Any]
    tag: str
    words: frozenset[str] = frozenset()
    integers: frozenset[str] = frozenset()


@dataclass(frozen=True)
class AlgorithmRow:
    """One algorithm: its name, its class, what it can do and needs (see the module's docstring)."""

    name: str
    cls: type[Algorithm]
    summary: str               # how it takes a step, in words (docs, ``check``)
    one_pass: bool = False
    simultaneous: bool = False
    workers: bool = False
    solves_loops: bool = False
    varies_step: bool = False
    table: SettingsTable | None = None   # the table of settings it reads itself

    @property
    def settings(self) -> tuple[str, ...]:
        """The names of the tables of settings it reads itself."""
        return (self.table.name,) if self.table is not None else ()

    @property
    def rolls_back(self) -> str | None:
        """Which instances it rolls back: "every" instance, the coupling "loops"' instances, or None."""
        return "every" if self.varies_step else "loops" if self.solves_loops else None


ITERATION = SettingsTable(ITERATION_TABLE, ITERATION_KEYS, lambda table, interval: iteration_spec(table), "Iteration",
                          words=frozenset({"method", "inputs", "jacobian"}), integers=frozenset({"max_iterations"}))
ADAPTIVE_SETTINGS = SettingsTable(ADAPTIVE_TABLE, ADAPTIVE_KEYS, lambda table, interval: adaptive_spec(table, interval),
                                  "Adaptive", words=frozenset({"coupling"}))

ROWS: tuple[AlgorithmRow, ...] = (
    AlgorithmRow(GAUSS_SEIDEL, GaussSeidel, "one pass per step in the plan's order, each instance seeing its "
                 "predecessors' outputs of this step", one_pass=True, workers=True),
    AlgorithmRow(JACOBI, Jacobi, "one pass per step, every instance seeing the outputs of the previous step",
                 one_pass=True, simultaneous=True, workers=True),
    AlgorithmRow(ITERATED, Iterated, "every coupling loop iterated to its tolerance at every step (fixed point "
                 "or Newton, the loop rolled back per iteration)", solves_loops=True, table=ITERATION),
    AlgorithmRow(ADAPTIVE, Adaptive, "the step size controlled by step doubling, a rejected step rolled back "
                 "(over one pass or the iterated step)", varies_step=True, table=ADAPTIVE_SETTINGS),
)
#: The tables of settings, in the order of the rows that read them.
TABLES: tuple[SettingsTable, ...] = tuple(r.table for r in ROWS if r.table is not None)
#: The algorithm a scenario that names none runs, and the step-size control's settings where it gives none.
DEFAULT = GAUSS_SEIDEL
DEFAULT_ADAPTIVE = AdaptiveSpec(coupling=DEFAULT)
NAMES: tuple[str, ...] = tuple(r.name for r in ROWS)
_BY_NAME = {r.name: r for r in ROWS}


def row(name: str) -> AlgorithmRow:
    """The row of a name the scenario's checks accepted (KeyError for another)."""
    return _BY_NAME[name]


def quoted(name: str) -> str:
    """A name as a scenario file writes it: ``"jacobi"``."""
    return f'"{name}"'


def names_where(flag: str) -> list[str]:
    """The names of the algorithms whose row has ``flag`` true."""
    return [r.name for r in ROWS if getattr(r, flag)]


def adaptive_couplings() -> list[str]:
    """What the step-size control may take as its step: a one-pass algorithm or one that solves loops."""
    return [r.name for r in ROWS if r.one_pass or r.solves_loops]


def iterates(name: str, coupling: str | None) -> bool:
    """Whether the coupling loops are solved at every step: by the algorithm itself, or by the step the
    step-size control takes (``coupling``, the name ``[experiment.adaptive]`` gives; None: the default)."""
    r = row(name)
    inner = _BY_NAME.get(coupling or DEFAULT)
    return r.solves_loops or (r.varies_step and inner is not None and inner.solves_loops)


def reads(name: str, table: str, coupling: str | None) -> bool:
    """Whether the algorithm ``name`` reads the table of settings ``table``: its own, or (the step-size
    control) that of the step it takes (``coupling``, the name ``[experiment.adaptive]`` gives; None: the
    default)."""
    r = row(name)
    inner = _BY_NAME.get(coupling or DEFAULT) if r.varies_step else None
    return table in r.settings or (inner is not None and table in inner.settings)


def readers(table: str) -> str:
    """Who reads a table of settings, in words: '"iterated", and by "adaptive" with coupling = "iterated"'."""
    own = [quoted(r.name) for r in ROWS if table in r.settings]
    own += [f"{quoted(r.name)} with coupling = {quoted(c)}" for r in ROWS if r.varies_step
            for c in adaptive_couplings() if table in row(c).settings]
    return ", and by ".join(own)


def adaptive_spec(table: dict[str, Any], interval: float | None = None,
                  where: str = "experiment.adaptive") -> AdaptiveSpec:
    """An :class:`AdaptiveSpec` from a table of its keys (all optional; the step taken by default: one
    pass of Gauss-Seidel), checked against the output interval [s] when it is known; SpecError naming a
    bad key."""
    for k in table:
        if k not in ADAPTIVE_KEYS:
            raise SpecError(f"{where}.{k}", unknown_key(k, ADAPTIVE_KEYS))
    d = DEFAULT_ADAPTIVE
    vals = {k: (positive(f"{where}.{k}", table[k]) if k in table else getattr(d, k))
            for k in ("rtol", "atol", "min_step", "max_step", "initial_step")}
    coupling = str(table.get("coupling", d.coupling)).lower()
    if coupling not in adaptive_couplings():
        raise SpecError(f"{where}.coupling", f"{coupling!r}: must be one of {', '.join(adaptive_couplings())}")
    spec = AdaptiveSpec(vals["rtol"], vals["atol"], vals["min_step"], vals["max_step"], vals["initial_step"],
                        coupling=coupling)
    check_adaptive(spec, interval, where)
    return spec


def describe_settings(name: str, iteration: IterationSpec | None, adaptive: AdaptiveSpec | None,
                      interval: float) -> str | None:
    """The settings an algorithm runs with, in words (``check`` prints them); None for one that has none.
    ``interval``: the output interval [s] (the step-size control's defaults follow it)."""
    r = row(name)
    if r.solves_loops:
        return (iteration or IterationSpec()).describe()
    if not r.varies_step:
        return None
    spec = adaptive or DEFAULT_ADAPTIVE
    text = spec.resolved(interval).describe()
    if row(spec.coupling).solves_loops:
        text += f"; iteration {(iteration or IterationSpec()).describe()}"
    return text


def make(name: str, iteration: IterationSpec | None = None, adaptive: AdaptiveSpec | None = None, *,
         workers: int = 1, own_rates: bool = False) -> Algorithm:
    """A new algorithm object for a name the scenario's checks accepted, with its settings (None: the
    defaults): at the instances' own rates (``own_rates``: some instance steps at a rate of its own), or
    with instances stepped at once (``workers`` > 1), where the resolver allowed it."""
    r = row(name)
    if own_rates:
        alg: Algorithm = MultiRate(jacobi=r.simultaneous)
    elif workers > 1:
        alg = ParallelJacobi(workers) if r.simultaneous else ParallelGaussSeidel(workers)
    elif r.solves_loops:
        alg = Iterated(iteration or IterationSpec())
    elif r.varies_step:
        spec = adaptive or DEFAULT_ADAPTIVE
        inner = row(spec.coupling)
        alg = Adaptive(spec, iteration, iterated=inner.solves_loops, jacobi=inner.simultaneous)
    else:
        alg = r.cls()
    alg.name = r.name
    return alg


def name_of(alg: Algorithm) -> str:
    """The name of an algorithm object (one made by :func:`make`, or made directly from a class of the
    table); "" for a class of the caller's own."""
    if alg.name:
        return alg.name
    if isinstance(alg, MultiRate):
        return JACOBI if alg.jacobi else GAUSS_SEIDEL
    if isinstance(alg, ParallelJacobi):
        return JACOBI
    if isinstance(alg, ParallelGaussSeidel):
        return GAUSS_SEIDEL
    return next((r.name for r in ROWS if type(alg) is r.cls), "")


def summary(alg: Algorithm) -> dict[str, Any] | None:
    """The algorithm's counts for summary.json ("stepping"), its name first; None when it has none."""
    own = alg.summary()
    if own is None:
        return None
    head: dict[str, Any] = {"algorithm": name_of(alg)}
    if isinstance(alg, Adaptive):
        head[ADAPTIVE_TABLE] = alg.settings().as_dict()
    return {**head, **own}

