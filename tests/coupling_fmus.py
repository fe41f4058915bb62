"""The C test FMUs of coupling algorithms (tests/c_fmus/mass.c, tests/c_fmus/affine.c), their closed-form
solutions and the systems they make (not a test module; the adaptive benchmark uses it too).

* A two-mass oscillator split across two FMUs: ``body`` (MassForce: body 1, force in, position and velocity
  out) and ``coupler`` (MassCoupler: body 2 and the coupling spring-damper, body 1's position and velocity
  in, the force on body 1 out with direct feedthrough), optionally with a stiff one-sided contact.
* An affine map with direct feedthrough, y = a u + b0 + b1 t + bw sin(w t): two of them in a ring are a pure
  algebraic loop.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from c_fmu_support import build_c_fmu

C_FMUS = Path(__file__).resolve().parent / "c_fmus"

_HEAD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{{coupling-{name}}}" generationTool="wmr-cosim tests"
  variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true" canGetAndSetFMUstate="true"
    canInterpolateInputs="true" maxOutputDerivativeOrder="0"{extra}/>
  <LogCategories><Category name="logStatusError"/></LogCategories>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.001"/>
  <ModelVariables>
"""


def _var(name: str, vr: int, causality: str, unit: str = "", start: float | None = None) -> str:
    attrs = (f' unit="{unit}"' if unit else "") + ("" if start is None else f' start="{start!r}"')
    extra = ' variability="fixed" initial="exact"' if causality == "parameter" else ""
    return (f'    <ScalarVariable name="{name}" valueReference="{vr}" causality="{causality}"{extra}>'
            f"<Real{attrs}/></ScalarVariable>\n")


def _description(name: str, variables: list[tuple[Any, ...]], outputs: dict[str, list[str] | None],
                 extra: str = "") -> str:
    """The model description: ``variables`` (name, vr, causality, unit, start) in index order, ``outputs``
    the inputs each output depends on directly (None: no ``dependencies`` attribute, which says that the
    output depends on every input); ``extra``: more attributes of the CoSimulation element."""
    index = {v[0]: i + 1 for i, v in enumerate(variables)}
    body = "".join(_var(*v) for v in variables)
    deps = "".join(f'<Unknown index="{index[o]}"/>' if d is None else
                   f'<Unknown index="{index[o]}" dependencies="{" ".join(str(index[i]) for i in d)}"/>'
                   for o, d in outputs.items())
    return (_HEAD.format(name=name, extra=extra) + body + "  </ModelVariables>\n  <ModelStructure>\n"
            f"    <Outputs>{deps}</Outputs>\n    <InitialUnknowns>{deps}</InitialUnknowns>\n"
            "  </ModelStructure>\n</fmiModelDescription>\n")


@dataclass(frozen=True)
class TwoMass:
    """The two-mass system's parameters (SI units): masses [kg], wall springs [N/m] and dampers [N.s/m],
    the coupling spring kc [N/m] and damper dc [N.s/m], the contact stiffness kk [N/m] (0: none) acting when
    x1 - x2 exceeds gap [m], the initial state, the FMUs' internal RK4 step h_int [s]."""

    m1: float = 1.0
    k1: float = 10.0
    d1: float = 0.1
    m2: float = 1.0
    k2: float = 10.0
    d2: float = 0.1
    kc: float = 100.0
    dc: float = 0.5
    kk: float = 0.0
    gap: float = 0.1
    x1: float = 1.0
    v1: float = 0.0
    x2: float = 0.0
    v2: float = 0.0
    h_int: float = 1e-5

    def body_parameters(self) -> dict[str, float]:
        return {"m1": self.m1, "k1": self.k1, "d1": self.d1, "x0": self.x1, "v0": self.v1, "h_int": self.h_int}

    def coupler_parameters(self) -> dict[str, float]:
        return {"m2": self.m2, "k2": self.k2, "d2": self.d2, "x0": self.x2, "v0": self.v2, "h_int": self.h_int,
                "kc": self.kc, "dc": self.dc, "kk": self.kk, "gap": self.gap}

    def matrix(self) -> np.ndarray:
        """A of z' = A z, z = (x1, v1, x2, v2), without the contact."""
        s = self
        return np.array([[0.0, 1.0, 0.0, 0.0],
                         [-(s.k1 + s.kc) / s.m1, -(s.d1 + s.dc) / s.m1, s.kc / s.m1, s.dc / s.m1],
                         [0.0, 0.0, 0.0, 1.0],
                         [s.kc / s.m2, s.dc / s.m2, -(s.k2 + s.kc) / s.m2, -(s.d2 + s.dc) / s.m2]])

    def closed_form(self, times: np.ndarray) -> np.ndarray:
        """z(t) = expm(A t) z0 at each time [s], rows (x1, v1, x2, v2); only without the contact."""
        from scipy.linalg import expm

        if self.kk:
            raise ValueError("the contact has no closed form")
        z0 = np.array([self.x1, self.v1, self.x2, self.v2])
        a = self.matrix()
        return np.array([expm(a * t) @ z0 for t in times])

    def rhs(self, t: float, z: np.ndarray) -> np.ndarray:
        """z' with the contact (for a fine reference by an ODE solver)."""
        s = self
        x1, v1, x2, v2 = z
        f = s.kc * (x2 - x1) + s.dc * (v2 - v1)
        if s.kk and x1 - x2 > s.gap:
            f -= s.kk * (x1 - x2 - s.gap)
        return np.array([v1, (-s.k1 * x1 - s.d1 * v1 + f) / s.m1, v2, (-s.k2 * x2 - s.d2 * v2 - f) / s.m2])


