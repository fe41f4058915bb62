"""Who feeds whom: the plan's one graph of the instances (:class:`~..stepping.graph.FeedGraph`), built from
its connections once (``plan.feeds``).  ``check`` prints the coupling loops and Gauss-Seidel's levels from
it, and the execution hands it to the algorithm, which steps by it: the two agree by construction.

A Float64 -> Float64 connection is a copy of the stepping loop (``ConnectionPlan.is_float64``); a connection of any other
types is an FMI get and set (a read).  An override of the input or of the output of a copy holds a value in
place of the connection's: the execution's graph then leaves that connection out (:func:`feed_graph` with
``cut``).
"""
from __future__ import annotations

from typing import Callable, Iterable

from ..stepping.graph import FeedGraph
from .records import ConnectionPlan


def feed_graph(order: Iterable[str], conns: Iterable[ConnectionPlan],
               cut: Callable[[ConnectionPlan], bool] | None = None) -> FeedGraph:
    """The graph of the instances ``order`` through the connections ``conns``, by kind (copies and reads);
    ``cut``: the copies that an override holds (left out)."""
    return FeedGraph.of(order, ((c.src, c.dst, c.is_float64) for c in conns
                                if cut is None or not (c.is_float64 and cut(c))))
