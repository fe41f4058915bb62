"""The analysis of the paper's experiments from recorded runs: the figures of Tables 2 and 3, the
disturbance estimate (52), the H-infinity gain (53), the true gains a simulation can add, and how close
the whole is to the paper.

Signals are dicts of numpy arrays named as recorded ('time', 'plant.x_A', 'controller.e1', ...).
Units: rad, rad/s, N.m, m, s.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..components import paper
from ..components.metrics import rmse, run_metrics
from ..cosim import RunResult, RunStatus

Signals = dict[str, np.ndarray]
RUNS = ("learn", "frozen", "foam")
#: the tables' rows: our run name -> the paper's row (Table 2/3 "without disturbances" / "under changing
#: operating conditions"); the frozen run is ours only (the reference of (52))
TABLE_ROWS = {"learn": "learn", "foam": "foam"}
#: the window after the foam's onset t_F in which the peak control at the edge is taken [s]
EDGE_WINDOW_S = 2.0
#: a run whose |e_i| at its last sample is above this has diverged [rad]: the paper's static errors are
#: 0.06-0.18 rad and its largest RMSE of e 0.40 rad, so an error above 1 rad at the end is no longer tracking
DIVERGED_E_RAD = 1.0
#: the tracking errors the paper's controller records (e [rad], de/dt [rad/s], per wheel)
TRACKING_ERRORS = ("controller.e1", "controller.e2", "controller.edot1", "controller.edot2")


def judge_run(res: RunResult) -> RunResult:
    """A finished run of the paper's controller judged by :func:`divergence`: a run that
    ended 'ok' but diverged gets the status 'diverged' (exit code 1) and the reason as its message.  A run
    that did not record the controller's tracking errors is left as it is."""
    if res.status != RunStatus.OK or res.out_dir is None:
        return res
    sig = load_signals(res.out_dir)
    if sig is None or not all(name in sig for name in TRACKING_ERRORS):
        return res
    reason = divergence(sig)
    if reason is not None:
        res.status, res.message = RunStatus.DIVERGED, reason
        summary = res.out_dir / "summary.json"     # the file on disk says what the command says
        if summary.is_file():
            from ..cosim import write_json
            doc = json.loads(summary.read_text(encoding="utf-8"))
            doc["status"], doc["message"] = res.status, res.message
            write_json(summary, doc)
    return res


def requirement_verdicts(folder: str | Path) -> dict[str, dict[str, Any]]:
    """The verdicts of a run's requirements, by name (summary.json's ``requirements``; {} when it has none
    or no summary)."""
    import json

    f = Path(folder) / "summary.json"
    try:
        doc = json.loads(f.read_text(encoding="utf-8")) if f.is_file() else {}
    except (OSError, ValueError):
        return {}
    return {r["name"]: r for r in doc.get("requirements") or [] if isinstance(r, dict) and "name" in r}


def load_signals(folder: str | Path) -> Signals | None:
    """The signals of one run folder (None if it recorded nothing; its whole rows when it was cut short);
    ResultsError (one line) when its signals.npy cannot be read."""
    from ..cosim import read_signals

    f = Path(folder) / "signals.npy"
    if not f.is_file():
        return None
    data = read_signals(f).signals
    if not len(data):
        return None
    names = data.dtype.names or ()   # never None: read_signals returns a structured array
    sig = {name: np.asarray(data[name]) for name in names}
    for name in names:  # FMI 3.0 array columns (W[1], P[1,2]) also under the FMI 2.0 names (W1, P12)
        if name.endswith("]") and "[" in name:
            i = name.rindex("[")  # the element's own index (s[2].v[1] is s[2].v1)
            sig.setdefault(name[:i] + name[i + 1:-1].replace(",", ""), sig[name])
    return sig


