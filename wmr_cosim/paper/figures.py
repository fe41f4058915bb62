"""The paper's figures redrawn from our runs (PNG), in the layout of Figures 5-9 and 11-13.

Every axis carries its unit.  Functions take the signals of the runs (see analysis.load_signals) and
write one PNG each; they return the path.
"""
from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure   # (no pyplot: the process's backend is left as it is)

from ..components import paper

Signals = dict[str, np.ndarray]
WHEELS = (("1", "wheel 1", "C0"), ("2", "wheel 2", "C3"))
DPI = 110
#: the two disturbances of the paper, which it names alike: the maximising player of (46), which the
#: controller outputs (controller.dF_hat1, dF_hat2), and the estimate (52) from two runs' controls
PLAYER = "dF_hat (46)"
ESTIMATE = "dF_est (52)"


def _wheels(ax, sig: Signals, name: str, ylabel: str, title: str, scale: float = 1.0, label: str = "",
            colours: tuple[str, str] | None = None, ls: str = "-") -> None:
    t = sig["time"]
    for (i, wl, col), c in zip(WHEELS, colours or (None, None)):
        ax.plot(t, scale * sig[f"controller.{name}{i}"], color=c or col, lw=1.0, ls=ls, label=f"{label}{wl}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9, loc="left")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")


def _weights(ax, sig: Signals, title: str) -> None:
    t = sig["time"]
    for j in (1, 2, 3):
        ax.plot(t, sig[f"controller.W{j}"], lw=1.0, label=f"W{j}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("W [-]")
    ax.set_title(title, fontsize=9, loc="left")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    return path


def fig_learning(sig: Signals, out: Path, task: str, number: str) -> Path:
    """Fig. 5 (G1) / Fig. 11 (LINE): tracking errors, control and disturbance players, kinematic control and
    velocity profile, weight adaptation of the learning run."""
    fig = Figure(figsize=(10, 9))
    axs = fig.subplots(3, 2)
    _wheels(axs[0, 0], sig, "e", "e [rad]", f"(a) angle tracking error e, {task} learning")
    _wheels(axs[0, 1], sig, "edot", "de/dt [rad/s]", "(b) velocity tracking error")
    _wheels(axs[1, 0], sig, "u", "u [N.m]", "(c) control u (minimising player)")
    _wheels(axs[1, 1], sig, "dF_hat", f"{PLAYER} [N.m]", f"(d) worst-case disturbance {PLAYER}, the maximising player")
    ax = axs[2, 0]
    t = sig["time"]
    ax.plot(t, sig["controller.u_v"], lw=1.0, label="u_v")
    ax.plot(t, sig["controller.u_beta"], lw=1.0, label="u_beta")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("kinematic control [-]")
    ax2 = ax.twinx()
    ax2.plot(t, sig["controller.v_A_d"], color="k", lw=1.0, ls="--", label="v_A")
    ax2.set_ylabel("v_A [m/s]")
    ax.set_title("(e) kinematic control (31)-(32) and velocity profile (50)", fontsize=9, loc="left")
    ax.grid(True, alpha=0.3)
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=7)
    _weights(axs[2, 1], sig, "(f) critic weights W")
    fig.suptitle(f"Fig. {number} redrawn: {task}, learning run (adaptation 0-39 s, reference floor)", fontsize=10)
    return _save(fig, out / f"fig{number}_{task.lower()}_learn.png")


def fig_value_and_paths(g1: Signals, learns: dict[str, Signals], out: Path) -> Path:
    """Fig. 6: the value function of G1 (a) and the paths of point A to G1-G3 (b)."""
    # (b) gets the width its tall, equal-aspect path plot needs
    fig = Figure(figsize=(10, 5.2))
    axs = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.5, 1.0]})
    ax = axs[0]
    ax.plot(g1["time"], g1["controller.V_hat"], lw=1.0)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("V_hat [(rad/s)^2 s]")
    ax.set_title("(a) value function (45), G1 learning", fontsize=9, loc="left")
    ax.grid(True, alpha=0.3)
    ax = axs[1]
    goals = paper.table1()["goals"]
    for task, sig in learns.items():
        ax.plot(sig["plant.x_A"], sig["plant.y_A"], lw=1.2, label=f"{task} {tuple(goals[task])}")
        ax.plot(*goals[task], "kx")
    ax.plot(0, 0, "ko", ms=4)
    ax.set_xlabel("x_A [m]")
    ax.set_ylabel("y_A [m]")
    ax.set_aspect("equal", adjustable="box")
    ax.set_title("(b) paths of point A (true pose), learning runs", fontsize=9, loc="left")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.suptitle("Fig. 6 redrawn", fontsize=10)
    return _save(fig, out / "fig6_value_paths.png")


