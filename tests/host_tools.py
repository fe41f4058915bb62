"""The FMI hosts the tests run our FMUs in besides this project's Python: the plain C host's spec and output
(tests/c_host/fmi_host.c, built by the tests for Linux and, with MinGW-w64, for Windows), and the prebuilt
third-party hosts the tests compare against (fmusim, OMSimulator): C/C++ programs that
no package index provides.  They are looked for in the folder ``WMR_HOST_TOOLS`` names, else in the
folder ``tools`` of a folder ``shared`` beside the checkout (fmusim in ``fmusim/fmusim``, OMSimulator in
``omsimulator/bin/OMSimulator``); a test that needs one skips, saying why, where it is absent or cannot
start (fmusim needs Debian's libxml2, libminizip1 and libsundials-cvode6; OMSimulator libcurl4 and
libicu72)."""
from __future__ import annotations

import os
import subprocess
from functools import lru_cache
from pathlib import Path
from typing import Any

import pytest
from fmpy import read_model_description

TOOLS = Path(os.environ.get("WMR_HOST_TOOLS") or Path(__file__).resolve().parents[2] / "shared" / "tools")
FMUSIM = "fmusim/fmusim"
OMSIMULATOR = "omsimulator/bin/OMSimulator"


@lru_cache(maxsize=None)
def problem(relative: str) -> str | None:
    """Why the tool at ``relative`` (below TOOLS) cannot be used here, or None when ``--version`` runs."""
    exe = TOOLS / relative
    if not exe.is_file():
        return f"{exe} not found (the prebuilt third-party hosts are not beside this checkout)"
    try:
        p = subprocess.run([str(exe), "--version"], capture_output=True, text=True, env={}, timeout=60)
    except OSError as exc:
        return f"{exe.name} cannot start here: {exc}"
    if p.returncode != 0 or "error while loading shared libraries" in p.stderr:
        return f"{exe.name} cannot start here (exit {p.returncode}): {(p.stderr or p.stdout).strip()[-300:]}"
    return None


def run_omsimulator(exe: Path, args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """OMSimulator in ``cwd`` (its temporary and working folder) with an empty environment but for the
    session's TMPDIR (so that anything it left there would be seen): no PATH, LD_PRELOAD or PYTHONHOME."""
    env = {"TMPDIR": os.environ["TMPDIR"]} if "TMPDIR" in os.environ else {}
    return subprocess.run([str(exe), *args], capture_output=True, text=True, env=env, cwd=cwd, timeout=900)


def fmusim_csv(fmu: Path, stop: float, step: float, folder: Path) -> list[list[str]]:
    """fmusim's output of ``fmu`` as co-simulation to ``stop`` every ``step`` [s] (run in ``folder``): its
    header and rows (a skip where fmusim is absent)."""
    import csv

    fmusim = tool(FMUSIM)
    out = folder / "fmusim.csv"
    p = subprocess.run([str(fmusim), "--interface-type", "cs", "--stop-time", repr(stop), "--output-interval",
                        repr(step), "--output-file", str(out), str(fmu)], capture_output=True, text=True,
                       cwd=folder, timeout=600, check=False)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    with out.open() as f:
        return list(csv.reader(f))


def assert_printed_columns(rows: list[list[str]], ref: Any) -> None:
    """Every column of fmusim's ``rows`` (by its header's names) equal to the structured array ``ref``'s
    column to the digits fmusim prints: a Boolean as 1/true, an integer as it is, a real to 16 digits."""
    for j, name in enumerate(rows[0]):
        col = [r[j] for r in rows[1:]]
        if ref[name].dtype.kind == "b":
            assert [x in ("1", "true") for x in col] == list(ref[name]), name
        elif ref[name].dtype.kind in "iu":
            assert [int(x) for x in col] == [int(x) for x in ref[name]], name
        else:
            assert [float(x) for x in col] == [float(f"{x:.16g}") for x in ref[name]], name


def tool(relative: str) -> Path:
    """The tool's executable, or a skip with the reason."""
    why = problem(relative)
    if why is not None:
        pytest.skip(why)
    return TOOLS / relative


# ------------------------------------------------------------------------------------------ the C host
# (tests/c_host/fmi_host.c: built, its spec and its output)
C_HOST = Path(__file__).resolve().parent / "c_host" / "fmi_host.c"


def system_cc() -> str:
    """This machine's C compiler (``CC``, else cc or gcc on PATH), or a skip."""
    import shutil

    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on PATH")
    return cc


def build_c_host(exe: Path, cc: str, windows: bool = False) -> Path:
    """The C host compiled by ``cc`` into ``exe``: for Linux, or (``windows``: a MinGW-w64 compiler) for
    Windows."""
    import fmpy

    inc = f"-I{Path(fmpy.__file__).parent / 'c-code'}"
    libs = ["-static-libgcc"] if windows else ["-ldl", "-lpthread"]
    subprocess.run([cc, "-O2", "-ffp-contract=off", "-Wall", inc, "-o", str(exe), str(C_HOST), *libs], check=True)
    return exe


class Model:
    """What the C host and a reference need of one (extracted) FMU: its identifier, inputs and outputs."""

    def __init__(self, d: Path):
        self.dir = d
        self.md = read_model_description(str(d / "modelDescription.xml"))
        self.id = self.md.coSimulation.modelIdentifier
        self.inputs = [v for v in self.md.modelVariables if v.causality == "input"]
        self.outputs = [v for v in self.md.modelVariables if v.causality == "output"]


def spec_lines(m: Model, instance: str, inputs) -> list[str]:
    lines = [f"fmu {m.dir} {m.id} {m.md.guid} {instance}"]
    for v, k in zip(m.inputs, inputs, strict=True):
        lines.append(f"in {v.valueReference} " + " ".join(repr(float(x)) for x in k))
    kinds = {"Real": "real", "Integer": "int", "Boolean": "bool"}
    lines += [f"{kinds[v.type]} {v.valueReference}" for v in m.outputs]
    return lines


def host_outputs(stdout: str) -> dict[str, list[list[float]]]:
    out: dict[str, list[list[float]]] = {}
    for line in stdout.splitlines():
        if line.startswith("OUT "):
            _, inst, k, *vals = line.split()
            rows = out.setdefault(inst, [])
            assert int(k) == len(rows)
            rows.append([float(x) for x in vals])
    return out