def divergence(sig: Signals | None, status: str = "ok") -> str | None:
    """Why a run of the paper's controller diverged, as one line, or None if it did not: THE definition of
    'diverged' of the paper job, its sweeps and ``wmr-cosim run`` of a protocol.  A run diverged if it did
    not end 'ok', recorded nothing, a tracking error (e, de/dt) is not finite, or the larger |e_i| at its
    last sample is above DIVERGED_E_RAD."""
    if status != "ok":
        return f"the run ended {status!r}"
    if sig is None:
        return "nothing was recorded"
    for name in TRACKING_ERRORS:
        if not np.all(np.isfinite(sig[name])):
            return f"{name.split('.', 1)[1]} is not finite"
    i = max((1, 2), key=lambda k: abs(float(sig[f"controller.e{k}"][-1])))
    e = abs(float(sig[f"controller.e{i}"][-1]))
    if e > DIVERGED_E_RAD:
        at = f" at t = {float(sig['time'][-1]):g} s" if "time" in sig else " at the end"
        return f"|e{i}| = {e:.3g} rad{at}, above {DIVERGED_E_RAD:g} rad"
    return None


def cumulative_integral(f: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The trapezoidal integral of f from t[0] to every t[k]."""
    out = np.zeros_like(f, dtype=float)
    out[1:] = np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))
    return out


def cruise_mask(sig: Signals, v_star: float) -> np.ndarray:
    """Samples at cruising speed: the desired speed of A at least 95 % of v*."""
    return sig["controller.v_A_d"] >= 0.95 * v_star


def run_summary(sig: Signals | None, goal: tuple[float, float] | None, status: str = "ok") -> dict[str, Any]:
    """Table 2/3 figures of one run and more: RMSE (54) of e and e_dot per wheel over all samples,
    the true final position of A, the time eps_G was reached, diverged, final W, cruising and peak control."""
    if sig is None:
        return {"rmse_e": None, "rmse_edot": None, "final_position": None, "t_goal": None, "diverged": True,
                "status": status, "samples": 0}
    m = run_metrics(sig, goal)
    v_star = paper.table1()["v_star"]
    cr = cruise_mask(sig, v_star)
    u1, u2 = sig["controller.u1"], sig["controller.u2"]
    true = true_errors(sig)
    out = {
        "rmse_e": m["rmse_e"], "rmse_edot": m["rmse_edot"],
        "rmse_e_true": [rmse(true["e1"]), rmse(true["e2"])] if true else None,
        "rmse_edot_true": [rmse(true["edot1"]), rmse(true["edot2"])] if true else None, "final_position": m["final_position"],
        "t_goal": m["t_goal"], "diverged": divergence(sig, status) is not None, "status": status,
        "samples": int(len(sig["time"])), "final_W": m["final_W"],
        "cruise_u": [float(np.mean(u1[cr])), float(np.mean(u2[cr]))] if cr.any() else None,
        "peak_u": [float(np.max(np.abs(u1))), float(np.max(np.abs(u2)))],
        "final_e": [float(sig["controller.e1"][-1]), float(sig["controller.e2"][-1])],
        "final_abs_e": float(max(abs(sig["controller.e1"][-1]), abs(sig["controller.e2"][-1]))),
        "t_move": t_move(sig, v_star),
        "final_u": [float(u1[-1]), float(u2[-1])],
    }
    if goal is not None:
        out["goal_distance"] = m["goal_distance"]
    return out


def true_errors(sig: Signals) -> dict[str, np.ndarray] | None:
    """The TRUE tracking errors from the plant's wheel angles and speeds: e_i = alpha_d_i - alpha_i [rad],
    edot_i = alpha_dot_d_i - alpha_dot_i [rad/s] (the controller's e, edot use the measured angle and the
    filtered speed, which lag the true ones through the filter (43)).  None if the run did not record
    the plant's angles and the desired ones."""
    need = [f"{src}{i}" for i in (1, 2) for src in ("plant.alpha", "plant.alpha_dot", "controller.alpha_d",
                                                     "controller.alpha_dot_d")]
    if not all(n in sig for n in need):
        return None
    return {f"e{i}": sig[f"controller.alpha_d{i}"] - sig[f"plant.alpha{i}"] for i in (1, 2)} | {
        f"edot{i}": sig[f"controller.alpha_dot_d{i}"] - sig[f"plant.alpha_dot{i}"] for i in (1, 2)}


def t_move(sig: Signals, v_star: float, fraction: float = 0.01) -> float | None:
    """The first time [s] the desired speed of A reaches ``fraction`` of v*: before it, the profile (50)
    (a logistic step at b1 = 5 s with slope c = 10 1/s) keeps the robot at rest."""
    on = np.nonzero(sig["controller.v_A_d"] >= fraction * v_star)[0]
    return float(sig["time"][on[0]]) if on.size else None


def foam_onset(foam: Signals) -> float:
    """t_F: the last sample before the foam's friction change appears in the plant (the paper reads it
    from the disturbance course)."""
    lvl = foam["plant.foam_level"]
    on = np.nonzero(lvl > 0.0)[0]
    if not on.size:
        return math.inf
    return float(foam["time"][max(on[0] - 1, 0)])


def disturbance_analysis(frozen: Signals, foam: Signals, Q: float, R: float, ramp: float = 0.1) -> dict[str, Any]:
    """(52), (53) and the gains a simulation can add.

    dF_est_i = u_foam_i - u_frozen_i for t > t_F, 0 before (the estimate (52); not the controller's output
    dF_hat, the maximising player of (46)); gamma*(t) = sqrt(int_0^t [s'Qs + u'Ru] / int_0^t dF_est'dF_est) on
    the foam run (53); gamma_true(t): (53) with the injected dF (the plant's
    output) in the denominator; gain_incremental = sqrt(int |z_foam - z_frozen|^2 / int |dF|^2) with
    |z|^2 = s'Qs + u'Ru (9): the gain from the injected disturbance to the change of the controlled output.
    Q, R: the weights of (9) (multiples of the identity); ramp [s]: the foam's ramp, before the window
    of the control's rise.  gamma is not an argument: (53) measures the gain, it does not use gamma.
    """
    # a diverged run gives inf, and every gain is 0/0 or c/0 before the disturbance starts: nan, no warnings
    with np.errstate(all="ignore"):
        return _disturbance_analysis(frozen, foam, Q, R, ramp)


def table1_disturbance_analysis(frozen: Signals, foam: Signals) -> dict[str, Any]:
    """:func:`disturbance_analysis` with the weights of Table 1 (Q = 1, R = 0.5): the (52)/(53) figures
    of the paper job, whose runs all use them (a sweep uses each point's own weights)."""
    t1 = paper.table1()
    return disturbance_analysis(frozen, foam, Q=t1["Q"], R=t1["R"])


def _disturbance_analysis(frozen: Signals, foam: Signals, Q: float, R: float, ramp: float) -> dict[str, Any]:
    n = min(len(frozen["time"]), len(foam["time"]))
    t = foam["time"][:n]
    tF = foam_onset(foam)
    after = t > tF
    du1 = np.where(after, foam["controller.u1"][:n] - frozen["controller.u1"][:n], 0.0)
    du2 = np.where(after, foam["controller.u2"][:n] - frozen["controller.u2"][:n], 0.0)
    s1, s2 = foam["controller.s1"][:n], foam["controller.s2"][:n]
    u1, u2 = foam["controller.u1"][:n], foam["controller.u2"][:n]
    cost = cumulative_integral(Q * (s1 * s1 + s2 * s2) + R * (u1 * u1 + u2 * u2), t)
    den_hat = cumulative_integral(du1 * du1 + du2 * du2, t)
    d1, d2 = foam["plant.dF1"][:n], foam["plant.dF2"][:n]
    den_true = cumulative_integral(d1 * d1 + d2 * d2, t)
    g_star = np.where(den_hat > 0, np.sqrt(cost / den_hat), np.nan)
    g_true = np.where(den_true > 0, np.sqrt(cost / den_true), np.nan)
    dz = (Q * ((s1 - frozen["controller.s1"][:n]) ** 2 + (s2 - frozen["controller.s2"][:n]) ** 2)
          + R * ((u1 - frozen["controller.u1"][:n]) ** 2 + (u2 - frozen["controller.u2"][:n]) ** 2))
    num_inc = cumulative_integral(dz, t)
    g_inc = np.where(den_true > 0, np.sqrt(num_inc / den_true), np.nan)
    # the rise of the control on the foam: its mean over the 2 s after the edge (the ramp and 0.5 s over),
    # where the robot still moves at about its speed at the edge
    settled = (t > tF + ramp + 0.5) & (t <= tF + ramp + 2.5)
    rise = [float(np.mean((foam[f"controller.u{i}"][:n] - frozen[f"controller.u{i}"][:n])[settled]))
            if settled.any() else None for i in (1, 2)]
    # the control at the foam's edge: the largest |u_i| of the foam run within EDGE_WINDOW_S of t_F, and
    # of the frozen run over the same samples (the paper reports 8.4 N.m there on the real robot)
    edge = (t >= tF) & (t <= tF + EDGE_WINDOW_S)
    edge_peak = edge_peak_frozen = None
    if edge.any():
        edge_peak = float(max(np.max(np.abs(u1[edge])), np.max(np.abs(u2[edge]))))
        edge_peak_frozen = float(max(np.max(np.abs(frozen["controller.u1"][:n][edge])),
                                     np.max(np.abs(frozen["controller.u2"][:n][edge]))))
    return {
        "t_F": tF, "time": t, "dF_est": (du1, du2), "dF_true": (d1, d2), "gamma_star_curve": g_star,
        "gamma_true_curve": g_true, "gain_incremental_curve": g_inc,
        "gamma_star": _last_finite(g_star), "gamma_true": _last_finite(g_true),
        "gain_incremental": _last_finite(g_inc),
        "edge_peak_u": edge_peak, "edge_peak_u_frozen": edge_peak_frozen,
        "foam_rise": rise,
        "dF_est_rms": float(rmse(np.concatenate([du1[after], du2[after]]))) if after.any() else None,
    }


def _last_finite(x: np.ndarray) -> float | None:
    ok = np.isfinite(x)
    return float(x[ok][-1]) if ok.any() else None


def fidelity(tasks: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The 32 RMSE cells of Tables 2 and 3 (ours against the paper's): each ratio, how many within a
    factor 1.5 and 2.5, and the rms log-factor exp(sqrt(mean(log(ours/paper)^2)))."""
    cells = []
    for task in paper.TASKS:
        ref = paper.rmse_table(task)
        for run, row in TABLE_ROWS.items():
            m = tasks.get(task, {}).get(run)
            names = ("e_1", "e_2", "e_dot_1", "e_dot_2")
            ours = (m["rmse_e"] + m["rmse_edot"]) if m and m.get("rmse_e") else [None] * len(names)
            for name, o, p in zip(names, ours, ref[row]):
                ratio = (o / p) if (o is not None and math.isfinite(o)) else None
                cells.append({"task": task, "run": run, "cell": name, "ours": o, "paper": p, "ratio": ratio})
    logs = [math.log(c["ratio"]) for c in cells if c["ratio"] is not None and c["ratio"] > 0]
    complete = len(logs) == len(cells)
    return {
        "cells": cells,
        "n_cells": len(cells),
        "within_1_5": sum(1 for c in cells if c["ratio"] and 1 / 1.5 <= c["ratio"] <= 1.5),
        "within_2_5": sum(1 for c in cells if c["ratio"] and 1 / 2.5 <= c["ratio"] <= 2.5),
        "rms_log_factor": math.exp(math.sqrt(sum(x * x for x in logs) / len(logs))) if complete else None,
    }


def position_error(task: str, final_position: list[float] | None) -> float | None:
    """Distance [m] between our final position of A and the paper's (go-to-goal tasks)."""
    fp = paper.results()["final_positions"].get(task)
    if fp is None or final_position is None:
        return None
    return math.dist(fp, final_position)
