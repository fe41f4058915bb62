"""The coupling structure of a system, from its connections and its FMUs' model descriptions.

* A **coupling loop** is a set of instances that feed each other through Float64 connections (a strongly
  connected component of the plan's graph of copies, ``plan.feeds``, "an output of a feeds an input of b",
  with more than one instance, or one that feeds itself: :attr:`~..stepping.graph.FeedGraph.loops`, which
  the iterated algorithms step by).  The iterated algorithms solve each as one; under one pass per step its
  instances see each other's outputs of the previous step (Jacobi) or of this one (Gauss-Seidel) only.
* An **algebraic loop** is a cycle of variables through the connections and the FMUs' direct
  dependencies: an output that depends on an input without delay (the model description's
  ``ModelStructure/Outputs``: an ``Unknown`` with that input in its ``dependencies``; without a
  ``dependencies`` attribute it depends on every input, as FMI 2.0 and 3.0 say).  Such a loop has no
  delay of its own: one pass per step lags it by a step, only the iterated coupling solves it.

``check`` prints both (:func:`describe_coupling`); :func:`check_iteration` refuses an algorithm that rolls
back an instance whose interface cannot get and set its state.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Iterable

from ..messages.errors import ScenarioError
from ..model.description import CO_SIMULATION, fmi2_cs_declares
from ..stepping import table as algorithms
from ..stepping.graph import FeedGraph, strongly_connected
from .records import ConnectionPlan, Coupling, InstancePlan

if TYPE_CHECKING:
    from ..model.description import FmuModel
    from ..scenario.document import Scenario


def direct_inputs(model: "FmuModel") -> dict[str, set[str]]:
    """For each output of the FMU (its own names), the inputs it depends on directly."""
    md = model.md
    inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    out: dict[str, set[str]] = {}
    for u in getattr(md, "outputs", None) or []:
        deps = u.dependencies
        out[u.variable.name] = set(inputs) if deps is None else {d.name for d in deps if d.causality == "input"}
    for v in md.modelVariables:   # an output the ModelStructure does not list: taken to depend on every input
        if v.causality == "output" and v.name not in out:
            out[v.name] = set(inputs)
    return out


def coupling(feeds: FeedGraph, insts: dict[str, InstancePlan], conns: Iterable[ConnectionPlan]) -> Coupling:
    """The coupling loops (those of the plan's graph ``feeds``, :attr:`FeedGraph.loops`) and the algebraic
    loops of the plan's instances and connections."""
    return Coupling(feeds.named(feeds.loops), _algebraic(list(feeds.names), insts, [c for c in conns if c.is_float64]))


def _algebraic(order: list[str], insts: dict[str, InstancePlan], conns: list[ConnectionPlan]) -> list[list[str]]:
    """The algebraic loops: one shortest cycle through the first output of each strongly connected set of
    variables (connections, then direct dependencies)."""
    nodes: list[tuple[str, str]] = []
    ids: dict[tuple[str, str], int] = {}

    def node(inst: str, var: str) -> int:
        key = (inst, var)
        if key not in ids:
            ids[key] = len(nodes)
            nodes.append(key)
        return ids[key]

    edges: list[tuple[int, int]] = []
    for c in conns:
        edges.append((node(c.src, c.src_var.name), node(c.dst, c.dst_var.name)))
    connected_inputs: dict[str, set[str]] = {}
    for c in conns:
        connected_inputs.setdefault(c.dst, set()).add(c.dst_var.name)
    for name in order:
        ins = connected_inputs.get(name)
        if not ins:
            continue
        for out, deps in direct_inputs(insts[name].model).items():
            for i in sorted(deps & ins):
                edges.append((node(name, i), node(name, out)))
    succ: list[list[int]] = [[] for _ in nodes]
    for a, b in edges:
        if b not in succ[a]:
            succ[a].append(b)
    rank = {n: i for i, n in enumerate(order)}
    found = []
    for comp in strongly_connected(len(nodes), succ):
        if len(comp) < 2:
            continue
        members = set(comp)
        start = min(comp, key=lambda v: (rank[nodes[v][0]], v))
        cycle = _shortest_cycle(start, succ, members)
        found.append([f"{nodes[v][0]}.{insts[nodes[v][0]].theirs_to_ours.get(nodes[v][1], nodes[v][1])}"
                      for v in cycle])
    return found


def _shortest_cycle(start: int, succ: list[list[int]], members: set[int]) -> list[int]:
    """The shortest cycle from ``start`` back to it within ``members`` (breadth first), start repeated."""
    prev: dict[int, int] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in succ[v]:
                if w not in members:
                    continue
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(prev[path[-1]])
                    return path[::-1] + [start]
                if w not in prev:
                    prev[w] = v
                    nxt.append(w)
        frontier = nxt
    raise AssertionError("a strongly connected set has a cycle through each of its nodes")


def describe_coupling(c: Coupling, algorithm: str) -> list[str]:
    """What ``check`` prints of the coupling: each coupling loop, each algebraic loop, and how the algorithm
    treats them."""
    lines = []
    row = algorithms.row(algorithm)
    solved = row.solves_loops
    for lp in c.loops:
        how = "iterated to its tolerance at every step" if solved else \
            ("one pass per step" if not row.varies_step else "one pass per step, the step size controlled")
        lines.append(f"coupling loop {' <-> '.join(lp)}: {how}")
    solver = " or ".join(f"algorithm = {algorithms.quoted(n)}" for n in algorithms.names_where("solves_loops"))
    for cyc in c.algebraic:
        text = " -> ".join(cyc)
        if solved:
            lines.append(f"algebraic loop {text}: solved at every step")
        else:
            lines.append(f"algebraic loop {text}: one pass per step lags it by a step ({solver} solves it)")
    return lines


def check_iteration(sc: "Scenario", insts: dict[str, InstancePlan], c: Coupling) -> None:
    """An algorithm that rolls instances back needs their interface to get and set the FMU state: the
    iterated coupling every instance of a coupling loop, the step-size control every instance; the
    iteration's linear inputs and directional Jacobian need what every loop instance declares (FMI 2.0
    co-simulation, canInterpolateInputs, providesDirectionalDerivative).  Otherwise one ScenarioError
    naming the instance."""
    algorithm = sc.algorithm
    rolls = algorithms.row(algorithm).rolls_back
    if rolls == "every":
        need = {n: f"the step-size control (algorithm = {algorithms.quoted(algorithm)}) rolls back every "
                   "instance when it rejects a step" for n in sc.order}
    elif rolls == "loops":
        need = {n: f"the iterated coupling rolls back the coupling loop {' <-> '.join(lp)} at every iteration"
                for lp in c.loops for n in lp}
    else:
        return
    for name in sc.order:
        ip = insts[name]
        if name in need and not ip.model.declares_state(ip.interface):
            raise ScenarioError(sc.file, f"instances.{name}",
                                f"{ip.model.path.name} cannot get and set its state through its {ip.interface} "
                                f"interface (canGetAndSetFMUstate is false), and {need[name]}")
    iterated = algorithms.iterates(algorithm, sc.adaptive.coupling if sc.adaptive is not None else None)
    if not iterated or sc.iteration is None:
        return
    for key, value, flag, gives in (("jacobian", "directional", "providesDirectionalDerivative",
                                     "give directional derivatives"),
                                    ("inputs", "linear", "canInterpolateInputs", "take its inputs' derivatives")):
        if getattr(sc.iteration, key) != value:
            continue
        for lp in c.loops:
            for name in lp:
                ip = insts[name]
                if not (ip.interface == CO_SIMULATION and fmi2_cs_declares(ip.model.md, flag)):
                    raise ScenarioError(sc.file, f"experiment.iteration.{key}",
                                        f"\"{value}\" needs every instance of the coupling loop "
                                        f"{' <-> '.join(lp)} to {gives} (an FMI 2.0 co-simulation FMU that "
                                        f"declares {flag}): {name} ({ip.model.path.name}, {ip.interface}) "
                                        "does not")
