"""Support for the master's tests (not a test module): scenarios written from Python, test FMUs built
from tests/slaves/ with pythonfmu."""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any, Callable

ROOT = Path(__file__).resolve().parents[1]
G1 = ROOT / "scenarios" / "g1_learn.toml"


def toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f'"{k}" = {toml_value(x)}' for k, x in v.items()) + "}"
    raise TypeError(v)


def write_document(path: Path, doc: dict[str, Any]) -> Path:
    """A scenario document written as a TOML file, each top-level table inline."""
    path.write_text("".join(f"{k} = {toml_value(v)}\n" for k, v in doc.items()))
    return path


def edited_fmu(src: Path, out: Path, edit: Callable[[str, bytes], bytes]) -> Path:
    """A copy of the FMU ``src`` at ``out`` with each entry's bytes through ``edit(name, data)``."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            zout.writestr(info, edit(info.filename, zin.read(info)))
    return out


def write_scenario(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def g1_with_paths(tmp: Path, fmus: dict[str, Path], extra: str = "", name: str = "g1.toml",
                  head: str = "", skip: tuple[str, ...] = ()) -> Path:
    """The G1 learning scenario with our FMUs given by absolute path (no build on demand); ``head`` goes
    before any table, ``extra`` after; instances in ``skip`` are left for ``extra`` to declare."""
    text = f'base = {toml_value(str(G1))}\n{head}'
    text += "".join(f'[instances.{inst}]\nfmu = {toml_value(str(fmus[model]))}\n'
                    for inst, model in (("plant", "WmrPlant"), ("sensor", "WmrSensor"), ("controller", "WmrController"))
                    if inst not in skip)
    return write_scenario(tmp / name, text + extra)


def fmu_cache_dir(name: str) -> Path | None:
    """The folder ``name`` in the FMU cache that the environment variable WMR_TEST_FMU_CACHE names (made if
    missing), or None when it is unset: the mutation testing runs hundreds of short test sessions, which
    then share the FMUs they build."""
    import os

    cache = os.environ.get("WMR_TEST_FMU_CACHE")
    if not cache:
        return None
    folder = Path(cache) / name
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def build_test_fmu(script: str, out: Path) -> Path:
    """Build tests/slaves/<script> with pythonfmu into ``out``, with our loader in front of pythonfmu's
    binary (see :func:`build_test_fmu_uncached`); returns the .fmu.  With an FMU cache
    (:func:`fmu_cache_dir`), an FMU built earlier from the same script and loader is reused from there."""
    import hashlib
    import shutil
    import tempfile

    src = ROOT / "tests" / "slaves" / script
    cache = fmu_cache_dir("test-fmus")
    if cache is None:
        return build_test_fmu_uncached(src, out)
    from wmr_cosim.fmus.build import LOADER_HEADER, LOADER_SOURCES
    key = hashlib.sha256(src.read_bytes() + LOADER_SOURCES[2].read_bytes() + LOADER_HEADER.read_bytes())
    done = cache / f"{src.stem}-{key.hexdigest()[:16]}"
    if not done.is_dir():
        tmp = Path(tempfile.mkdtemp(prefix=done.name, dir=cache))
        build_test_fmu_uncached(src, tmp)
        try:
            tmp.rename(done)          # atomic: a concurrent session may have built it first
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
    fmu = sorted(done.glob("*.fmu"))[-1]
    out.mkdir(parents=True, exist_ok=True)
    shutil.copy2(fmu, out / fmu.name)
    return out / fmu.name


def build_test_fmu_uncached(src: Path, out: Path) -> Path:
    """Build the pythonfmu script ``src`` into ``out``; returns the .fmu.  Its binary is our FMI 2.0 loader
    with pythonfmu's beside it, as in our own FMUs (fmus/build.py): pythonfmu's binary alone corrupts the
    heap at the exit of the process that instantiated it (see fmus/pyloader/wmr_pyfinder.h), and the
    test session hosts these FMUs in its own process."""
    import tempfile

    from wmr_cosim.fmus.build import build_python, compile_loader, install_loader

    p = subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(src), "-d", str(out)],
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(p.stdout + p.stderr)
    fmus = sorted(out.glob("*.fmu"), key=lambda f: f.stat().st_mtime)
    fmu = fmus[-1]
    with tempfile.TemporaryDirectory(prefix="wmr_test_loader_") as tmp:
        py = build_python()
        install_loader(fmu, fmu.stem, compile_loader(Path(tmp) / "loader.so", py), py)
    return fmu


class FakeClock:
    """A wall clock [s] for the real-time pacer's tests: it advances only when slept on (``sleep``) or
    when a test moves ``now``; ``slept`` lists every sleep asked for."""

    def __init__(self, now: float = 100.0) -> None:
        self.now = now
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, dt: float) -> None:
        self.slept.append(dt)
        self.now += dt
