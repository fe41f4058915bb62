"""Who feeds whom: the plan's one graph of the instances (:class:`~..stepping.graph.FeedGraph`), built from
its connections once (``plan.feeds``).  ``check`` prints the coupling loops and Gauss-Seidel's levels from
it, and the execution hands it to the algorithm, which steps by it: the two agree by construction.

A Float64 -> Float64 connection is a copy of the stepping loop (:func:`is_real`); a connection of any other
types is an FMI get and set (a read).  An override of the input or of the output of a copy holds a value in
place of the connection's: the execution's graph then leaves that connection out (:func:`feed_graph` with
``cut``).
"""
from __future__ import annotations

from typing import Callable, Iterable

from ..model.description import Variable
from ..stepping.graph import FeedGraph
from .records import ConnectionPlan


def is_f64(var: Variable) -> bool:
    """A 64-bit real (FMI 2.0 Real, FMI 3.0 Float64): the values the generated loop copies directly."""
    return var.fmi_type in ("Real", "Float64")


def is_real(c: ConnectionPlan) -> bool:
    """A Float64 -> Float64 connection (a copy in the generated loop); the others are copied by closures."""
    return is_f64(c.src_var) and is_f64(c.dst_var)


def feed_graph(order: Iterable[str], conns: Iterable[ConnectionPlan],
               cut: Callable[[ConnectionPlan], bool] | None = None) -> FeedGraph:
    """The graph of the instances ``order`` through the connections ``conns``, by kind (copies and reads);
    ``cut``: the copies that an override holds (left out)."""
    return FeedGraph.of(order, ((c.src, c.dst, is_real(c)) for c in conns
                                if cut is None or not (is_real(c) and cut(c))))
