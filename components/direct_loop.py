"""The direct loop: plant, sensor chain and controller wired together in plain Python, no FMI.

Exchange order per communication step k (t_k = k h), the same as the co-simulation's Gauss-Seidel
order plant -> sensor -> controller:

1. the plant integrates from t_k to t_{k+1} with the torques the controller produced at t_k;
2. the sensor samples the wheel angles at t_{k+1};
3. the controller takes the measurements at t_{k+1} and produces the torques for the next step.

Time is computed as k h (never accumulated), so every implementation that does the same sees the same
floats.  Every output of every component is recorded at every sample t_0 ... t_N (N + 1 samples).
"""
from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .controller import CONTROLLER_OUTPUTS, Controller, ControllerParams
from .plant import PLANT_OUTPUTS, Plant, PlantParams
from .sensor import SENSOR_OUTPUTS, Sensor, SensorParams
from .validation import ParameterError, positive, step as check_step

#: |u| above this [N.m], or a non-finite value, stops the loop as diverged.
U_LIMIT = 1e9


@dataclass
class LoopResult:
    """Recorded signals of a run: ``signals['plant.alpha1']`` etc. (numpy arrays over ``signals['time']``)."""

    signals: dict[str, np.ndarray]
    status: str                      # 'ok' or 'diverged'
    message: str = ""
    steps: int = 0
    wall_s: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.signals[name]


def _signals(times: list[float], recs: list[tuple[str, tuple[str, ...], list[tuple[float, ...]]]]) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {"time": np.asarray(times)}
    for prefix, names, rows in recs:
        arr = np.asarray(rows, dtype=float).reshape(len(rows), len(names))
        for j, name in enumerate(names):
            out[f"{prefix}.{name}"] = arr[:, j]
    return out


def run_direct(plant: PlantParams | None = None, sensor: SensorParams | None = None,
               controller: ControllerParams | None = None, t_stop: float = 50.0, h: float = 0.002,
               disturbance: Callable[[float], tuple[float, float]] | None = None,
               record: bool = True) -> LoopResult:
    """Run the closed loop from t = 0 to t_stop [s] at communication step h [s].

    ``disturbance(t)`` optionally gives the plant's external disturbance torques (tau1, tau2) [N.m] held
    over the step starting at t.  With ``record=False`` only the final sample is kept.
    """
    check_step("direct loop", h)
    t_stop = positive("direct loop", "t_stop", t_stop)
    n = round(t_stop / h)
    if abs(n * h - t_stop) > 1e-9 * t_stop:
        raise ParameterError(f"direct loop parameter t_stop = {t_stop!r}: not a whole number of steps h = {h!r}")
    pl = Plant(plant)
    se = Sensor(sensor)
    co_ = Controller(controller)
    po = pl.outputs()
    se.reset(po[0], po[1])
    so = se.outputs()
    co = co_.reset(0.0, so[0], so[1], so[2], so[3], po[4], po[5], po[6])
    times = [0.0]
    rp, rs, rc = [po], [so], [co]
    tau1 = tau2 = 0.0
    status, message = "ok", ""
    pstep, sstep, cstep = pl.step, se.step, co_.step
    wall = _time.perf_counter()
    for k in range(n):   # (n >= 1: k is set here, or by the else clause)
        t = k * h
        tn = (k + 1) * h
        if disturbance is not None:
            tau1, tau2 = disturbance(t)
        try:
            po = pstep(t, h, co[0], co[1], tau1, tau2)
            so = sstep(h, po[0], po[1])
            co = cstep(tn, h, so[0], so[1], so[2], so[3], po[4], po[5], po[6])
        except (ValueError, OverflowError, ZeroDivisionError) as exc:  # a non-finite state reached a component
            status = "diverged"
            message = f"the state is no longer finite at t = {tn:.3f} s ({exc})"
            k -= 1
            break
        if record:
            times.append(tn)
            rp.append(po)
            rs.append(so)
            rc.append(co)
        u1, u2 = co[0], co[1]
        if not (-U_LIMIT < u1 < U_LIMIT and -U_LIMIT < u2 < U_LIMIT):
            status = "diverged"
            message = f"controller output u = ({u1!r}, {u2!r}) N.m at t = {tn:.3f} s"
            break
    else:
        k = n - 1
    wall = _time.perf_counter() - wall
    if not record:
        times, rp, rs, rc = [(k + 1) * h], [po], [so], [co]
    sig = _signals(times, [("plant", PLANT_OUTPUTS, rp), ("sensor", SENSOR_OUTPUTS, rs),
                           ("controller", CONTROLLER_OUTPUTS, rc)])
    return LoopResult(sig, status, message, k + 1, wall)
