"""The Modelica Association's Reference FMUs, built from their sources (not a test module).

``tests/data/reference-fmus/fmi2|fmi3/<Model>/`` holds each model as its FMU unpacked without binaries
and sources (modelDescription.xml, resources/, extra/, and for FMI 3.0 sources/buildDescription.xml),
beside its reference result ``<Model>_ref.csv``; the C sources are kept once: ``models/<Model>/``
(model.c, config.h, the same for both FMI versions) and ``common/`` (the code every model shares).
:func:`fmu` compiles them with the system C compiler against the FMI headers FMPy ships and zips the FMU,
its sources included, into ``build/reference-fmus/`` of the checkout (git-ignored), once: the repository
holds no built FMU.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "reference-fmus"
BUILD = ROOT / "build" / "reference-fmus"
PLATFORM = {"fmi2": "linux64", "fmi3": "x86_64-linux"}


def fmu(version: str, model: str) -> Path:
    """``build/reference-fmus/<version>/<model>.fmu``, built from its sources when missing."""
    out = BUILD / version / f"{model}.fmu"
    if out.is_file():
        return out
    import fmpy

    src, own, common = DATA / version / model, DATA / "models" / model, DATA / "common"
    sources = [own / "model.c", own / "config.h"] + [
        common / f for f in ("cosimulation.c", "cosimulation.h", "model.h", f"fmi{version[-1]}Functions.c")]
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise RuntimeError("building the Reference FMUs needs a C compiler (cc or gcc)")
    out.parent.mkdir(parents=True, exist_ok=True)
    # names of this process's own: test workers that build the same FMU at once do not meet; the last
    # rename wins, and every rename is of a whole archive
    tag = f"{os.getpid()}"
    so = out.parent / f".{model}.{tag}.so"
    c_files = [str(p) for p in sources if p.suffix == ".c"]
    flags = [f"-DFMI_VERSION={version[-1]}", "-DDISABLE_PREFIX",   # a binary FMU: unprefixed FMI functions
             f"-I{Path(fmpy.__file__).parent / 'c-code'}", f"-I{own}", f"-I{common}"]
    p = subprocess.run([cc, "-shared", "-fPIC", "-O2", *flags, *c_files, "-o", str(so), "-lm"],
                       capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(f"building {version}/{model}: {p.stderr[-2000:]}")
    part = out.parent / f".{model}.{tag}.fmu.part"
    with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
        for f in sorted(src.rglob("*")):
            if f.is_file():
                zf.write(f, f.relative_to(src).as_posix())
        for f in sources:
            zf.write(f, f"sources/{f.name}")
        zf.write(so, f"binaries/{PLATFORM[version]}/{model}.so")
    so.unlink()
    part.replace(out)
    return out


def fmi2(model: str) -> Path:
    return fmu("fmi2", model)


def fmi3(model: str) -> Path:
    return fmu("fmi3", model)


class _Folder:
    """``REF / "fmi2" / "Dahlquist.fmu"`` is the built FMU; any other name is the data file itself."""

    def __init__(self, path: Path, version: str | None = None) -> None:
        self.path, self.version = path, version

    def __truediv__(self, name: str):
        if self.version is None:
            return _Folder(self.path / name, name) if name in PLATFORM else self.path / name
        return fmu(self.version, name[:-4]) if name.endswith(".fmu") else self.path / name


#: The Reference FMUs' data folder, with built FMUs in place of ``<Model>.fmu``.
REF = _Folder(DATA)