def fig_foam(sig: Signals, out: Path, task: str, number: str, t_F: float) -> Path:
    """Fig. 7 (G1) / Fig. 12 (LINE): errors, control and disturbance players on the foam."""
    fig = Figure(figsize=(10, 6.5))
    axs = fig.subplots(2, 2)
    _wheels(axs[0, 0], sig, "e", "e [rad]", f"(a) angle tracking error, {task} on foam")
    _wheels(axs[0, 1], sig, "edot", "de/dt [rad/s]", "(b) velocity tracking error")
    _wheels(axs[1, 0], sig, "u", "u [N.m]", "(c) control u")
    _wheels(axs[1, 1], sig, "dF_hat", f"{PLAYER} [N.m]", f"(d) worst-case disturbance {PLAYER}, the maximising player")
    for ax in axs.ravel():
        if np.isfinite(t_F):
            ax.axvline(t_F, color="k", lw=0.6, ls=":")
    fig.suptitle(f"Fig. {number} redrawn: {task}, learned weights frozen, foam from t_F = {t_F:.2f} s", fontsize=10)
    return _save(fig, out / f"fig{number}_{task.lower()}_foam.png")


def _gamma(ax, d: dict[str, Any], title: str, gamma: float) -> None:
    t = d["time"]
    ax.plot(t, d["gamma_star_curve"], lw=1.2, label=f"gamma* (53) with {ESTIMATE}")
    ax.plot(t, d["gamma_true_curve"], lw=1.0, ls="--", label="(53) with the injected dF")
    ax.axhline(gamma, color="k", lw=0.8, label=f"gamma = {gamma:g}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("gain [-]")
    finite = np.concatenate([x[np.isfinite(x)] for x in (d["gamma_star_curve"], d["gamma_true_curve"])] + [[gamma]])
    ax.set_ylim(0, 1.3 * max(gamma, float(np.percentile(finite, 99))))
    ax.set_title(title, fontsize=9, loc="left")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)


def _dF(ax, d: dict[str, Any], title: str) -> None:
    t = d["time"]
    for (_, wl, col), est, true in zip(WHEELS, d["dF_est"], d["dF_true"]):
        ax.plot(t, est, color=col, lw=1.0, label=f"{ESTIMATE}, {wl}")
        ax.plot(t, true, color=col, lw=0.8, ls="--", label=f"injected dF, {wl}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{ESTIMATE}, injected dF [N.m]")
    ax.set_title(title, fontsize=9, loc="left")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)


def fig_gamma_g1(d: dict[str, Any], out: Path, gamma: float) -> Path:
    """Fig. 8: the disturbance estimate (52) (a) and the gain curve (53) (b), G1."""
    fig = Figure(figsize=(10, 4.2))
    axs = fig.subplots(1, 2)
    _dF(axs[0], d, f"(a) disturbance estimate {ESTIMATE}, G1")
    _gamma(axs[1], d, "(b) gamma* gain (53), G1", gamma)
    fig.suptitle("Fig. 8 redrawn", fontsize=10)
    return _save(fig, out / "fig8_g1_gamma.png")


def fig_gamma_g2_g3(d2: dict[str, Any], d3: dict[str, Any], out: Path, gamma: float) -> Path:
    """Fig. 9: gamma* for G2 (a) and G3 (b)."""
    fig = Figure(figsize=(10, 4.2))
    axs = fig.subplots(1, 2)
    _gamma(axs[0], d2, "(a) gamma* gain (53), G2", gamma)
    _gamma(axs[1], d3, "(b) gamma* gain (53), G3", gamma)
    fig.suptitle("Fig. 9 redrawn", fontsize=10)
    return _save(fig, out / "fig9_g2_g3_gamma.png")


