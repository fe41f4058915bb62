"""The recording as a result file in Dymola's layout (MAT v4, "binTrans", the one DyMat, OMEdit and
FMPy read), written with numpy alone.

The file holds six matrices:

- ``Aclass``: the text ``Atrajectory`` / ``1.1`` / (empty) / ``binTrans`` (a 4-row char matrix);
- ``name`` and ``description``: one column per variable (char matrices, transposed as Dymola writes
  them: a reader takes column j as the j-th name), padded with spaces; the description carries the unit
  as Dymola writes it, ``text [unit]`` (``[unit]`` alone where the FMU gives no text);
- ``dataInfo``: one column per variable (int32): the data block (0 for time, the abscissa of both
  blocks; 1 for a constant; 2 for a signal), the 1-based row in that block, 0 (linear interpolation),
  -1 (undefined outside the time range; 0 for a constant);
- ``data_1``: the constants: row 0 the first and last recorded time [s], then one row per parameter
  the scenario sets (its value twice; see :func:`constants`);
- ``data_2``: row 0 the recorded time [s], then one row per recorded column, one column per recorded
  point: every value as float64 (Float32 exactly, integers exactly up to 2**53, booleans 0/1).

Names and descriptions are written in UTF-8 (ASCII as it is; a reader that decodes bytes as Latin-1, as
``scipy.io.loadmat`` does, shows other letters as their UTF-8 bytes).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from ..plan.records import Plan, unit_of

#: Rows of the recording converted at a time (bounds the memory the writer needs).
MAT_CHUNK = 20000
#: The description of the time column, as Dymola writes it.
TIME_DESCRIPTION = "Simulation time"
#: MAT v4 type codes (MOPT: little-endian IEEE, full matrix): float64, int32, text in uint8.
_DOUBLE, _INT32, _TEXT = 0, 20, 51
#: The largest dimension a MAT v4 header holds (a signed 32-bit integer).
_MAX_DIM = 2 ** 31 - 1


@dataclass(frozen=True)
class MatVariable:
    """One variable of the file: its name (as in signals.npy), its description (the FMU's text) and its
    unit (None where none is known); ``value`` for a constant (data_1)."""

    name: str
    description: str = ""
    unit: str | None = None
    value: float | None = None

    def described(self) -> str:
        """The description as Dymola writes it: ``text [unit]``, ``[unit]`` or ``text``."""
        unit = f"[{self.unit}]" if self.unit else ""
        return " ".join(part for part in (self.description, unit) if part)


@dataclass
class MatLayout:
    """What the file says of each column of the recording (``signals``, by name, time included) and the
    constants written beside them (``constants``)."""

    signals: dict[str, MatVariable] = field(default_factory=dict)
    constants: list[MatVariable] = field(default_factory=list)

    @classmethod
    def from_columns(cls, columns: dict[str, dict[str, Any]]) -> "MatLayout":
        """A layout from what summary.json's ``columns`` says (units, no descriptions, no constants)."""
        return cls({n: MatVariable(n, TIME_DESCRIPTION if n == "time" else "", (c or {}).get("unit"))
                    for n, c in columns.items()})


def layout(plan: Plan) -> MatLayout:
    """The layout of a plan's recording: each column's description (the model description's text) and
    unit (the scenario's ``units``, else the model description's), and the constants (:func:`constants`)."""
    signals = {"time": MatVariable("time", TIME_DESCRIPTION, "s")}
    for r in plan.record:
        ip = plan.instances[r.instance]
        unit = unit_of(ip, r.var) if r.var.type == "Real" else None
        signals[r.column] = MatVariable(r.column, r.var.description, unit.name if unit is not None else None)
    return MatLayout(signals, constants(plan))


def constants(plan: Plan) -> list[MatVariable]:
    """The scalar numeric parameters the scenario sets, at the values it sets them to (their values at the
    start), unless a ``set`` event of the scenario changes them (a value a script sets during the run is
    not known here); :func:`write_mat` leaves out those also recorded as signals."""
    changed = {(e.instance, e.var.name) for e in plan.events + plan.conditions
               if e.action == "set" and e.var is not None}
    out: list[MatVariable] = []
    for name, ip in plan.instances.items():
        for var, value in ip.parameters:
            ref = f"{name}.{ip.our_name(var)}"
            if (var.causality != "parameter" or var.shape or (name, var.name) in changed
                    or not isinstance(value, (int, float))):
                continue
            unit = unit_of(ip, var) if var.type == "Real" else None
            out.append(MatVariable(ref, var.description, unit.name if unit is not None else None, float(value)))
    return out


def write_mat(path: str | os.PathLike, signals: np.ndarray, spec: MatLayout | None = None,
              chunk: int = MAT_CHUNK) -> Path:
    """Write ``signals`` (a structured array with a ``time`` field [s], e.g. ``numpy.load('signals.npy',
    mmap_mode='r')``) to ``path`` in Dymola's layout, converted ``chunk`` rows at a time, through a
    temporary name renamed when whole.  ``spec``: descriptions, units and constants (None: names only,
    time in s).  ValueError for a recording without a time field or without rows."""
    names = list(signals.dtype.names or ())
    if "time" not in names:
        raise ValueError("the recording has no 'time' column")
    if not len(signals):
        raise ValueError("the recording has no rows: nothing to write")
    if len(signals) > _MAX_DIM:
        raise ValueError(f"{len(signals)} rows: a MAT v4 file holds at most {_MAX_DIM}")
    names.remove("time")
    spec = spec or MatLayout({"time": MatVariable("time", TIME_DESCRIPTION, "s")})
    variables = [spec.signals.get(n) or MatVariable(n) for n in ["time", *names]]
    constants = [c for c in spec.constants if c.name not in names and c.name != "time"]
    path = Path(path)
    tmp = path.with_name(path.name + ".part")
    try:
        with open(tmp, "wb") as fh:
            _write_header_matrices(fh, variables, constants, len(names))
            t = np.asarray(signals["time"], dtype="<f8")
            _data_1(fh, np.array([[t[0], t[-1]]] + [[c.value, c.value] for c in constants], "<f8"))
            _write_signals(fh, signals, ["time", *names], chunk)
        os.replace(tmp, path)
    except BaseException:   # interrupted or failed: no partial file left behind
        tmp.unlink(missing_ok=True)
        raise
    return path


def _write_header_matrices(fh: IO[bytes], variables: list[MatVariable], constants: list[MatVariable],
                           n_signals: int) -> None:
    """Aclass, name, description and dataInfo (time, the constants, then the signals)."""
    _text(fh, "Aclass", ["Atrajectory", "1.1", "", "binTrans"], transposed=False)
    every = [variables[0], *constants, *variables[1:]]
    _text(fh, "name", [v.name for v in every])
    _text(fh, "description", [v.described() for v in every])
    info = [[0, 1, 0, -1]] + [[1, 2 + i, 0, 0] for i in range(len(constants))] + \
        [[2, 2 + j, 0, -1] for j in range(n_signals)]
    _per_column(fh, "dataInfo", np.array(info, "<i4"), _INT32)


def _write_signals(fh: IO[bytes], signals: np.ndarray, names: list[str], chunk: int) -> None:
    """data_2: one row per variable, one column per recorded point.  MAT v4 stores a matrix column by
    column, so each recorded point's values are contiguous: the rows are written as they come."""
    _header(fh, "data_2", _DOUBLE, len(names), len(signals))
    for i in range(0, len(signals), chunk):
        part = signals[i:i + chunk]
        block = np.empty((len(part), len(names)), "<f8")
        for j, n in enumerate(names):
            block[:, j] = part[n]
        fh.write(block.tobytes())


def _header(fh: IO[bytes], name: str, mopt: int, rows: int, cols: int) -> None:
    """A MAT v4 matrix header: type, rows, columns, no imaginary part, the name with its NUL."""
    raw = name.encode("ascii") + b"\0"
    fh.write(np.array([mopt, rows, cols, 0, len(raw)], "<i4").tobytes() + raw)


def _per_column(fh: IO[bytes], name: str, per_var: np.ndarray, mopt: int) -> None:
    """A matrix with one column per variable (``per_var[v]`` its entries), as Dymola writes dataInfo."""
    n_var, n_entry = per_var.shape
    _header(fh, name, mopt, n_entry, n_var)
    fh.write(np.ascontiguousarray(per_var).tobytes())   # row-major here = column-major there


def _data_1(fh: IO[bytes], per_var: np.ndarray) -> None:
    """data_1: one row per variable (``per_var[v]``: its values at the first and last time), as data_2."""
    n_var, n_entry = per_var.shape
    _header(fh, "data_1", _DOUBLE, n_var, n_entry)
    fh.write(np.ascontiguousarray(per_var.T).tobytes())   # column-major: every variable's first value, then


def _text(fh: IO[bytes], name: str, lines: list[str], transposed: bool = True) -> None:
    """A char matrix of ``lines`` padded with spaces: one column per line (transposed, as Dymola writes
    names and descriptions), or one row per line (``Aclass``)."""
    raw = [s.encode("utf-8") for s in lines]
    width = max([1, *(len(b) for b in raw)])
    grid = np.frombuffer(b"".join(b.ljust(width) for b in raw), np.uint8).reshape(len(raw), width)
    if transposed:
        _header(fh, name, _TEXT, width, len(raw))
        fh.write(grid.tobytes())          # each line contiguous = one column of the stored matrix
    else:
        _header(fh, name, _TEXT, len(raw), width)
        fh.write(grid.T.tobytes())        # column-major: the first character of every line, then the second
