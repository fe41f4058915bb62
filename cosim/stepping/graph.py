"""Graphs of the instances: the strongly connected sets of a directed graph (Tarjan), which the
coupling loops are and which the iterating algorithms step together."""
from __future__ import annotations


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
