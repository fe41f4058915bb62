"""A loop broken at one connection: its frequency response, gain and phase margins, Bode and Nyquist plots.

The connection ``src -> dst`` is cut; a signal w is injected at ``dst`` and the return r = factor * src (what
the connection would carry, in the unit of ``dst``) is read, everything else connected as in the run.  G is
the model from w to r; closing the connection again is w = r, so the closed loop's characteristic equation
is 1 - G = 0.  The loop gain is taken as L = -G, the convention of a negative-feedback loop (1 + L = 0),
whose margins python-control's ``stability_margins`` gives: the gain margin is the factor by which L may be
multiplied before the loop becomes unstable at the phase crossover; the phase margin the lag that may be
added at the gain crossover.  A discrete-time G (a realisation from responses) gives the margins up to the
Nyquist frequency pi / dt.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .model import LinearModel


@dataclass
class LoopAnalysis:
    """The loop broken at ``src -> dst``: ``gain`` = G (the model from the injection to the return) and the
    margins of L = -G: ``gain_margin`` (a factor; inf where the phase never crosses -180 deg), ``phase_margin``
    [deg], at ``phase_crossover`` and ``gain_crossover`` [rad/s] (nan where there is none), ``stability_margin``
    (the least distance of L to -1); the closed loop's eigenvalues."""

    src: str
    dst: str
    gain: LinearModel
    gain_margin: float
    phase_margin: float
    phase_crossover: float
    gain_crossover: float
    stability_margin: float
    closed_eigenvalues: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))

    def summary(self) -> dict[str, Any]:
        """The figures as plain numbers (summary.json, the command's printout)."""
        def num(x: float) -> float | str:
            return x if math.isfinite(x) else str(x)
        return {"break": f"{self.src}->{self.dst}", "gain_margin": num(self.gain_margin),
                "gain_margin_db": num(20.0 * math.log10(self.gain_margin)) if self.gain_margin > 0 else "nan",
                "phase_margin_deg": num(self.phase_margin), "phase_crossover_rad_s": num(self.phase_crossover),
                "gain_crossover_rad_s": num(self.gain_crossover), "stability_margin": num(self.stability_margin),
                "closed_loop_stable": bool(self.closed_stable)}

    @property
    def closed_stable(self) -> bool:
        ev = self.closed_eigenvalues
        if self.gain.continuous:
            return bool(np.all(ev.real < 0))
        return bool(np.all(np.abs(ev) < 1))

    def loop_gain(self) -> Any:
        """L = -G as a python-control ``StateSpace``."""
        return -self.gain.statespace()


def analyse(gain: LinearModel, src: str, dst: str) -> LoopAnalysis:
    """The margins of the loop whose injection-to-return model is ``gain`` (one input, one output)."""
    import control

    if gain.A.shape[0] and (len(gain.inputs), len(gain.outputs)) != (1, 1):
        raise ValueError("a loop is analysed from one injection to one return")
    G = gain.statespace()
    L = -G
    with warnings.catch_warnings():   # (its note that a discrete L is taken by the frequency response)
        warnings.filterwarnings("ignore", message="stability_margins: Falling back", category=UserWarning)
        gm, pm, sm, wpc, wgc, _ = control.stability_margins(L)
    closed = np.linalg.eigvals(gain.A + gain.B @ np.linalg.solve(np.eye(1) - gain.D, gain.C)) \
        if gain.A.size else np.zeros(0, dtype=complex)
    return LoopAnalysis(src, dst, gain, float(gm), float(pm), float(wpc), float(wgc), float(sm), closed)


def frequencies(gain: LinearModel, n: int = 400) -> np.ndarray:
    """A logarithmic grid [rad/s] over the poles' range (up to the Nyquist frequency in discrete time)."""
    ev = gain.eigenvalues()
    if gain.continuous:
        mags = np.abs(ev[np.abs(ev) > 0])
    else:
        mags = np.abs(np.log(ev[(np.abs(ev) > 0) & (np.abs(ev - 1) > 0)].astype(complex))) / gain.dt
    lo = max(float(mags.min()) / 100 if mags.size else 1e-2, 1e-6)
    hi = float(mags.max()) * 100 if mags.size else 1e3
    if not gain.continuous:
        hi = min(hi, math.pi / gain.dt)
    return np.logspace(math.log10(lo), math.log10(max(hi, lo * 10)), n)


def plot_loop(analysis: LoopAnalysis, folder: str | Path) -> list[Path]:
    """``bode.png`` and ``nyquist.png`` of L in ``folder`` (python-control's plots, margins marked)."""
    import control
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    L = analysis.loop_gain()
    w = frequencies(analysis.gain)
    out = []
    fig = plt.figure(figsize=(7, 6))
    control.bode_plot(L, w, display_margins=True, title=f"loop gain L = -G, broken at {analysis.src} -> "
                                                         f"{analysis.dst}")
    out.append(folder / "bode.png")
    fig.savefig(out[-1], dpi=110)
    plt.close(fig)
    fig = plt.figure(figsize=(6, 6))
    control.nyquist_plot(L, w, title=f"Nyquist of L, broken at {analysis.src} -> {analysis.dst}")
    out.append(folder / "nyquist.png")
    fig.savefig(out[-1], dpi=110)
    plt.close(fig)
    return out
