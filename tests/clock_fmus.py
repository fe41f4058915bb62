"""The public synchronous-clock example (github.com/clagms/synchronous-clock-fmus: a Controller with a
periodic input clock r and a triggered input clock s, a Plant, a Supervisor whose output clock s is raised
at a state event) built from its sources with the system C compiler (not a test module).

The sources are read from a local copy of that repository (``SYNC_CLOCK_FMUS``: a git directory or a
checkout; by default a mirror ``.mirror/clagms+synchronous-clock-fmus/repo`` in a folder above the
checkout); the tests that need them are skipped where there is none.  The FMUs are FMI 3.0 (3.0-beta.3
model descriptions) with model exchange and co-simulation (``hasEventMode``) in one binary each."""
from __future__ import annotations

import io
import os
import shutil
import subprocess
import tarfile
import zipfile
from pathlib import Path

import pytest

_MIRROR = Path(".mirror") / "clagms+synchronous-clock-fmus" / "repo"


def _default_sources() -> Path:
    """The mirror of the example in the nearest folder above the checkout that has one."""
    here = Path(__file__).resolve()
    return next((p / _MIRROR for p in here.parents if (p / _MIRROR).is_dir()), _MIRROR)


SOURCES = Path(os.environ["SYNC_CLOCK_FMUS"]) if os.environ.get("SYNC_CLOCK_FMUS") else _default_sources()
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
             order: str = '["Supervisor", "Controller", "Plant"]', extra: str = "",
             interface: str = "co-simulation") -> str:
    """The example's system as a scenario: Controller.ur -> Plant.u_r, Plant.x -> Supervisor.x, the
    Supervisor's output clock s -> the Controller's input clock s, and Supervisor.as -> Controller.as
    (clocked by s), each FMU through ``interface`` (the Plant in Model Exchange integrated by Euler, one
    step per communication step)."""
    inst = "".join(f'[instances.{m}]\nfmu = "{fmus[m]}"\ninterface = "{interface}"\n'
                   + ('solver = "euler"\n' if m == "Plant" and interface == "model-exchange" else "") for m in MODELS)
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


def _crosses(pz: float, z: float) -> bool:
    """The Supervisor's zero crossing of z since pz (its isZeroCrossing)."""
    return pz * z < 0.0 or (pz != 0 and z == 0)


def expected(h: float, n_steps: int, r_every: int, me: bool = False) -> list[tuple[float, float, float, float]]:
    """The example under the FMI 3.0 rules the master follows, computed here from the FMUs' equations (the
    oracle): rows (t, Plant.x, Controller.ur, Supervisor.as) at t_k = k h, each the values after the events
    of t_k, the instances in the order Supervisor, Controller, Plant (Gauss-Seidel: each takes the values
    of the instances before it at t_(k+1), those of the instances after it at t_k).

    The step from t_k to t_(k+1), instance by instance, each step followed by its events at t_(k+1):
    the Supervisor's (its output clock s raised: its clocked output as flips sign); the Controller's: s
    ticks its input clock s (as set: the new as, the Supervisor's partition first, the dependency order),
    r ticks every ``r_every`` points from t = 0 (ur becomes ur + as, after s where both tick); then the
    Plant's Euler step x += h (-x + u_r), u_r the Controller's ur at t_(k+1).  The events at t = 0 are
    those of initialisation (r ticks: ur = as); those of the stop time run too.

    The Supervisor's event: in co-simulation its step from t_k computes z = 2 - x with its input x(t_k)
    and asks for an event at its end (t_(k+1)) when z crossed zero since its last event (pz).  In Model
    Exchange z moves with its input: x(t_k), set at the start of its step from t_k, is an event at t_k
    when z changes sign (the master's test, z > 0 against z <= 0) and the FMU sees the crossing; the
    Controller, past t_k already, takes that tick of s at t_k at the start of its step from t_k."""
    x, ur, as_c, as_s = 0.0, 0.0, 1.0, 1.0
    pz = z = 2.0 - x                # the Supervisor's indicator after initialisation
    ur += as_c                      # r ticks at the start time (the events of initialisation)
    rows = [(0.0, x, ur, as_s)]
    for k in range(n_steps):
        raised = False
        if me:
            if k > 0:                                   # its input x(t_k), set at t_k
                z_new = 2.0 - x
                if (z > 0.0) != (z_new > 0.0):          # an event of its new input, at t_k
                    raised, pz = _crosses(pz, z_new), z_new
                z = z_new
        else:
            z = 2.0 - x                                 # its step from t_k, with x(t_k)
            if _crosses(pz, z):                         # an event at t_(k+1)
                raised, pz = True, z
        if raised:
            as_s = -as_s
            as_c = as_s                                 # the Controller's s ticks (at t_k in ME, t_(k+1) in CS)
        if (k + 1) % r_every == 0:                      # the Controller's r at t_(k+1)
            ur = ur + as_c
        x = x + h * (-x + ur)                           # the Plant's step, u_r = ur(t_(k+1))
        rows.append(((k + 1) * h, x, ur, as_s))
    return rows
