"""Build WmrCPlant.fmu, the plant FMU "from another toolchain": C sources (fmus/c_plant/) compiled with the
C compiler through the CMake project and FMI 2.0 headers that FMPy ships (``fmpy/c-code``).

The FMU holds ``modelDescription.xml``, ``sources/`` with its ``buildDescription.xml`` (so it is also a
source FMU any tool can rebuild: FMPy, Simulink)
and ``binaries/linux64/WmrCPlant.so``, one library for both of its interfaces, co-simulation and Model
Exchange (one ``modelIdentifier``); where the MinGW-w64 cross compiler is on PATH
(``x86_64-w64-mingw32-gcc``, Debian's ``gcc-mingw-w64-x86-64``) also ``binaries/win64/WmrCPlant.dll``,
from the same sources with the same flags (the DLL alone: no import library).  It is rebuilt only when
its inputs change: a SHA-256 over the model description, the C sources, this script, FMPy's CMake
project and the compilers' identities is stored beside it (``WmrCPlant.fmu.sha256``).  Needs ``cmake``
(>= 3.15) and a C compiler (gcc or clang) on PATH.

Floating point: compiled with ``-ffp-contract=off`` (no fused multiply-add) so that the plant's arithmetic
is the IEEE double arithmetic of components/plant.py, operation for operation.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

try:
    from ..cosim.stepping.native import MINGW_CC, MINGW_CXX, WIN64_LDFLAGS
except ImportError:   # run as a script (python fmus/cplant_build.py): from the installed package
    from wmr_cosim.cosim.stepping.native import MINGW_CC, MINGW_CXX, WIN64_LDFLAGS

_HERE = Path(__file__).resolve().parent
SRC = _HERE / "c_plant"
MODEL = "WmrCPlant"
C_FLAGS = "-O2 -ffp-contract=off -fno-fast-math"
#: Libraries the FMU's binary declares (DT_NEEDED) besides libc.
C_LIBS = "-lm"


class CBuildError(RuntimeError):
    """The C plant could not be built (the message says what is missing or what the compiler said)."""


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise CBuildError(f"building {MODEL}.fmu needs {name!r} on PATH (install cmake >= 3.15 and a C compiler, "
                          f"e.g. apt-get install cmake gcc)")
    return path


def _compiler_id(cc: str | None = None) -> str:
    cc = cc or os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        raise CBuildError(f"building {MODEL}.fmu needs a C compiler (cc, gcc or clang) on PATH")
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    except OSError as exc:
        raise CBuildError(f"C compiler {cc}: {exc}") from None
    return cc + "\n" + out.splitlines()[0] if out else cc


def mingw() -> tuple[str, str] | None:
    """The MinGW-w64 C and C++ cross compilers for win64, or None where either is not on PATH."""
    cc, cxx = shutil.which(MINGW_CC), shutil.which(MINGW_CXX)
    return (cc, cxx) if cc and cxx else None


def _fmpy_c_code() -> Path:
    import fmpy
    d = Path(fmpy.__file__).parent / "c-code"
    if not (d / "CMakeLists.txt").is_file() or not (d / "fmi2Functions.h").is_file():
        raise CBuildError(f"{d}: FMPy's CMake project and FMI headers not found (fmpy >= 0.3.20 ships them)")
    return d


def _inputs() -> list[Path]:
    files = [SRC / "modelDescription.xml"] + sorted((SRC / "sources").glob("*.[ch]")) \
        + [SRC / "sources" / "buildDescription.xml"]
    for f in files:
        if not f.is_file():
            raise CBuildError(f"{f}: missing")
    return files


def digest() -> str:
    """SHA-256 over everything that goes into the FMU."""
    h = hashlib.sha256()

    def add(label: str, data: bytes) -> None:
        h.update(f"{label}\0{len(data)}\0".encode())
        h.update(data)

    for f in _inputs():
        add(f.relative_to(SRC).as_posix(), f.read_bytes())
    add("cplant_build.py", Path(__file__).read_bytes())
    c_code = _fmpy_c_code()
    for f in sorted(c_code.iterdir()):
        if f.is_file():
            add(f"fmpy/{f.name}", f.read_bytes())
    add("flags", C_FLAGS.encode())
    add("libs", C_LIBS.encode())
    add("compiler", _compiler_id().encode())
    cross = mingw()
    add("win64", (_compiler_id(cross[0]) + WIN64_LDFLAGS).encode() if cross else b"")
    return h.hexdigest()


def default_out_dir() -> Path:
    from .build import default_out_dir as d
    return d()


def build_c_plant(out_dir: str | os.PathLike | None = None, force: bool = False) -> Path:
    """Build (if needed) ``<out_dir>/WmrCPlant.fmu`` from fmus/c_plant/; returns its path.

    Default ``out_dir``: the Python FMUs' (:func:`wmr_cosim.fmus.build.default_out_dir`)."""
    out = Path(out_dir) if out_dir is not None else default_out_dir()
    out.mkdir(parents=True, exist_ok=True)
    fmu = out / f"{MODEL}.fmu"
    hash_file = out / f"{MODEL}.fmu.sha256"
    dg = digest()
    try:
        if not force and fmu.is_file() and hash_file.read_text().strip() == dg:
            return fmu
    except OSError:
        pass
    cmake = _tool("cmake")
    with tempfile.TemporaryDirectory(prefix="wmr_cplant_build_") as tmp:
        unz = Path(tmp) / "fmu"
        (unz / "sources").mkdir(parents=True)
        shutil.copyfile(SRC / "modelDescription.xml", unz / "modelDescription.xml")
        for f in _inputs()[1:]:
            shutil.copyfile(f, unz / "sources" / f.name)
        # (FMPy's project links no libm: the plant's exp, tanh, sincos and nearbyint need it declared, or a
        # host without libm already loaded fails with "undefined symbol: sincos")
        _cmake(cmake, unz, Path(tmp) / "build", {"CMAKE_C_FLAGS:STRING": C_FLAGS,
                                                 "CMAKE_C_STANDARD_LIBRARIES:STRING": C_LIBS})
        cross = mingw()
        if cross is not None:   # the same sources and flags for win64, into binaries/win64
            _cmake(cmake, unz, Path(tmp) / "build-win64", {
                "CMAKE_SYSTEM_NAME:STRING": "Windows", "CMAKE_C_COMPILER:FILEPATH": cross[0],
                "CMAKE_CXX_COMPILER:FILEPATH": cross[1], "CMAKE_C_FLAGS:STRING": C_FLAGS,
                "CMAKE_SHARED_LINKER_FLAGS:STRING": WIN64_LDFLAGS}, platform="win64")
            for f in (unz / "binaries" / "win64").iterdir():   # the DLL alone (no import library)
                if f.name != f"{MODEL}.dll":
                    f.unlink()
        hash_file.unlink(missing_ok=True)
        part = out / f".{MODEL}.fmu.part"
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
            for f in sorted(unz.rglob("*")):
                if f.is_file():
                    zf.write(f, f.relative_to(unz).as_posix())
        os.replace(part, fmu)
        hash_file.write_text(dg + "\n")
    return fmu


