"""A loop broken at one connection: its frequency response, gain and phase margins, and what its Bode and
Nyquist plots are drawn from (the loop gain, a frequency grid, the margins and a title; the application
draws them).

The connection ``src -> dst`` is cut; a signal w is injected at ``dst`` and the return r = factor * src (what
the connection would carry, in the unit of ``dst``) is read, everything else connected as in the run.  G is
the model from w to r; closing the connection again is w = r, so the closed loop's characteristic equation
is 1 - G = 0.  The loop gain is taken as L = -G, the convention of a negative-feedback loop (1 + L = 0),
whose margins python-control's ``stability_margins`` gives (``returnall``: every crossover): at each phase
crossover (L on the negative real axis) the gain margin, the factor by which L may be multiplied before the
loop's stability changes there: above 1 an upper margin (the loop destabilises when the gain grows past
it), below 1 a lower one (when the gain falls below it: a conditionally stable loop, or an open loop with a
pole on or outside the stability boundary); at each gain crossover (|L| = 1) the phase margin, the lag
that may be added there.  A discrete-time G (a realisation from responses) gives the margins up to the
Nyquist frequency pi / dt, its ends w = 0 (z = 1) and pi / dt (z = -1) included.

The open loop's poles on or outside the stability boundary (the closed right half plane, the unit circle
and beyond) are named, within the model's accuracy (:func:`pole_tolerance`): a loop that needs its
feedback to be stable, or an integrator that a realisation puts a little inside or outside the circle.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .model import LinearModel
from .realisation import ORDER_RTOL

#: A continuous-time model's poles within this fraction of its largest pole's magnitude from the imaginary
#: axis are taken as on it (its Jacobian's accuracy: the differences are checked to 1e-6).
JACOBIAN_RTOL = 1e-6


#: A phase crossover where |L| is below 1 / this is the rounding of python-control's polynomial method (where
#: L has rolled off to nothing, its phase is noise: three lags give one at 1e8 rad/s with |L| = 2e-30): dropped.
NOISE_GAIN_MARGIN = 1e12


def pole_tolerance(model: LinearModel) -> float:
    """How close to the stability boundary a pole of ``model`` counts as on it: in continuous time
    :data:`JACOBIAN_RTOL` times the largest pole's magnitude [1/s]; for a realisation from responses
    (discrete time) the relative size of the first Hankel singular value left out, at least the order's
    cut :data:`ORDER_RTOL` (on |z|: a pole with |z| >= 1 - tolerance is on or outside the unit circle)."""
    if model.continuous:
        ev = model.eigenvalues()
        return JACOBIAN_RTOL * (float(np.abs(ev).max()) if ev.size else 1.0)
    sv = model.singular_values
    n = len(model.states)
    cut = float(sv[n] / sv[0]) if sv is not None and len(sv) > n and sv[0] > 0 else 0.0
    return max(ORDER_RTOL, cut)


def unstable_poles(model: LinearModel, tol: float) -> np.ndarray:
    """The poles of ``model`` on or beyond the stability boundary within ``tol`` (:func:`pole_tolerance`)."""
    ev = model.eigenvalues()
    if model.continuous:
        return ev[ev.real >= -tol]
    return ev[np.abs(ev) >= 1.0 - tol]


@dataclass
class LoopAnalysis:
    """The loop broken at ``src -> dst``: ``gain`` = G (the model from the injection to the return) and the
    margins of L = -G: ``gain_margin`` (a factor; python-control's choice among the phase crossovers, the
    one nearest 1; inf where the phase never crosses -180 deg), ``phase_margin`` [deg] (the least, at its
    crossover), at ``phase_crossover`` and ``gain_crossover`` [rad/s] (nan where there is none),
    ``stability_margin`` (the least distance of L to -1); every crossover: ``phase_crossovers`` (w [rad/s],
    gain margin) and ``gain_crossovers`` (w [rad/s], phase margin [deg]), by frequency; the closed loop's
    eigenvalues; the open loop's poles on or outside the stability boundary within ``pole_tolerance``."""

    src: str
    dst: str
    gain: LinearModel
    gain_margin: float
    phase_margin: float
    phase_crossover: float
    gain_crossover: float
    stability_margin: float
    closed_eigenvalues: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))
    phase_crossovers: list[tuple[float, float]] = field(default_factory=list)
    gain_crossovers: list[tuple[float, float]] = field(default_factory=list)
    pole_tolerance: float = 0.0
    boundary_poles: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))

    @property
    def upper_gain_margin(self) -> float:
        """The least gain margin above 1 (inf where there is none)."""
        return min((g for _, g in self.phase_crossovers if g > 1.0), default=math.inf)

    @property
    def lower_gain_margin(self) -> float:
        """The greatest gain margin below 1 (0 where there is none: no gain too small)."""
        return max((g for _, g in self.phase_crossovers if g < 1.0), default=0.0)

    @property
    def title(self) -> str:
        """What the plots are titled: the loop and the time of its point."""
        return f"Loop broken at {self.src} -> {self.dst}, t = {self.gain.t:g} s"

    def margins_text(self) -> str:
        """Every crossover in a line: "GM 42.03 (upper) at 98.75 rad/s, 0.0373 (lower) at 0 rad/s; PM 86.45
        deg at 5.92 rad/s"."""
        gms = ", ".join(f"{g:.4g} ({'lower' if g < 1 else 'upper'}) at {w:.4g} rad/s" for w, g in self.phase_crossovers)
        pms = ", ".join(f"{p:.4g} deg at {w:.4g} rad/s" for w, p in self.gain_crossovers)
        return f"GM {gms or 'inf'}; PM {pms or 'inf'}"

    def summary(self) -> dict[str, Any]:
        """The figures as plain numbers (linear.json, the command's printout)."""
        n = plain_number
        return {"break": f"{self.src}->{self.dst}", "gain_margin": n(self.gain_margin),
                "gain_margin_db": _db(self.gain_margin),
                "phase_margin_deg": n(self.phase_margin), "phase_crossover_rad_s": n(self.phase_crossover),
                "gain_crossover_rad_s": n(self.gain_crossover), "stability_margin": n(self.stability_margin),
                "upper_gain_margin": n(self.upper_gain_margin), "lower_gain_margin": n(self.lower_gain_margin),
                "phase_crossovers": [{"rad_s": n(w), "gain_margin": n(g), "gain_margin_db": _db(g),
                                      "kind": "lower" if g < 1.0 else "upper"} for w, g in self.phase_crossovers],
                "gain_crossovers": [{"rad_s": n(w), "phase_margin_deg": n(p)} for w, p in self.gain_crossovers],
                "open_loop_poles_on_or_outside": [[float(z.real), float(z.imag)] for z in self.boundary_poles],
                "pole_tolerance": self.pole_tolerance,
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

    def frequencies(self, n: int = 400) -> np.ndarray:
        """The frequency grid [rad/s] its plots are drawn over (:func:`frequencies` of ``gain``)."""
        return frequencies(self.gain, n)


def plain_number(x: float) -> float | str:
    """A figure for JSON: the number, or its name where it is not finite ("inf", "nan")."""
    x = float(x)
    return x if math.isfinite(x) else str(x)


def _db(g: float) -> float | str:
    return plain_number(20.0 * math.log10(g)) if g > 0 else "-inf" if g == 0 else "nan"


def margins(gain: LinearModel) -> tuple[list[tuple[float, float]], list[tuple[float, float]], tuple[float, ...]]:
    """Every crossover of L = -G: (phase crossovers (w [rad/s], gain margin), gain crossovers (w [rad/s],
    phase margin [deg]), python-control's own choice (gm, pm, sm, w_pc, w_gc)).  In discrete time the ends
    of the frequency range, z = 1 and z = -1, where L is real, are phase crossovers too when L is negative
    there (python-control's frequency-response fallback does not look at them)."""
    import control

    L = -gain.statespace()
    with warnings.catch_warnings():   # (its note that a discrete L is taken by the frequency response)
        warnings.filterwarnings("ignore", message="stability_margins: Falling back", category=UserWarning)
        warnings.filterwarnings("ignore", message="Badly conditioned filter coefficients")   # (scipy's, on the way)
        gms, pms, sms, w180, wc, _ = control.stability_margins(L, returnall=True)
    phase = [(float(w), float(g)) for w, g in zip(np.atleast_1d(w180), np.atleast_1d(gms)) if g <= NOISE_GAIN_MARGIN]
    if not gain.continuous and gain.A.size:
        nyquist = math.pi / gain.dt
        for w, z in ((0.0, 1.0), (nyquist, -1.0)):
            value = _response(gain, z)
            if value is not None and -value < 0 and all(abs(w - v) > 1e-9 * nyquist for v, _ in phase):
                phase.append((w, 1.0 / abs(value)))
    phase.sort()
    gains = sorted((float(w), float(p)) for w, p in zip(np.atleast_1d(wc), np.atleast_1d(pms)))
    # python-control's own choice among them (its stability_margins without returnall): the gain margin
    # nearest 1, the phase margin least in magnitude, the least stability margin
    gm, wpc = min(((g, w) for w, g in phase), key=lambda gw: abs(math.log(gw[0])) if gw[0] > 0 else math.inf,
                  default=(math.inf, math.nan))
    wgc, pm = min(gains, key=lambda wp: abs(wp[1]), default=(math.nan, math.inf))
    sm = float(np.min(sms)) if np.size(sms) else math.inf
    return phase, gains, (float(gm), float(pm), sm, float(wpc), float(wgc))


def _response(gain: LinearModel, z: complex) -> float | None:
    """G(z) = C (z I - A)^-1 B + D at a real z, or None where z is a pole (to the conditioning's accuracy)."""
    M = z * np.eye(len(gain.A)) - gain.A
    if np.linalg.cond(M) > 1e14:
        return None
    return float(np.real((gain.C @ np.linalg.solve(M, gain.B) + gain.D)[0, 0]))


def analyse(gain: LinearModel, src: str, dst: str) -> LoopAnalysis:
    """The margins of the loop whose injection-to-return model is ``gain`` (one input, one output)."""
    if gain.A.shape[0] and (len(gain.inputs), len(gain.outputs)) != (1, 1):
        raise ValueError("a loop is analysed from one injection to one return")
    phase, gains, (gm, pm, sm, wpc, wgc) = margins(gain)
    closed = np.linalg.eigvals(gain.A + gain.B @ np.linalg.solve(np.eye(1) - gain.D, gain.C)) \
        if gain.A.size else np.zeros(0, dtype=complex)
    tol = pole_tolerance(gain)
    return LoopAnalysis(src, dst, gain, gm, pm, wpc, wgc, sm, closed, phase, gains, tol,
                        unstable_poles(gain, tol))


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
