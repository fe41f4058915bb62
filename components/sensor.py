"""The sensor chain of one robot, per wheel: quantised incremental encoder, increment velocity (42),
second-order filter (43), wheel angle.

* Encoder: ``ppr`` pulses per motor revolution behind a ``gear`` reduction, so one count is
  q = 2 pi / (ppr gear) rad of wheel angle.  The count is floor(alpha / q + phase_i); ``phase_i`` (in
  counts) sets where the encoder's edges lie; the default puts wheel 2 half a count out of phase with
  wheel 1 (docs/decisions.md).
* (42): alpha_dot_inc = 2 pi / (ppr gear h) INC, INC the count increment over the last step of h seconds:
  the mean wheel speed over that step.
* (43): printed as 1/(p^2 + 0.03 p + 0.0001), which has DC gain 10^4 and time constants of minutes;
  the default is the normalised form 1/(0.0001 p^2 + 0.03 p + 1) (unit DC gain, poles at -38.2 and
  -261.8 rad/s; decision 10).  The filter is discretised exactly, holding the increment velocity over
  the step it is the mean of (zero-order hold).
* Encoder noise (off by default): with ``noise_std`` > 0 every reading adds a Gaussian jitter of
  ``noise_std`` counts (standard deviation) to the edge position before the floor, drawn from a
  generator seeded with ``noise_seed`` at :meth:`Sensor.reset`, so a run is repeatable.  A jitter
  near an edge flips the count by one, as a noisy encoder does.  With ``noise_std`` = 0 no number is
  drawn and the chain is bit-identical to the noise-free one.
* The wheel angle is the integral of the filtered velocity (default, Fig. 2; integrated exactly with
  the filter) or the count angle (count - count at start) q (decision 11).

The sensor samples its input at the END of each communication step: ``step(h, alpha1, alpha2)`` takes
the wheel angles at t + h and returns the measurements at t + h.
"""
from __future__ import annotations

import math
import random
from dataclasses import asdict, dataclass
from typing import Any

from . import paper
from .linalg import zoh
from .params import choice, half_open, integer, non_negative, param, positive, validate
from .validation import step as check_step

_ENC = paper.results()["encoder"]

FILTER_FORMS = ("normalised", "printed")
ANGLE_SOURCES = ("filtered", "counts")
#: The printed coefficients of (43): p^2 + F_C1 p + F_C0.
F_C1 = 0.03
F_C0 = 0.0001

#: Names of the values returned by :meth:`Sensor.step` / :meth:`Sensor.outputs`, in order.
SENSOR_OUTPUTS = (
    "alpha_m1", "alpha_m2",            # measured wheel angles [rad]
    "alpha_dot_m1", "alpha_dot_m2",    # filtered wheel speeds [rad/s]
    "alpha_dot_inc1", "alpha_dot_inc2",  # raw increment velocity (42) [rad/s]
    "count1", "count2",                # encoder counts (integers)
)


@dataclass
class SensorParams:
    """Parameters of the sensor chain: each field's unit, accepted values and meaning are in its declaration."""

    ppr: float = param(float(_ENC["ppr"]), unit="1", check=positive, doc="encoder pulses per motor revolution")
    gear: float = param(float(_ENC["gear"]), unit="1", check=positive, doc="gear reduction motor : wheel")
    phase1: float = param(0.0, unit="1", check=half_open(0.0, 1.0, "counts"),
                          doc="encoder 1 edge phase in counts, 0 <= phase1 < 1")
    phase2: float = param(0.5, unit="1", check=half_open(0.0, 1.0, "counts"),
                          doc="encoder 2 edge phase in counts, 0 <= phase2 < 1")
    filter_form: str = param("normalised", check=choice(*FILTER_FORMS),
                             doc="filter (43): normalised (default, 1/(0.0001 p^2 + 0.03 p + 1)) or printed")
    angle_source: str = param("filtered", check=choice(*ANGLE_SOURCES),
                              doc="measured angle: filtered (default, integral of the filtered speed) or counts")
    noise_std: float = param(0.0, unit="1", check=non_negative,
                             doc="encoder noise: standard deviation of a Gaussian jitter of the edge position "
                                 "in counts (0 = off, the default)")
    noise_seed: int = param(0, check=integer(0, 2**31 - 1, "an integer in [0, 2^31)"),
                            doc="encoder noise: seed of the jitter's generator (repeatable runs)")

    def __post_init__(self) -> None:
        validate(self, "sensor")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def count_angle(self) -> float:
        """q: the wheel angle of one encoder count [rad]."""
        return 2.0 * math.pi / (self.ppr * self.gear)


def filter_coefficients(form: str) -> tuple[float, float, float]:
    """(c2, c1, c0) of the filter (43) 1 / (c2 p^2 + c1 p + c0) for the printed or normalised form."""
    if form == "printed":
        return 1.0, F_C1, F_C0
    return F_C0, F_C1, 1.0