MASS_VARIABLES = [("x", 0, "output", "m"), ("v", 1, "output", "m/s"), ("F", 2, "input", "N", 0.0),
                  ("m1", 10, "parameter", "kg", 1.0), ("k1", 11, "parameter", "N/m", 10.0),
                  ("d1", 12, "parameter", "N.s/m", 0.1), ("x0", 13, "parameter", "m", 1.0),
                  ("v0", 14, "parameter", "m/s", 0.0), ("h_int", 15, "parameter", "s", 1e-5)]
COUPLER_VARIABLES = [("x", 0, "output", "m"), ("v", 1, "output", "m/s"), ("x_in", 2, "input", "m", 0.0),
                     ("v_in", 3, "input", "m/s", 0.0), ("F", 4, "output", "N"),
                     ("m2", 10, "parameter", "kg", 1.0), ("k2", 11, "parameter", "N/m", 10.0),
                     ("d2", 12, "parameter", "N.s/m", 0.1), ("x0", 13, "parameter", "m", 0.0),
                     ("v0", 14, "parameter", "m/s", 0.0), ("h_int", 15, "parameter", "s", 1e-5),
                     ("kc", 16, "parameter", "N/m", 100.0), ("dc", 17, "parameter", "N.s/m", 0.5),
                     ("kk", 18, "parameter", "N/m", 0.0), ("gap", 19, "parameter", "m", 0.1)]
AFFINE_VARIABLES = [("u", 0, "input", "", 0.0), ("y", 1, "output", ""), ("a", 10, "parameter", "", 1.0),
                    ("b0", 11, "parameter", "", 0.0), ("b1", 12, "parameter", "1/s", 0.0),
                    ("bw", 13, "parameter", "", 0.0), ("w", 14, "parameter", "rad/s", 1.0)]


def build_mass(out: Path) -> tuple[Path, Path]:
    """``out/MassForce.fmu`` and ``out/MassCoupler.fmu``."""
    body = build_c_fmu(C_FMUS / "mass.c", _description("MassForce", MASS_VARIABLES, {"x": [], "v": []}),
                       out, "MassForce")
    coupler = build_c_fmu(C_FMUS / "mass.c",
                          _description("MassCoupler", COUPLER_VARIABLES,
                                       {"x": [], "v": [], "F": ["x_in", "v_in"]}),
                          out, "MassCoupler", COUPLER=True)
    return body, coupler


def build_affine(out: Path, name: str = "Affine", dependencies: tuple[str, ...] | None = ("u",),
                 directional: bool = True) -> Path:
    """``out/<name>.fmu``, its output declared to depend directly on ``dependencies`` (None: the attribute
    left out), declaring providesDirectionalDerivative if ``directional`` (the binary gives them always)."""
    md = _description(name, AFFINE_VARIABLES, {"y": None if dependencies is None else list(dependencies)},
                      ' providesDirectionalDerivative="true"' if directional else "")
    return build_c_fmu(C_FMUS / "affine.c", md, out, name)


def two_mass_document(fmus: tuple[Path, Path], system: TwoMass, *, stop: float, step: float) -> dict[str, Any]:
    """The scenario document of the two-mass system: ``body`` then ``coupler``, recording both positions,
    both velocities and the coupling force."""
    return {"experiment": {"start": 0.0, "stop": stop, "step": step},
            "instances": {"body": {"fmu": str(fmus[0]), "parameters": system.body_parameters()},
                          "coupler": {"fmu": str(fmus[1]), "parameters": system.coupler_parameters()}},
            "connections": [{"from": "body.x", "to": "coupler.x_in"}, {"from": "body.v", "to": "coupler.v_in"},
                            {"from": "coupler.F", "to": "body.F"}],
            "record": {"variables": ["body.x", "body.v", "coupler.x", "coupler.v", "coupler.F"]}}


@dataclass(frozen=True)
class AffineLoop:
    """y1 = a1 u1 + b1(t), u2 = y1, y2 = a2 u2 + b2(t), u1 = y2, with b(t) = b0 + bt t + bw sin(w t)."""

    a1: float
    a2: float
    b1: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 1.0)   # (b0, bt, bw, w)
    b2: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)

    @staticmethod
    def _b(b: tuple[float, float, float, float], t: np.ndarray) -> np.ndarray:
        return b[0] + b[1] * t + b[2] * np.sin(b[3] * t)

    def solution(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(y1, y2) at each time: y1 = a1 (a2 y1 + b2) + b1."""
        b1, b2 = self._b(self.b1, times), self._b(self.b2, times)
        y1 = (self.a1 * b2 + b1) / (1.0 - self.a1 * self.a2)
        return y1, self.a2 * y1 + b2

    def document(self, fmu: Path, *, stop: float, step: float) -> dict[str, Any]:
        def params(a: float, b: tuple[float, float, float, float]) -> dict[str, float]:
            return {"a": a, "b0": b[0], "b1": b[1], "bw": b[2], "w": b[3]}

        return {"experiment": {"start": 0.0, "stop": stop, "step": step},
                "instances": {"one": {"fmu": str(fmu), "parameters": params(self.a1, self.b1)},
                              "two": {"fmu": str(fmu), "parameters": params(self.a2, self.b2)}},
                "connections": [{"from": "one.y", "to": "two.u"}, {"from": "two.y", "to": "one.u"}],
                "record": {"variables": ["one.y", "two.y"]}}
