"""A linear model as the linearisation gives it: the matrices of

    continuous time (``dt == 0``):   x' = A x + B u,          y = C x + D u
    discrete time (``dt > 0``):      x[k+1] = A x[k] + B u[k], y[k] = C x[k] + D u[k]

with every state, input and output named and given its unit (the FMU's declared unit: the matrices are in
those units), how it was obtained, and where: the time of the operating point and its values x, u, y (the
model is that of the deviations from them).  It converts to a python-control ``StateSpace`` and saves to
``linear.npz`` and ``linear.mat``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: The file names in the output folder (``wmr-cosim linearize --out``).
NPZ_FILE, MAT_FILE = "linear.npz", "linear.mat"


def control_name(name: str) -> str:
    """A signal's name as python-control takes it: ``plant.torque_right`` -> ``plant:torque_right``."""
    return name.replace(".", ":")


@dataclass
class LinearModel:
    """(A, B, C, D) with named signals; ``dt`` 0 for continuous time, else the sampling time [s]."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: list[str]
    inputs: list[str]
    outputs: list[str]
    state_units: list[str] = field(default_factory=list)
    input_units: list[str] = field(default_factory=list)
    output_units: list[str] = field(default_factory=list)
    dt: float = 0.0                  # [s]; 0: continuous time
    t: float = 0.0                   # the operating point's time [s]
    method: str = ""                 # how the matrices were obtained, in words
    singular_values: np.ndarray | None = None   # of the Hankel matrix (a realisation from responses)
    #: The operating point: the states', inputs' and outputs' values at ``t`` (in their units); nan where a
    #: value is not defined (a realisation's states are coordinates of the deviations, 0 at the point by
    #: construction, not values of the FMUs' states); None: not recorded (all nan).
    x: np.ndarray | None = None
    u: np.ndarray | None = None
    y: np.ndarray | None = None

    def __post_init__(self) -> None:
        n, m, p = len(self.states), len(self.inputs), len(self.outputs)
        self.A = np.asarray(self.A, dtype=float).reshape(n, n)
        self.B = np.asarray(self.B, dtype=float).reshape(n, m)
        self.C = np.asarray(self.C, dtype=float).reshape(p, n)
        self.D = np.asarray(self.D, dtype=float).reshape(p, m)
        for name, count in (("x", n), ("u", m), ("y", p)):
            value = getattr(self, name)
            setattr(self, name, np.full(count, np.nan) if value is None
                    else np.asarray(value, dtype=float).reshape(count))
        for name, units, count in (("state_units", self.state_units, n), ("input_units", self.input_units, m),
                                   ("output_units", self.output_units, p)):
            if not units:
                setattr(self, name, [""] * count)
            elif len(units) != count:
                raise ValueError(f"{name}: {len(units)} units for {count} signals")

    @property
    def continuous(self) -> bool:
        return self.dt == 0.0

    def eigenvalues(self) -> np.ndarray:
        """The eigenvalues of A (the poles: [1/s] in continuous time; in the z-plane in discrete time)."""
        return np.linalg.eigvals(self.A) if self.A.size else np.zeros(0, dtype=complex)

    def statespace(self) -> Any:
        """The model as a python-control ``StateSpace``, its signals named as here with every "." written
        ":" (python-control reserves the dot for its own subsystem names): ``plant:torque_right``."""
        import control

        def labels(names: list[str]) -> list[str] | None:
            return [control_name(n) for n in names] or None
        return control.ss(self.A, self.B, self.C, self.D, self.dt, states=labels(self.states),
                          inputs=labels(self.inputs), outputs=labels(self.outputs))

    def arrays(self) -> dict[str, Any]:
        """What linear.npz and linear.mat hold: A, B, C, D, dt [s], t [s], the names and units of the
        states, inputs and outputs, the method, the singular values (empty where there are none), the
        operating point ``x``, ``u``, ``y`` (nan where not defined)."""
        text = {"states": self.states, "inputs": self.inputs, "outputs": self.outputs,
                "state_units": self.state_units, "input_units": self.input_units, "output_units": self.output_units}
        out: dict[str, Any] = {"A": self.A, "B": self.B, "C": self.C, "D": self.D, "dt": np.float64(self.dt),
                               "t": np.float64(self.t), "method": np.str_(self.method),
                               "singular_values": np.zeros(0) if self.singular_values is None
                               else np.asarray(self.singular_values, dtype=float),
                               "x": np.asarray(self.x, dtype=float), "u": np.asarray(self.u, dtype=float),
                               "y": np.asarray(self.y, dtype=float)}
        out.update({k: np.array(v, dtype=str) if v else np.zeros(0, dtype="<U1") for k, v in text.items()})
        return out

    def save(self, folder: str | Path) -> tuple[Path, Path]:
        """``folder/linear.npz`` (numpy) and ``folder/linear.mat`` (MATLAB 5, scipy.io) with :meth:`arrays`."""
        from scipy.io import savemat

        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        arrays = self.arrays()
        npz, mat = folder / NPZ_FILE, folder / MAT_FILE
        np.savez(npz, **arrays)
        savemat(mat, {k: (np.array(list(v), dtype=object) if v.dtype.kind == "U" and v.ndim else v)
                      for k, v in arrays.items()}, oned_as="column")
        return npz, mat

    @classmethod
    def load(cls, path: str | Path) -> "LinearModel":
        """A model saved by :meth:`save` (linear.npz; one saved before the operating point was: its x, u, y
        nan)."""
        with np.load(path) as z:
            sv = z["singular_values"]
            point = {k: z[k] for k in ("x", "u", "y") if k in z.files}
            return cls(z["A"], z["B"], z["C"], z["D"], list(map(str, z["states"])), list(map(str, z["inputs"])),
                       list(map(str, z["outputs"])), list(map(str, z["state_units"])),
                       list(map(str, z["input_units"])), list(map(str, z["output_units"])), float(z["dt"]),
                       float(z["t"]), str(z["method"]), sv if sv.size else None, **point)

    def operating_point(self) -> dict[str, Any]:
        """The point as linear.json gives it: ``time`` [s] and, for the states, inputs and outputs, each one's
        name, unit and value (None where not defined)."""
        def rows(names: list[str], units: list[str], values: np.ndarray | None) -> list[dict[str, Any]]:
            known = np.full(len(names), np.nan) if values is None else values
            return [{"name": n, "unit": u, "value": float(v) if np.isfinite(v) else None}
                    for n, u, v in zip(names, units, known)]
        return {"time": self.t, "states": rows(self.states, self.state_units, self.x),
                "inputs": rows(self.inputs, self.input_units, self.u),
                "outputs": rows(self.outputs, self.output_units, self.y)}