def filter_matrices(form: str, h: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Exact ZOH discretisation over h [s] of the filter (43) with its output integrated.

    State z = [theta, y, y_dot] (theta = integral of the filtered velocity y), input the increment
    velocity v: theta' = y, c2 y'' + c1 y' + c0 y = v.  Returns Ad (9 floats, row-major) and Bd (3 floats).
    """
    c2, c1, c0 = filter_coefficients(form)
    a = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -c0 / c2, -c1 / c2]]
    b = [[0.0], [0.0], [1.0 / c2]]
    ad, bd = zoh(a, b, h)
    return tuple(v for row in ad for v in row), tuple(row[0] for row in bd)


class Sensor:
    """Encoders + (42) + (43) + angle, for both wheels.  Call :meth:`reset` with the initial angles."""

    def __init__(self, params: SensorParams | None = None, **overrides: Any) -> None:
        if params is None:
            params = SensorParams(**overrides)
        elif overrides:
            params = SensorParams(**{**params.as_dict(), **overrides})
        self.p = params
        self.q = params.count_angle
        self._inv_q = 1.0 / self.q
        self._h = math.nan
        self._ad: tuple[float, ...] = ()
        self._bd: tuple[float, ...] = ()
        self.reset(0.0, 0.0)

    def reset(self, alpha1: float, alpha2: float) -> None:
        """Initial state: counts from the initial wheel angles [rad], filter at rest, measured angles 0."""
        p = self.p
        self.c1 = math.floor(alpha1 * self._inv_q + p.phase1)
        self.c2 = math.floor(alpha2 * self._inv_q + p.phase2)
        self.c1_0, self.c2_0 = self.c1, self.c2
        self.z1 = [0.0, 0.0, 0.0]
        self.z2 = [0.0, 0.0, 0.0]
        self.v1 = self.v2 = 0.0
        self._rng = random.Random(p.noise_seed) if p.noise_std > 0.0 else None

    def get_state(self) -> dict[str, Any]:
        """All internal state as JSON-serialisable plain values."""
        return {"c": [self.c1, self.c2], "c0": [self.c1_0, self.c2_0], "z1": list(self.z1),
                "z2": list(self.z2), "v": [self.v1, self.v2],
                "rng": _rng_state(self._rng)}

    def set_state(self, s: dict[str, Any]) -> None:
        """Restore a state returned by :meth:`get_state`."""
        self.c1, self.c2 = (int(v) for v in s["c"])
        self.c1_0, self.c2_0 = (int(v) for v in s["c0"])
        self.z1 = [float(v) for v in s["z1"]]
        self.z2 = [float(v) for v in s["z2"]]
        self.v1, self.v2 = (float(v) for v in s["v"])
        if self._rng is not None and s.get("rng") is not None:
            st = s["rng"]
            self._rng.setstate((int(st[0]), tuple(int(v) for v in st[1]), None if st[2] is None else float(st[2])))

    def _discretise(self, h: float) -> None:
        check_step("sensor", h)
        self._ad, self._bd = filter_matrices(self.p.filter_form, h)
        self._h = h
        self._vq = self.q / h

    def step(self, h: float, alpha1: float, alpha2: float) -> tuple[float, ...]:
        """Sample the wheel angles alpha_i [rad] at the end of a step of h [s]; return the measurements.

        The returned tuple is named by :data:`SENSOR_OUTPUTS`.
        """
        if h != self._h:
            self._discretise(h)
        p = self.p
        floor = math.floor
        iq = self._inv_q
        vq = self._vq
        a00, a01, a02, a10, a11, a12, a20, a21, a22 = self._ad
        b0, b1, b2 = self._bd
        # encoder counts and the increment velocity (42)
        if self._rng is None:
            c1 = floor(alpha1 * iq + p.phase1)
            c2 = floor(alpha2 * iq + p.phase2)
        else:  # encoder noise: a Gaussian jitter of the edge position [counts]
            g, sd = self._rng.gauss, p.noise_std
            c1 = floor(alpha1 * iq + p.phase1 + g(0.0, sd))
            c2 = floor(alpha2 * iq + p.phase2 + g(0.0, sd))
        v1 = (c1 - self.c1) * vq
        v2 = (c2 - self.c2) * vq
        self.c1, self.c2, self.v1, self.v2 = c1, c2, v1, v2
        # filter (43), exact ZOH, with the integral of its output
        t, y, yd = self.z1
        self.z1 = [a00 * t + a01 * y + a02 * yd + b0 * v1,
                   a10 * t + a11 * y + a12 * yd + b1 * v1,
                   a20 * t + a21 * y + a22 * yd + b2 * v1]
        t, y, yd = self.z2
        self.z2 = [a00 * t + a01 * y + a02 * yd + b0 * v2,
                   a10 * t + a11 * y + a12 * yd + b1 * v2,
                   a20 * t + a21 * y + a22 * yd + b2 * v2]
        return self.outputs()

    def outputs(self) -> tuple[float, ...]:
        """The measurements at the current time, named by :data:`SENSOR_OUTPUTS`."""
        if self.p.angle_source == "filtered":
            am1, am2 = self.z1[0], self.z2[0]
        else:
            am1, am2 = (self.c1 - self.c1_0) * self.q, (self.c2 - self.c2_0) * self.q
        return (am1, am2, self.z1[1], self.z2[1], self.v1, self.v2, self.c1, self.c2)


def _rng_state(rng: random.Random | None) -> list[Any] | None:
    """The generator's state as JSON values (None without noise)."""
    if rng is None:
        return None
    version, internal, gauss_next = rng.getstate()
    return [version, list(internal), gauss_next]
