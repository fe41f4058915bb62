"""The result formats: the one table of what a results folder can hold of the recording, a row per
format (its file, the scenario's ``[record]`` flag that asks for it, what it is, its writer).  The results
folder (:mod:`.folder`: the stale files removed, the files written at the end) and ``run --format`` read
it; the flags themselves are the scenario's fields (``Scenario.csv``, ``Scenario.mat``, their defaults
with them), below this layer.

The module imports nothing heavy: the writers import their own on first use, so that the command line
reads the table without loading the results' writers."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from ..plan.records import Plan

#: A writer: (signals.npy, the file to write, the plan of the run) -> None.
Writer = Callable[[Path, Path, "Plan"], None]


def _write_csv(npy: Path, out: Path, plan: Plan) -> None:
    """signals.csv: the recording as CSV, its times on the scenario's grid (start [s], step [s])."""
    from .recording import write_csv

    write_csv(npy, out, start=plan.scenario.start or 0.0, step=plan.scenario.step)


def _write_mat(npy: Path, out: Path, plan: Plan) -> None:
    """signals.mat: the recording in Dymola's result layout, with the plan's descriptions and units."""
    import numpy as np

    from .matfile import layout, write_mat

    write_mat(out, np.load(npy, mmap_mode="r"), layout(plan))


@dataclass(frozen=True)
class ResultFormat:
    """One format of the results folder."""

    file: str                 # its file in the results folder
    flag: str | None          # the scenario's [record] flag (a bool field of Scenario) asking for it; None: always
    description: str          # what the file is (after its name in the help of run --format)
    writer: Writer | None     # writes it at the end of a run; None: written as the run goes (the recording)


#: The result formats by name, in the order ``run --format`` names them.
RESULT_FORMATS: dict[str, ResultFormat] = {
    "csv": ResultFormat("signals.csv", "csv", "", _write_csv),
    "npy": ResultFormat("signals.npy", None, "", None),
    "mat": ResultFormat("signals.mat", "mat", "Dymola's result layout, MAT v4", _write_mat),
}

#: The recording's own format: always written, as the run goes.
RECORDING = next(name for name, f in RESULT_FORMATS.items() if f.flag is None)


def format_flags(chosen: list[str]) -> dict[str, bool]:
    """The ``[record]`` fields (``record.csv``, ...) that make the results folder hold exactly the formats
    ``chosen`` (names of :data:`RESULT_FORMATS`; the recording is always written)."""
    return {f"record.{f.flag}": name in chosen for name, f in RESULT_FORMATS.items() if f.flag is not None}


def format_help() -> str:
    """The formats as the help of ``run --format`` names them: each asked-for one with its file, then the
    recording alone (nothing more)."""
    asked = [f"{name} ({f.file}{', ' + f.description if f.description else ''})"
             for name, f in RESULT_FORMATS.items() if f.flag is not None]
    return f"{', '.join(asked)} or {RECORDING} (nothing more)"
