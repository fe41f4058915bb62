"""The plots of a loop broken at one connection (``wmr-cosim linearize --break``): the Bode and Nyquist
plots of L = -G, margins marked, drawn from what the master's :class:`LoopAnalysis` holds (the loop gain,
its frequency grid, its margins and title).  Each plot is a matplotlib ``Figure`` on its own Agg canvas:
no pyplot, no backend chosen for the process, so a caller's backend is left as it set it."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..cosim import LoopAnalysis

#: The PNGs :func:`plot_loop` writes, in the order of :func:`loop_figures`.
FILES = ("bode.png", "nyquist.png")


def loop_figures(analysis: LoopAnalysis) -> tuple[Any, Any]:
    """The Bode and Nyquist plots of L (python-control's, margins marked) as matplotlib ``Figure`` objects
    on their own Agg canvases, titled by the loop (:attr:`LoopAnalysis.title`), over the loop's
    frequency grid [rad/s]."""
    import control
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    L = analysis.loop_gain()
    w = analysis.frequencies()
    bode = Figure(figsize=(7, 6))
    FigureCanvasAgg(bode)
    axes = np.asarray(bode.subplots(2, 1, sharex=True)).reshape(2, 1)
    control.bode_plot(L, w, ax=axes, display_margins=True)
    axes[0, 0].set_title(analysis.margins_text(), fontsize=8)   # (every crossover, not python-control's one)
    bode.suptitle(f"{analysis.title}: L = -G")
    nyquist = Figure(figsize=(6, 6))
    FigureCanvasAgg(nyquist)
    control.nyquist_plot(L, w, ax=nyquist.add_subplot())
    nyquist.suptitle(f"{analysis.title}: Nyquist of L = -G")
    return bode, nyquist


def plot_loop(analysis: LoopAnalysis, folder: str | Path) -> list[Path]:
    """``bode.png`` and ``nyquist.png`` of L in ``folder`` (:func:`loop_figures`; each PNG's ``Title``
    holds its title)."""
    folder = Path(folder)
    out = []
    for fig, name in zip(loop_figures(analysis), FILES):
        out.append(folder / name)
        fig.savefig(out[-1], dpi=110, metadata={"Title": fig.get_suptitle()})
    return out