def _cmake(cmake: str, unz: Path, build: Path, options: dict[str, str], platform: str | None = None) -> None:
    """FMPy's CMake project over the unpacked FMU ``unz``, built in ``build`` with ``options``: it installs
    the library into ``unz/binaries/<this platform>`` (``platform``: into ``binaries/<platform>``)."""
    from fmpy.build import create_cmake_settings

    build.mkdir()
    # FMPy writes the CMake cache (model identifier, sources, include dirs, target folder) ...
    create_cmake_settings(unz, build, cmake_options=options)
    if platform is not None:   # (FMPy names the folder of the platform it runs on)
        cache = build / "CMakeCache.txt"
        lines = [f"FMI_TARGET_DIR:STRING={(unz / 'binaries' / platform).as_posix()}"
                 if ln.startswith("FMI_TARGET_DIR:") else ln for ln in cache.read_text().splitlines()]
        cache.write_text("\n".join(lines) + "\n")
    for cmd in ([cmake, "-S", str(_fmpy_c_code()), "-B", str(build)],
                [cmake, "--build", str(build), "--target", "install", "--config", "Release"]):
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            tail = "\n".join((p.stdout + p.stderr).strip().splitlines()[-15:])
            raise CBuildError(f"{' '.join(cmd[:2])} failed (exit {p.returncode}):\n{tail}")
    # ... and its project installs the shared library into binaries/<platform>/
    if not list((unz / "binaries").rglob(f"{platform or '*'}/{MODEL}.*")):
        raise CBuildError(f"the build produced no binaries/{platform or '*'}/{MODEL} library")


def main(argv: list[str] | None = None) -> int:
    """``python -m wmr_cosim.fmus.cplant_build [--out DIR] [--force]``."""
    import argparse
    ap = argparse.ArgumentParser(prog="python -m wmr_cosim.fmus.cplant_build", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    try:
        print(build_c_plant(args.out, args.force))
    except CBuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
