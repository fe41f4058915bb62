"""Graphs of the instances: who feeds whom (:class:`FeedGraph`, the one graph the plan builds from its
connections, ``check`` prints and the algorithms step by), the strongly connected sets of a directed graph
(Tarjan), which the coupling loops are and which the iterating algorithms step together, and Gauss-Seidel's
levels, whose instances may step at once."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Iterable


@dataclass(frozen=True)
class FeedGraph:
    """Who feeds whom among the instances ``names`` (in the plan's order; an instance is its index there),
    by kind of connection: ``copies[i]``, the instances whose Float64 outputs instance i's Float64 inputs
    copy (the copies of the stepping loop); ``reads[i]``, those whose outputs of other types its inputs take
    (an FMI get and set each).  The plan builds it from its connections (``plan.feeds``); the execution
    hands the algorithm the plan's, cut where an override holds an input's value in place of its
    connection's (:meth:`of`, from what still connects)."""

    names: tuple[str, ...] = ()
    copies: tuple[frozenset[int], ...] = ()
    reads: tuple[frozenset[int], ...] = ()

    @classmethod
    def of(cls, names: Iterable[str], links: Iterable[tuple[str, str, bool]]) -> "FeedGraph":
        """The graph of links (source instance, destination instance, whether a Float64 copy); a link
        naming an instance outside ``names`` is left out."""
        order = tuple(names)
        index = {n: i for i, n in enumerate(order)}
        copies: list[set[int]] = [set() for _ in order]
        reads: list[set[int]] = [set() for _ in order]
        for src, dst, copied in links:
            if src in index and dst in index:
                (copies if copied else reads)[index[dst]].add(index[src])
        return cls(order, tuple(frozenset(s) for s in copies), tuple(frozenset(s) for s in reads))

    @cached_property
    def depends(self) -> list[set[int]]:
        """For each instance, the instances whose outputs its inputs take, of every kind."""
        return [set(c | r) for c, r in zip(self.copies, self.reads)]

    @cached_property
    def components(self) -> list[list[int]]:
        """The strongly connected components of the graph of copies ("Float64 outputs of a feed inputs of
        b"), each in the plan's order, in the order of their first instance (the order in which the
        instances step)."""
        succ: list[list[int]] = [[] for _ in self.names]
        for b, srcs in enumerate(self.copies):
            for a in sorted(srcs):
                succ[a].append(b)
        return strongly_connected(len(self.names), succ)

    def is_loop(self, comp: list[int]) -> bool:
        """Whether a component is a coupling loop: more than one instance, or one that feeds itself."""
        return len(comp) > 1 or comp[0] in self.copies[comp[0]]

    @cached_property
    def loops(self) -> list[list[int]]:
        """The coupling loops: the components that are loops, in stepping order."""
        return [comp for comp in self.components if self.is_loop(comp)]

    @cached_property
    def levels(self) -> list[list[int]]:
        """Gauss-Seidel's pass cut into levels whose instances may step at once (:func:`levels`, over
        every kind of connection)."""
        return levels(len(self.names), self.depends)

    def named(self, groups: list[list[int]]) -> list[list[str]]:
        """Groups of instances by their names."""
        return [[self.names[i] for i in g] for g in groups]


def strongly_connected(n: int, succ: list[list[int]]) -> list[list[int]]:
    """The strongly connected components of a graph of nodes 0..n-1 with successors ``succ``, each sorted,
    in the order of their smallest node (Tarjan's algorithm, iteratively)."""
    index: dict[int, int] = {}
    low: dict[int, int] = {}
    on: set[int] = set()
    stack: list[int] = []
    out: list[list[int]] = []
    counter = 0
    for root in range(n):
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            v, i = work.pop()
            if i == 0:
                index[v] = low[v] = counter
                counter += 1
                stack.append(v)
                on.add(v)
            if i < len(succ[v]):
                work.append((v, i + 1))
                w = succ[v][i]
                if w not in index:
                    work.append((w, 0))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                out.append(sorted(comp))
            if work:
                u = work[-1][0]
                low[u] = min(low[u], low[v])
    return sorted(out, key=lambda c: c[0])


def levels(n: int, fed_by: list[set[int]]) -> list[list[int]]:
    """Gauss-Seidel's pass over nodes 0..n-1 (in that order; ``fed_by[i]``: the nodes whose outputs node i
    reads) as levels whose nodes may step at once, bit for bit as the pass: each level's inputs set, its
    nodes stepped, its outputs read, level after level.  Node i's level is above that of each node before it
    that feeds it (it reads that node's outputs of this step) and not below that of each node before it
    that it feeds (that node reads i's outputs of the previous step: read in a level before, or in the same
    level before any output of it is).  Each level's nodes in order, the levels in order."""
    level = [0] * n
    for i in range(n):
        lv = 0
        for a in fed_by[i]:
            if a < i:
                lv = max(lv, level[a] + 1)
        for b in range(i):
            if i in fed_by[b]:
                lv = max(lv, level[b])
        level[i] = lv
    out: list[list[int]] = [[] for _ in range(max(level, default=-1) + 1)]
    for i in range(n):
        out[level[i]].append(i)
    return out
