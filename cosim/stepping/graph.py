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
