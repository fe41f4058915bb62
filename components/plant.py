"""The plant: Maggi dynamics (34)-(36) of the two drive wheels and the pose of point A (23)-(24).

States: wheel angles alpha_i [rad], wheel speeds alpha_dot_i [rad/s], pose of point A x_A, y_A [m] and
frame angle beta [rad].  Inputs: drive torques u_i = M_i [N.m] and an external disturbance torque tau_d_i
[N.m] acting in the sense of Delta F of (34) (positive opposes positive wheel rotation).  Both are held
constant over a communication step and integrated with RK4 in ``substeps`` substeps.

The foam (changing operating conditions) raises the rolling-resistance parameters a5, a6 by da_i:
Delta F_i = lambda(t) da_i 2 tanh(cF alpha_dot_i / 2), the shape of (36), where the level lambda ramps
linearly from 0 to 1 over ``foam_ramp`` seconds once the foam is reached: at time ``foam_t_on`` (if
``foam_on_time``) or at the first communication point at which point A is inside the rectangle
[foam_x_min, foam_x_max] x [foam_y_min, foam_y_max] (if ``foam_on_region``), whichever comes first.
An optional bump at the foam's edge (off by default): a5 and a6 rise by a further ``foam_bump`` for
``foam_bump_time`` seconds from the moment the foam is reached (the wheels climbing its edge).

Wheel 1 is the right wheel: by (23) its speed grows when the robot turns counter-clockwise.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from . import paper
from .friction import FRICTION_FORMS, shape_function
from .params import boolean, choice, finite, non_negative, param, positive, positive_int, validate
from .validation import ParameterError, mass_matrix_pd

_A = paper.table1()["a"]
_CF = paper.table1()["cF"]

#: Names of the values returned by :meth:`Plant.step` / :meth:`Plant.outputs`, in order.
PLANT_OUTPUTS = (
    "alpha1", "alpha2",            # wheel angles [rad]
    "alpha_dot1", "alpha_dot2",    # wheel speeds [rad/s]
    "x_A", "y_A", "beta",          # pose of point A [m, m, rad]
    "dF1", "dF2",                  # true disturbance torque applied: foam + tau_d [N.m]
    "foam_level",                  # lambda(t) in [0, 1]
)


@dataclass
class PlantParams:
    """Parameters of the plant: each field's unit, accepted values and meaning are in its declaration."""

    a1: float = param(_A[0], unit="kg.m2", check=finite,
                      doc="Maggi parameter a1 of M (35); a1..a3 must make M positive definite")
    a2: float = param(_A[1], unit="kg.m2", check=finite, doc="Maggi parameter a2 of M (35)")
    a3: float = param(_A[2], unit="kg.m2", check=finite, doc="Maggi parameter a3 of M (35)")
    a4: float = param(_A[3], unit="kg.m2", check=non_negative, doc="Maggi parameter a4 of C (35)")
    a5: float = param(_A[4], unit="N.m", check=non_negative,
                      doc="rolling-resistance parameter a5 of friction (36), wheel 1")
    a6: float = param(_A[5], unit="N.m", check=non_negative,
                      doc="rolling-resistance parameter a6 of friction (36), wheel 2")
    cF: float = param(_CF, unit="s/rad", check=positive, doc="slope cF of friction (36)")
    r: float = param(paper.WHEEL_RADIUS_M, unit="m", check=positive, doc="wheel radius r")
    l1: float = param(paper.HALF_AXLE_M, unit="m", check=positive, doc="half axle length l1")
    substeps: int = param(2, check=positive_int(1_000_000), doc="RK4 substeps per communication step")
    friction_form: str = param("tanh", check=choice(*FRICTION_FORMS),
                               doc="shape of friction (36): tanh (default, 2 a tanh(cF w/2)) or printed "
                                   "(the paper's exp form)")
    # initial state
    x0: float = param(0.0, unit="m", check=finite, doc="initial x of point A")
    y0: float = param(0.0, unit="m", check=finite, doc="initial y of point A")
    beta0: float = param(0.0, unit="rad", check=finite, doc="initial frame angle beta")
    # foam: friction change of the rolling-resistance parameters a5, a6
    foam_da1: float = param(0.0, unit="N.m", check=finite, tunable=True,
                            doc="foam: rise of a5 (wheel 1) at full foam level (friction change; tunable)")
    foam_da2: float = param(0.0, unit="N.m", check=finite, tunable=True,
                            doc="foam: rise of a6 (wheel 2) at full foam level (friction change; tunable)")
    foam_ramp: float = param(0.1, unit="s", check=non_negative, doc="foam: time the foam level ramps from 0 to 1")
    foam_on_time: bool = param(False, check=boolean, doc="foam: reached at time foam_t_on")
    foam_t_on: float = param(0.0, unit="s", check=finite, doc="foam: time it is reached (if foam_on_time)")
    foam_on_region: bool = param(False, check=boolean,
                                 doc="foam: reached when point A enters the rectangle foam_x/y_min..max")
    foam_x_min: float = param(0.0, unit="m", check=finite, doc="foam rectangle: x min")
    foam_x_max: float = param(0.0, unit="m", check=finite, doc="foam rectangle: x max")
    foam_y_min: float = param(0.0, unit="m", check=finite, doc="foam rectangle: y min")
    foam_y_max: float = param(0.0, unit="m", check=finite, doc="foam rectangle: y max")
    foam_bump: float = param(0.0, unit="N.m", check=non_negative,
                             doc="foam: further rise of a5 and a6 during the bump at the foam's edge "
                                 "(0 = off, the default)")
    foam_bump_time: float = param(0.2, unit="s", check=non_negative,
                                  doc="foam: duration of the bump from the moment the foam is reached")

    def __post_init__(self) -> None:
        validate(self, "plant")
        mass_matrix_pd("plant", self.a1, self.a2, self.a3)
        if self.foam_on_region and not (self.foam_x_min < self.foam_x_max and self.foam_y_min < self.foam_y_max):
            raise ParameterError(
                f"plant parameter foam region [{self.foam_x_min}, {self.foam_x_max}] x "
                f"[{self.foam_y_min}, {self.foam_y_max}]: empty rectangle (need x_min < x_max, y_min < y_max)")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def mass_matrix(a1: float, a2: float, a3: float) -> tuple[float, float]:
    """M of (35) as (m11, m12): M = [[m11, m12], [m12, m11]], m11 = a1+a2+a3, m12 = a1-a2 [kg m^2]."""
    return a1 + a2 + a3, a1 - a2


