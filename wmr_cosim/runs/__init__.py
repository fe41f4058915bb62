"""What serves a single run: what an FMU holds (``info``), the recorded signals of a results folder drawn
(``plot``), a linear model around a point of a run and a loop's margins (``linear_model``).

This face exports what the command line and the Python API use.
"""
from __future__ import annotations

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "info": ["describe"],
    "linear_model": ["linearize", "report", "write"],
    "plot": ["PlotError", "plot_results"],
})
