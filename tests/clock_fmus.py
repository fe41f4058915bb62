"""The public synchronous-clock example (github.com/clagms/synchronous-clock-fmus: a Controller with a
periodic input clock r and a triggered input clock s, a Plant, a Supervisor whose output clock s is raised
at a state event) built from its sources with the system C compiler (not a test module).

The sources are read from a local copy of that repository (``SYNC_CLOCK_FMUS``: a git directory or a
checkout; by default the mirror this project's sessions fetch); the tests that need them are skipped
where there is none.  The FMUs are FMI 3.0 (3.0-beta.3 model descriptions) with model exchange and
co-simulation (``hasEventMode``) in one binary each."""
from __future__ import annotations

import io
import os
import shutil
import subprocess
import tarfile
import zipfile
from pathlib import Path

import pytest

SOURCES = Path(os.environ.get("SYNC_CLOCK_FMUS", "/work/.mirror/clagms+synchronous-clock-fmus/repo"))
MODELS = ("Controller", "Plant", "Supervisor")


def _sources(out: Path) -> Path:
    """The example's files under ``out/src`` (from a checkout, or ``git archive`` of a git directory)."""
    dst = out / "src"
    if (SOURCES / "Controller" / "Controller.c").is_file():
        shutil.copytree(SOURCES, dst, ignore=shutil.ignore_patterns(".git"))
        return dst
    if not SOURCES.is_dir() or shutil.which("git") is None:
        pytest.skip(f"no copy of the synchronous-clock example at {SOURCES} (set SYNC_CLOCK_FMUS)")
    p = subprocess.run(["git", f"--git-dir={SOURCES}", "archive", "HEAD"], capture_output=True, timeout=120)
    if p.returncode:
        pytest.skip(f"no copy of the synchronous-clock example at {SOURCES}: {p.stderr.decode()[:200]}")
    with tarfile.open(fileobj=io.BytesIO(p.stdout)) as tf:
        tf.extractall(dst, filter="data")
    return dst


def build_example(out: Path, model_descriptions: dict[str, str] | None = None) -> dict[str, Path]:
    """``out/<Model>.fmu`` for Controller, Plant and Supervisor (a model's description replaced where
    ``model_descriptions`` gives one), and the example's files under ``out/src``."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    src = _sources(out)
    fmus = {}
    for m in MODELS:
        so = out / f"{m}.so"
        p = subprocess.run([cc, "-shared", "-fPIC", "-O1", f"-I{src / 'include'}", str(src / m / f"{m}.c"),
                            str(src / "src" / "fmi3Functions.c"), "-o", str(so), "-lm"], capture_output=True, text=True)
        if p.returncode:
            raise RuntimeError(p.stderr)
        fmu = out / f"{m}.fmu"
        md = (model_descriptions or {}).get(m) or (src / m / "modelDescription.xml").read_text()
        with zipfile.ZipFile(fmu, "w") as zf:
            zf.writestr("modelDescription.xml", md)
            zf.write(so, f"binaries/x86_64-linux/{m}.so")
        so.unlink()
        fmus[m] = fmu
    return fmus


def scenario(fmus: dict[str, Path], step: float = 0.01, stop: float = 10.0,
             order: str = '["Plant", "Supervisor", "Controller"]', extra: str = "") -> str:
    """The example's system as a scenario: Controller.ur -> Plant.u_r, Plant.x -> Supervisor.x, the
    Supervisor's output clock s -> the Controller's input clock s, and Supervisor.as -> Controller.as
    (clocked by s), in co-simulation."""
    inst = "".join(f'[instances.{m}]\nfmu = "{fmus[m]}"\ninterface = "co-simulation"\n' for m in MODELS)
    return f'''[experiment]
start = 0.0
stop = {stop}
step = {step}
order = {order}

{inst}
[[connections]]
from = "Controller.ur"
to = "Plant.u_r"
[[connections]]
from = "Plant.x"
to = "Supervisor.x"
[[connections]]
from = "Supervisor.s"
to = "Controller.s"
[[connections]]
from = "Supervisor.as"
to = "Controller.as"
{extra}
[record]
variables = ["Plant.x", "Controller.ur", "Supervisor.as"]
'''


def expected(h: float, n_steps: int, r_every: int) -> list[tuple[float, float, float, float]]:
    """The example under the FMI 3.0 rules the master follows, computed here from the FMUs' equations (the
    oracle): rows (t, Plant.x, Controller.ur, Supervisor.as) at t_k = k h.

    Plant: x += h (-x + u_r) in each step (its fixed-step Euler); u_r holds the Controller's ur of the last
    tick.  Supervisor: at the end of a step, z = 2 - x; a zero crossing of z since its last event (pz)
    raises its output clock s, and its clocked output as flips sign.  Controller: r ticks every
    ``r_every`` steps from t = 0; at a tick ur becomes ur + as, with as the Supervisor's if s ticks at
    the same instant (the Supervisor's partition first: the dependency order)."""
    x, ur, as_c, as_s, pz = 0.0, 0.0, 1.0, 1.0, 2.0
    ur += as_c                      # r ticks at the start time
    rows = [(0.0, x, ur, as_s)]
    for n in range(1, n_steps + 1):
        x = x + h * (-x + ur)
        z = 2.0 - x
        if pz * z < 0.0 or (pz != 0 and z == 0):
            as_s, pz = -as_s, z
            as_c = as_s             # s ticks the Controller's s: as set at the tick
        if n % r_every == 0:
            ur = ur + as_c
        rows.append((n * h, x, ur, as_s))
    return rows