def fig_line_control(frozen: Signals, foam: Signals, d: dict[str, Any], out: Path, gamma: float) -> Path:
    """Fig. 13: the control without (a) and with (b) the foam, the estimate (52) (c), gamma and gamma* (d)."""
    fig = Figure(figsize=(10, 6.5))
    axs = fig.subplots(2, 2)
    _wheels(axs[0, 0], frozen, "u", "u [N.m]", "(a) control, reference floor")
    _wheels(axs[0, 1], foam, "u", "u [N.m]", "(b) control, foam")
    _dF(axs[1, 0], d, f"(c) disturbance estimate {ESTIMATE}")
    _gamma(axs[1, 1], d, "(d) gamma and gamma* (53)", gamma)
    fig.suptitle("Fig. 13 redrawn: LINE", fontsize=10)
    return _save(fig, out / "fig13_line_gamma.png")


def fig_line_learning(sig: Signals, out: Path) -> Path:
    """Fig. 11: LINE learning run: errors, control with 30 x the player dF_hat (46) (as the paper scales it),
    weights."""
    fig = Figure(figsize=(10, 6.5))
    axs = fig.subplots(2, 2)
    _wheels(axs[0, 0], sig, "e", "e [rad]", "(a) angle tracking error, LINE learning")
    _wheels(axs[0, 1], sig, "edot", "de/dt [rad/s]", "(b) velocity tracking error")
    _wheels(axs[1, 0], sig, "u", f"u, 30 x {PLAYER} [N.m]", f"(c) control u and 30 x {PLAYER}", label="u ")
    _wheels(axs[1, 0], sig, "dF_hat", f"u, 30 x {PLAYER} [N.m]", f"(c) control u and 30 x {PLAYER}", scale=30.0,
            label=f"30 x {PLAYER}, ", colours=("C2", "C1"), ls="--")
    _weights(axs[1, 1], sig, "(d) critic weights W")
    fig.suptitle("Fig. 11 redrawn: LINE, learning run", fontsize=10)
    return _save(fig, out / "fig11_line_learn.png")


#: what each figure shows, by file name (the report's captions)
CAPTIONS = {
    "fig5_g1_learn": "Fig. 5 redrawn, G1 learning run (adaptation 0-39 s, reference floor): (a) angle tracking "
                     "error e of both wheels (measured signal), (b) velocity tracking error, (c) control u, (d) the "
                     "maximising player dF_hat of (46), (e) the kinematic controls u_v, u_beta and the speed "
                     "profile v_A of (50), (f) the critic weights W, which change only in the acceleration phase.",
    "fig6_value_paths": "Fig. 6 redrawn: (a) the value function V_hat (45) along the G1 learning run; (b) the paths "
                        "of point A (true pose) of the three go-to-goal learning runs from (0, 0) to G1, G2, G3 "
                        "(crosses).",
    "fig7_g1_foam": "Fig. 7 redrawn, G1 with the learned weights frozen, foam from t_F (dotted line): tracking "
                    "errors (a, b), control (c) and the maximising player dF_hat of (46) (d); at t_F the control "
                    "steps up by the friction change.",
    "fig8_g1_gamma": "Fig. 8 redrawn, G1: (a) the disturbance estimate dF_est of (52) (foam run minus frozen run) "
                     "and the injected friction change (dashed); (b) gamma*(t) of (53) with the estimate and with "
                     "the injected dF, against gamma of Table 1.",
    "fig9_g2_g3_gamma": "Fig. 9 redrawn: gamma*(t) of (53) for G2 (a) and G3 (b), with the estimate dF_est of "
                        "(52) and with the injected dF, against gamma of Table 1.",
    "fig11_line_learn": "Fig. 11 redrawn, LINE learning run: (a) angle and (b) velocity tracking errors; (c) the "
                        "control u (solid, blue/red) and 30 x the maximising player dF_hat of (46) (dashed, "
                        "green/orange), scaled as in the paper; (d) the critic weights W.",
    "fig12_line_foam": "Fig. 12 redrawn, LINE with frozen weights, foam from t_F (dotted line): tracking errors "
                       "(a, b), control (c) and the maximising player dF_hat of (46) (d).",
    "fig13_line_gamma": "Fig. 13 redrawn, LINE: control without (a) and with (b) the foam, (c) the estimate "
                        "dF_est of (52) and the injected dF, (d) gamma*(t) of (53) against gamma of Table 1.",
    "robustness": "Robustness study: the largest RMSE of e of the foam run per task against the swept mismatch, "
                  "initial heading, encoder noise and bump at the foam's edge; crosses mark diverged points.",
}