def mass_matrix_inverse(a1: float, a2: float, a3: float) -> tuple[float, float]:
    """M^-1 as (i11, i12): M^-1 = [[i11, i12], [i12, i11]] [1/(kg m^2)]."""
    m11, m12 = mass_matrix(a1, a2, a3)
    det = m11 * m11 - m12 * m12
    return m11 / det, -m12 / det


class Plant:
    """Maggi dynamics (34)-(36) + pose (23)-(24), RK4 with ``substeps`` substeps per communication step."""

    def __init__(self, params: PlantParams | None = None, **overrides: Any) -> None:
        if params is None:
            params = PlantParams(**overrides)
        elif overrides:
            params = PlantParams(**{**params.as_dict(), **overrides})
        self.p = params
        p = params
        self._i11, self._i12 = mass_matrix_inverse(p.a1, p.a2, p.a3)
        self._g = shape_function(p.friction_form)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Back to the initial state at t = 0: wheels at rest, point A at (x0, y0), frame angle beta0."""
        p = self.p
        self.t = 0.0
        self.x = [0.0, 0.0, 0.0, 0.0, p.x0, p.y0, p.beta0]
        self.u1 = self.u2 = 0.0
        self.tau1 = self.tau2 = 0.0
        self.t_foam = p.foam_t_on if p.foam_on_time else math.inf
        self.region_hit = False
        self._check_region()

    def get_state(self) -> dict[str, Any]:
        """All internal state as JSON-serialisable plain values."""
        return {"t": self.t, "x": list(self.x), "u": [self.u1, self.u2], "tau": [self.tau1, self.tau2],
                "t_foam": self.t_foam, "region_hit": self.region_hit}

    def set_state(self, s: dict[str, Any]) -> None:
        """Restore a state returned by :meth:`get_state`."""
        self.t = float(s["t"])
        self.x = [float(v) for v in s["x"]]
        self.u1, self.u2 = (float(v) for v in s["u"])
        self.tau1, self.tau2 = (float(v) for v in s["tau"])
        self.t_foam = float(s["t_foam"])
        self.region_hit = bool(s["region_hit"])

    # ------------------------------------------------------------------ physics
    def _check_region(self) -> None:
        p = self.p
        if p.foam_on_region and not self.region_hit:
            xa, ya = self.x[4], self.x[5]
            if p.foam_x_min <= xa <= p.foam_x_max and p.foam_y_min <= ya <= p.foam_y_max:
                self.region_hit = True
                if self.t < self.t_foam:
                    self.t_foam = self.t

    def foam_level(self, t: float) -> float:
        """lambda(t) in [0, 1]: 0 before the foam is reached, then a linear ramp over foam_ramp seconds."""
        tf = self.t_foam
        if t < tf:
            return 0.0
        ramp = self.p.foam_ramp
        if ramp <= 0.0 or t >= tf + ramp:
            return 1.0
        return (t - tf) / ramp

    def in_bump(self, t: float) -> bool:
        """Whether time t [s] is in the bump at the foam's edge (foam_bump_time seconds from the onset)."""
        tf = self.t_foam
        return tf <= t < tf + self.p.foam_bump_time

    def _forces(self, t: float) -> tuple[float, float]:
        """2 (a5 + level da1 [+ bump]), 2 (a6 + level da2 [+ bump]) at time t [N.m]."""
        p = self.p
        lam = self.foam_level(t)
        bump = p.foam_bump if self.in_bump(t) else 0.0   # (x + 0.0 is x: no bump, no change)
        return 2.0 * (p.a5 + lam * p.foam_da1 + bump), 2.0 * (p.a6 + lam * p.foam_da2 + bump)

    def derivatives(self, t: float, x: list[float], u1: float, u2: float,
                    tau1: float = 0.0, tau2: float = 0.0) -> list[float]:
        """dx/dt of the 7 states at time t [s] (the right-hand side integrated by :meth:`step`).

        (34): M alpha_ddot = u - C(alpha_dot) alpha_dot - F(alpha_dot) - Delta F, with (35), (36);
        (23)-(24): v_A = r (w1 + w2) / 2, beta_dot = r (w1 - w2) / (2 l1), x_dot = v_A cos beta, y_dot = v_A sin beta.
        """
        p = self.p
        f5, f6 = self._forces(t)
        w1, w2 = x[2], x[3]
        k = 0.5 * p.cF
        g1 = self._g(k * w1)
        g2 = self._g(k * w2)
        c = 2.0 * p.a4 * (w2 - w1)
        r1 = u1 - c * w2 - f5 * g1 - tau1
        r2 = u2 + c * w1 - f6 * g2 - tau2
        v = 0.5 * p.r * (w1 + w2)
        return [w1, w2, self._i11 * r1 + self._i12 * r2, self._i12 * r1 + self._i11 * r2,
                v * math.cos(x[6]), v * math.sin(x[6]), 0.5 * p.r * (w1 - w2) / p.l1]

    def step(self, t: float, h: float, u1: float, u2: float,
             tau1: float = 0.0, tau2: float = 0.0) -> tuple[float, ...]:
        """Advance from t to t + h [s] with torques u_i and disturbance torques tau_i [N.m] held constant.

        Returns the outputs at t + h, named by :data:`PLANT_OUTPUTS`.  The hot path: plain floats, the
        derivative inlined in the RK4 stages.
        """
        p = self.p
        self.t = t
        self.u1, self.u2, self.tau1, self.tau2 = u1, u2, tau1, tau2
        if p.foam_on_region and not self.region_hit:
            self._check_region()
        n = p.substeps
        dt = h / n
        hdt = 0.5 * dt
        i11, i12 = self._i11, self._i12
        g = self._g
        k = 0.5 * p.cF
        a4x2 = 2.0 * p.a4
        a5, a6, da1, da2 = p.a5, p.a6, p.foam_da1, p.foam_da2
        hr = 0.5 * p.r
        hrl = hr / p.l1
        cos, sin = math.cos, math.sin
        level = self.foam_level
        forces = self._forces
        # the foam level is constant over the whole step before the foam and after its ramp (and bump)
        end = max(p.foam_ramp, p.foam_bump_time) if p.foam_bump > 0.0 else p.foam_ramp
        static = t + h < self.t_foam or t >= self.t_foam + end
        if static:
            lam = level(t)
            f5 = 2.0 * (a5 + lam * da1)
            f6 = 2.0 * (a6 + lam * da2)
        x1, x2, w1, w2, xa, ya, be = self.x
        ts = t
        for _ in range(n):
            # stage 1 at ts
            if not static:
                f5, f6 = forces(ts)
            c = a4x2 * (w2 - w1)
            r1 = u1 - c * w2 - f5 * g(k * w1) - tau1
            r2 = u2 + c * w1 - f6 * g(k * w2) - tau2
            kw1a, kw2a = i11 * r1 + i12 * r2, i12 * r1 + i11 * r2
            v = hr * (w1 + w2)
            kxa, kya, kba = v * cos(be), v * sin(be), hrl * (w1 - w2)
            # stage 2 at ts + dt/2
            if not static:
                f5, f6 = forces(ts + hdt)
            wb1 = w1 + hdt * kw1a
            wb2 = w2 + hdt * kw2a
            bb = be + hdt * kba
            c = a4x2 * (wb2 - wb1)
            r1 = u1 - c * wb2 - f5 * g(k * wb1) - tau1
            r2 = u2 + c * wb1 - f6 * g(k * wb2) - tau2
            kw1b, kw2b = i11 * r1 + i12 * r2, i12 * r1 + i11 * r2
            v = hr * (wb1 + wb2)
            kxb, kyb, kbb = v * cos(bb), v * sin(bb), hrl * (wb1 - wb2)
            # stage 3 at ts + dt/2
            wc1 = w1 + hdt * kw1b
            wc2 = w2 + hdt * kw2b
            bc = be + hdt * kbb
            c = a4x2 * (wc2 - wc1)
            r1 = u1 - c * wc2 - f5 * g(k * wc1) - tau1
            r2 = u2 + c * wc1 - f6 * g(k * wc2) - tau2
            kw1c, kw2c = i11 * r1 + i12 * r2, i12 * r1 + i11 * r2
            v = hr * (wc1 + wc2)
            kxc, kyc, kbc = v * cos(bc), v * sin(bc), hrl * (wc1 - wc2)
            # stage 4 at ts + dt
            if not static:
                f5, f6 = forces(ts + dt)
            wd1 = w1 + dt * kw1c
            wd2 = w2 + dt * kw2c
            bd = be + dt * kbc
            c = a4x2 * (wd2 - wd1)
            r1 = u1 - c * wd2 - f5 * g(k * wd1) - tau1
            r2 = u2 + c * wd1 - f6 * g(k * wd2) - tau2
            kw1d, kw2d = i11 * r1 + i12 * r2, i12 * r1 + i11 * r2
            v = hr * (wd1 + wd2)
            kxd, kyd, kbd = v * cos(bd), v * sin(bd), hrl * (wd1 - wd2)
            s6 = dt / 6.0
            # the angles' derivatives are the speeds at the stages
            x1 += s6 * (w1 + 2.0 * (wb1 + wc1) + wd1)
            x2 += s6 * (w2 + 2.0 * (wb2 + wc2) + wd2)
            w1 += s6 * (kw1a + 2.0 * (kw1b + kw1c) + kw1d)
            w2 += s6 * (kw2a + 2.0 * (kw2b + kw2c) + kw2d)
            xa += s6 * (kxa + 2.0 * (kxb + kxc) + kxd)
            ya += s6 * (kya + 2.0 * (kyb + kyc) + kyd)
            be += s6 * (kba + 2.0 * (kbb + kbc) + kbd)
            ts += dt
        self.x = [x1, x2, w1, w2, xa, ya, be]
        self.t = t + h
        return self.outputs()

    def outputs(self) -> tuple[float, ...]:
        """The outputs at the current time, named by :data:`PLANT_OUTPUTS`."""
        x1, x2, w1, w2, xa, ya, be = self.x
        if self.t < self.t_foam:  # no foam yet: Delta F is the external torque alone
            return (x1, x2, w1, w2, xa, ya, be, self.tau1, self.tau2, 0.0)
        p = self.p
        lam = self.foam_level(self.t)
        k = 0.5 * p.cF
        bump = p.foam_bump if p.foam_bump > 0.0 and self.in_bump(self.t) else 0.0
        df1 = 2.0 * (lam * p.foam_da1 + bump) * self._g(k * w1) + self.tau1
        df2 = 2.0 * (lam * p.foam_da2 + bump) * self._g(k * w2) + self.tau2
        return (x1, x2, w1, w2, xa, ya, be, df1, df2, lam)