def caption(path: str | os.PathLike) -> str:
    """The caption of a figure file: what it shows."""
    return CAPTIONS.get(Path(path).stem, Path(path).stem.replace("_", " "))


def fig_robustness(rob: dict[str, Any], out: str | os.PathLike) -> Path | None:
    """The robustness study: per axis, the largest RMSE of e of the foam run (measured signal) per task
    against the swept value; a point where a run of the task diverged is a cross at the top."""
    axes = [(a, lab) for a, lab in (("mismatch", "left/right mismatch m [%]"), ("heading", "initial heading [deg]"),
                                    ("noise", "encoder noise [counts, std]"),
                                    ("bump", "bump at the foam's edge [N.m]")) if rob.get(a)]
    if not axes:
        return None
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(3.4 * len(axes), 3.6))
    axs = fig.subplots(1, len(axes), squeeze=False)
    finite = [y for a, _ in axes for e in rob[a] for t in rob["tasks"]
              if not any(r.startswith(t + ".") for r in e["diverged_runs"])
              for y in [e["rmse_e_max"].get(t, {}).get("foam")] if y is not None and np.isfinite(y)]
    top = 1.5 * max(finite + [0.1])     # diverged points are drawn at this height
    for ax, (name, label) in zip(axs[0], axes):
        scale = 100.0 if name == "mismatch" else 1.0
        for k, task in enumerate(rob["tasks"]):
            xs, ys, xd = [], [], []
            for e in rob[name]:
                x = scale * e["value"]
                div = any(r.startswith(task + ".") for r in e["diverged_runs"])
                y = e["rmse_e_max"].get(task, {}).get("foam")
                if div or y is None:
                    xd.append(x)
                else:
                    xs.append(x)
                    ys.append(y)
            col = f"C{k}"
            ax.plot(xs, ys, "o-", color=col, ms=4, lw=1.0, label=task)
            if xd:
                ax.plot(xd, [top] * len(xd), "x", color=col, ms=8)
        ax.set_xlabel(label)
        ax.set_ylabel("foam run: max RMSE e [rad]")
        ax.set_ylim(0, top * 1.05)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Robustness beyond the paper (x at the top: a run of the task diverged)", fontsize=10)
    return _save(fig, out / "robustness.png")


def render_all(runs: Mapping[str, Mapping[str, Signals | None]], dist: Mapping[str, dict[str, Any]],
               out: str | os.PathLike) -> list[Path]:
    """Every figure for which the runs exist (``runs``: task -> run -> its signals, None or absent for a
    run that recorded nothing; ``dist``: task -> its (52)/(53) curves); returns the files written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    gamma = paper.table1()["gamma"]
    files: list[Path] = []

    def g(task: str, run: str) -> Signals | None:
        return runs.get(task, {}).get(run)

    g1_learn = g("G1", "learn")
    if g1_learn is not None:
        files.append(fig_learning(g1_learn, out, "G1", "5"))
    learns = {t: s for t in ("G1", "G2", "G3") if (s := g(t, "learn")) is not None}
    if g1_learn is not None and learns:
        files.append(fig_value_and_paths(g1_learn, learns, out))
    g1_foam = g("G1", "foam")
    if g1_foam is not None:
        files.append(fig_foam(g1_foam, out, "G1", "7", dist.get("G1", {}).get("t_F", np.inf)))
    if "G1" in dist:
        files.append(fig_gamma_g1(dist["G1"], out, gamma))
    if "G2" in dist and "G3" in dist:
        files.append(fig_gamma_g2_g3(dist["G2"], dist["G3"], out, gamma))
    line_learn, line_foam, line_frozen = g("LINE", "learn"), g("LINE", "foam"), g("LINE", "frozen")
    if line_learn is not None:
        files.append(fig_line_learning(line_learn, out))
    if line_foam is not None:
        files.append(fig_foam(line_foam, out, "LINE", "12", dist.get("LINE", {}).get("t_F", np.inf)))
    # the (52)/(53) curves of a task (dist) are made of its frozen and its foam run: both are there
    if "LINE" in dist and line_frozen is not None and line_foam is not None:
        files.append(fig_line_control(line_frozen, line_foam, dist["LINE"], out, gamma))
    return files
