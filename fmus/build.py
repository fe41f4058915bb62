"""Build WmrPlant.fmu, WmrSensor.fmu and WmrController.fmu with pythonfmu (FMI 2.0), and WmrPlant3.fmu,
WmrSensor3.fmu and WmrController3.fmu with pythonfmu3 (FMI 3.0), rebuilding only what changed.

FMI 3.0: the same slave script, bundled in the package as ``slave_<component>.py`` with its ``fmi_base``
import pointing at ``fmi3_base`` (the FMI 3.0 base with the same interface), and a two-line main script
``class WmrPlant3(WmrPlant, Fmi3Slave)``; the FMI 3.0 loader (below) in front of pythonfmu3's binary.
Its package is ``wmrfmu_<component>3_<hash8>``, the hash over the slave script, fmi3_base.py, fmi_decl.py,
the components, this script, the loader's sources, the Python and C compiler and the pythonfmu3 version.

Each FMU carries, in its resources, a copy of the components package (with paper_results.json) plus
fmus/fmi_base.py under a package name unique to the FMU and to the source version,
``wmrfmu_<component>_<hash8>``, and its slave script as ``wmr_<component>_slave_<hash8>.py`` with the
two ``wmr_cosim`` imports rewritten to that package.  So the code inside an FMU never collides with the
installed ``wmr_cosim``, with another of the three FMUs, or with another build of the same FMU loaded in
the same process: a slave script's file name becomes a module name in the host process, so two FMUs whose
scripts or helper packages share a name collide (the second fails to instantiate or silently runs the
first one's code), and a rebuilt FMU loaded again in the same process would run the old, cached code.

``hash8`` is the start of a SHA-256 over everything that goes into the FMU: the slave script,
fmi_base.py, every file of components/ (.py and .json), this build script and the pythonfmu version.
It is stored beside the FMU (``WmrPlant.fmu.sha256``); an FMU is rebuilt only when it is missing or
its hash differs.  pythonfmu's builder runs in a child process (it imports the slave script and leaves
modules and sys.path entries behind).

Loader: pythonfmu's and pythonfmu3's binaries take the Python C API from the process that loads them, so
alone they run only in Python hosts.  Each FMU's ``binaries/linux64/<model>.so`` (FMI 3.0:
``binaries/x86_64-linux/<model>.so``) is instead our loader (fmus/pyloader/, compiled here with the system
C compiler; wmr_pyloader.c for FMI 2.0, wmr_pyloader3.c for FMI 3.0, the shared part in wmr_pyfinder.h):
it uses the interpreter already in the process, or loads the libpython this build ran on (recorded in the
loader; the environment variable :data:`LIBPYTHON_ENV` names another), and forwards every FMI call to
pythonfmu's binary, shipped beside it as ``libpythonfmu-export.so``, guarding against that binary's
use-after-free at exit and its double release after a Fatal status (see wmr_pyfinder.h).  The model
description records the Python version, library and variable (FMI 2.0: VendorAnnotations; FMI 3.0: an
Annotation of type ``wmr-cosim``).

Platforms: only the binaries built and tested here ship.  Linux (``binaries/linux64``; FMI 3.0
``binaries/x86_64-linux``) always; 64-bit Windows (FMI 2.0 ``binaries/win64``) when MinGW-w64's C
compiler is on PATH: the same loader, cross-compiled (``-static-libgcc``: it imports only Windows' own
KERNEL32, ADVAPI32 and msvcrt), in front of pythonfmu's stock ``pythonfmu-export.dll``; on Windows the
loader finds the Python of a Python host, or the one :data:`LIBPYTHON_ENV` names, or the newest one
registered (wmr_pyfinder.h says how).  The stock Windows DLL of pythonfmu3 (``binaries/x86_64-windows``)
is removed: no FMI 3.0 host runs under Wine here to test it.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

try:
    from ..cosim.messages.errors import CosimError
    from ..cosim.stepping.native import MINGW_CC, WIN64_LDFLAGS, fmi_headers
except ImportError:   # run as a script (python fmus/build.py): from the installed package
    from wmr_cosim.cosim.messages.errors import CosimError
    from wmr_cosim.cosim.stepping.native import MINGW_CC, WIN64_LDFLAGS, fmi_headers

_HERE = Path(__file__).resolve().parent

#: model name -> (slave script in fmus/, component short name)
SLAVES: dict[str, tuple[str, str]] = {
    "WmrPlant": ("slave_plant.py", "plant"),
    "WmrSensor": ("slave_sensor.py", "sensor"),
    "WmrController": ("slave_controller.py", "controller"),
}
#: FMI 3.0 model name -> the FMI 2.0 model it exposes (same slave script and component).
SLAVES3: dict[str, str] = {"WmrPlant3": "WmrPlant", "WmrSensor3": "WmrSensor", "WmrController3": "WmrController"}
#: The FMI version of every model name build_all knows.
FMI_VERSION: dict[str, int] = {**{m: 2 for m in SLAVES}, **{m: 3 for m in SLAVES3}}
#: Build options: state save/restore and serialisation declared (pythonfmu declares them only with these
#: flags); never --interpolate-inputs (it declares a capability pythonfmu does not implement).
BUILD_OPTIONS = ("--handle-state", "--serialize-state")
_IMPORT_RE = re.compile(r"^\s*(from|import)\s+wmr_cosim\b", re.MULTILINE)
#: The loader's C sources by FMI version, the part both include, and the name pythonfmu's own binary gets
#: beside the loader.
LOADER_SOURCES = {2: _HERE / "pyloader" / "wmr_pyloader.c", 3: _HERE / "pyloader" / "wmr_pyloader3.c"}
LOADER_HEADER = _HERE / "pyloader" / "wmr_pyfinder.h"
REAL_BINARY = "libpythonfmu-export.so"
#: The name pythonfmu's Windows binary keeps beside the Windows loader.
REAL_BINARY_WINDOWS = "pythonfmu-export.dll"
#: The environment variable that points the FMUs at another libpython (a path to libpython3.X.so).
LIBPYTHON_ENV = "WMR_FMU_LIBPYTHON"


class BuildError(RuntimeError):
    """An FMU could not be built; the message is one line (plus the builder's output, if any)."""


@dataclass(frozen=True)
class Plan:
    """What goes into one FMU."""

    model: str
    short: str
    script: Path
    digest: str
    fmi: int = 2

    @property
    def hash8(self) -> str:
        return self.digest[:8]

    @property
    def options(self) -> tuple[str, ...]:
        """pythonfmu's build options: :data:`BUILD_OPTIONS`, and ``--no-variable-step`` for a slave that
        declares ``variable_step = False`` (the builder writes canHandleVariableCommunicationStepSize from
        its options, over what the slave's model description says)."""
        return BUILD_OPTIONS + (() if variable_step(self.script) else ("--no-variable-step",))

    @property
    def package(self) -> str:
        return f"wmrfmu_{self.short}_{self.hash8}"

    @property
    def module(self) -> str:
        return f"wmr_{self.short}_slave_{self.hash8}"


def variable_step(script: Path) -> bool:
    """Whether the slave class of ``script`` takes steps of any length: its class attribute
    ``variable_step`` (see fmi_decl.SlaveCore), read from the source without importing it."""
    for node in ast.walk(ast.parse(script.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ClassDef):
            for stmt in node.body:
                if (isinstance(stmt, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "variable_step"
                                                         for t in stmt.targets)
                        and isinstance(stmt.value, ast.Constant)):
                    return bool(stmt.value.value)
    return True


def _components_dir() -> Path:
    """The components package folder: ../components in a source tree, else the installed package."""
    here = _HERE.parent / "components"
    if (here / "plant.py").is_file():
        return here
    from wmr_cosim import components  # installed (non-editable): use the package's own folder
    return Path(components.__file__).resolve().parent


def _component_files() -> list[Path]:
    d = _components_dir()
    files = sorted(p for p in d.iterdir() if p.is_file() and p.suffix in (".py", ".json"))
    if not any(p.name == "paper_results.json" for p in files):
        raise BuildError(f"{d}: paper_results.json is missing")
    return files


def _pythonfmu_version() -> str:
    from pythonfmu import __version__
    return __version__


def _pythonfmu3_version() -> str:
    try:
        from pythonfmu3 import __version__
    except ImportError:
        return "not installed"
    return __version__


@dataclass(frozen=True)
class PythonRecord:
    """The interpreter a build records for the loader: version "X.Y", its shared library ("" if it has
    none: a Python built without --enable-shared) and its prefix (where its standard library is)."""

    version: str
    library: str
    home: str


def build_python() -> PythonRecord:
    """The Python this build runs on, as the loader records it."""
    import sysconfig
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    library = ""
    if sysconfig.get_config_var("Py_ENABLE_SHARED"):
        for name in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
            if name and libdir and (Path(libdir) / name).is_file():
                library = str(Path(libdir) / name)
                break
    return PythonRecord(version, library, sys.base_prefix)


def c_compiler() -> str:
    """The C compiler the loader is built with: $CC, else cc, gcc or clang on PATH."""
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        raise BuildError("building the FMUs needs a C compiler (cc, gcc or clang) on PATH for their Python "
                         "loader (fmus/pyloader/wmr_pyloader.c): install one, e.g. apt-get install gcc")
    return cc


@functools.lru_cache(maxsize=None)
def _compiler_identity() -> str:
    """The C compiler's path and version line, for the build hash ("no C compiler" when there is none:
    the build then stops with one line)."""
    try:
        return _compiler_id(c_compiler())
    except BuildError:
        return "no C compiler"


def min_python() -> tuple[int, int]:
    """The oldest Python the FMUs' code runs on: the package's Requires-Python (">=3.11"), which the
    Windows loader's choice among the registered Pythons follows."""
    from importlib.metadata import PackageNotFoundError, metadata
    try:
        md = metadata("wmr-cosim")   # the protocol of Python 3.11's stubs has no get (3.12's has)
        spec = md["Requires-Python"] if "Requires-Python" in md else ""
    except PackageNotFoundError:
        spec = ""
    m = re.fullmatch(r">=\s*3\.(\d+)", spec.strip())
    if m is None:
        raise BuildError(f"wmr-cosim's Requires-Python {spec!r}: expected '>=3.N' (install the package: pip install -e .)")
    return 3, int(m.group(1))


def windows_compiler() -> str | None:
    """MinGW-w64's C compiler for win64 (the Windows loader), or None where it is not on PATH."""
    return shutil.which(MINGW_CC)


@functools.lru_cache(maxsize=None)
def _windows_compiler_identity() -> str:
    """MinGW-w64's path and version line, for the build hash ("no MinGW-w64": no Windows binaries)."""
    cc = windows_compiler()
    return _compiler_id(cc) if cc else "no MinGW-w64"


def _compiler_id(cc: str) -> str:
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=60).stdout
    except OSError as exc:
        raise BuildError(f"C compiler {cc}: {exc}") from None
    return cc + "\n" + (out.splitlines()[0] if out else "")


def _fmi_headers(fmi: int = 2) -> Path:
    """The FMI 2.0 or 3.0 headers FMPy ships (the master's :func:`fmi_headers`, as BuildError)."""
    try:
        return fmi_headers(fmi)
    except CosimError as exc:   # (the headers are not where FMPy ships them)
        raise BuildError(str(exc)) from None


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def compile_loader(dest: Path, py: PythonRecord | None = None, fmi: int = 2, windows: bool = False) -> Path:
    """Compile the loader of FMI version ``fmi`` into ``dest`` (a shared library; with ``windows``, a win64
    DLL cross-compiled by MinGW-w64); returns its path."""
    py = py or build_python()
    source = LOADER_SOURCES[fmi]
    defines = [f"-DWMR_PY_VERSION={_c_string(py.version)}", f"-DWMR_PY_ENV={_c_string(LIBPYTHON_ENV)}",
               f"-DWMR_PY_MIN_MINOR={min_python()[1]}"]
    if windows:
        cc = windows_compiler()
        if cc is None:
            raise BuildError("building the Windows loader needs MinGW-w64 (x86_64-w64-mingw32-gcc)")
        cmd = [cc, "-shared", "-O2", "-Wall", *WIN64_LDFLAGS.split(), f"-I{_fmi_headers(fmi)}", *defines,
               "-o", str(dest), str(source), "-ladvapi32"]
    else:
        cc = c_compiler()
        cmd = [cc, "-shared", "-fPIC", "-O2", "-Wall", f"-I{_fmi_headers(fmi)}",
               f"-DWMR_PY_LIBRARY={_c_string(py.library)}", f"-DWMR_PY_HOME={_c_string(py.home)}", *defines,
               "-o", str(dest), str(source), "-ldl", "-lpthread"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0 or not dest.is_file() or "warning" in p.stderr:
        tail = "\n".join((p.stdout + p.stderr).strip().splitlines()[-10:])
        raise BuildError(f"compiling the FMU loader {source.name} with {cc} failed (exit {p.returncode}):\n{tail}")
    return dest


def _python_element(py: PythonRecord, platform: str) -> str:
    from xml.sax.saxutils import quoteattr
    return (f'<Python version={quoteattr(py.version)} library={quoteattr(py.library)} '
            f'override={quoteattr(LIBPYTHON_ENV)} platforms={quoteattr(platform)} description='
            f'{quoteattr(f"Runs on Python {py.version} (its shared library libpython{py.version}.so, found at the path recorded here) or on the interpreter of a Python host; set the environment variable {LIBPYTHON_ENV} to the path of another libpython3.X.so to use it")}/>')


def _python_element_windows(platform: str) -> str:
    from xml.sax.saxutils import quoteattr
    major, minor = min_python()
    return (f'<Python version={quoteattr(f"{major}.{minor} or later")} library="" '
            f'override={quoteattr(LIBPYTHON_ENV)} platforms={quoteattr(platform)} description='
            f'{quoteattr(f"Runs on the interpreter of a Python host, else on the python3X.dll (or its folder) named by the environment variable {LIBPYTHON_ENV}, else on the newest 64-bit Python {major}.{minor} or later registered (PEP 514, as the python.org installer registers it); only its standard library is needed")}/>')


def _vendor_annotation(py: PythonRecord, windows: bool = False) -> str:
    """The FMI 2.0 form: one element in the Tool (the schema allows one), a Python per platform in it."""
    win = f'\t\t\t\t{_python_element_windows(WINDOWS_PLATFORM[2])}\n' if windows else ""
    return (f'\t<VendorAnnotations>\n\t\t<Tool name="wmr-cosim">\n\t\t\t<Loader>\n'
            f'\t\t\t\t{_python_element(py, "linux64")}\n{win}'
            f'\t\t\t</Loader>\n\t\t</Tool>\n\t</VendorAnnotations>\n')


def _annotation3(py: PythonRecord) -> str:
    """The FMI 3.0 form (an Annotation of the model description's last element, Annotations)."""
    return (f'\t<Annotations>\n\t\t<Annotation type="wmr-cosim">\n'
            f'\t\t\t{_python_element(py, "x86_64-linux")}\n'
            f'\t\t</Annotation>\n\t</Annotations>\n')


def install_loader(fmu: Path, model: str, loader: Path, py: PythonRecord, fmi: int = 2,
                   windows_loader: Path | None = None) -> None:
    """Rewrite ``fmu`` in place: pythonfmu's binaries/linux64/<model>.so (FMI 3.0: pythonfmu3's
    binaries/x86_64-linux/<model>.so) becomes ``libpythonfmu-export.so``, the loader takes its name, and
    the model description records the loader's Python (VendorAnnotations; FMI 3.0: Annotations).  With
    ``windows_loader`` (FMI 2.0), pythonfmu's binaries/win64/<model>.dll becomes ``pythonfmu-export.dll``
    and that loader takes its name."""
    swaps = {f"binaries/{SHIPPED_PLATFORM[fmi]}/{model}.so": (f"binaries/{SHIPPED_PLATFORM[fmi]}/{REAL_BINARY}", loader)}
    if windows_loader is not None:
        if fmi not in WINDOWS_PLATFORM:
            raise BuildError(f"{fmu}: no Windows loader for FMI {fmi}.0")
        win = WINDOWS_PLATFORM[fmi]
        swaps[f"binaries/{win}/{model}.dll"] = (f"binaries/{win}/{REAL_BINARY_WINDOWS}", windows_loader)
    part = fmu.with_name(fmu.name + ".part")
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as dst:
        names = src.namelist()
        for ours in swaps:
            if ours not in names:
                raise BuildError(f"{fmu}: pythonfmu wrote no {ours}")
        for info in src.infolist():
            data = src.read(info)
            if info.filename in swaps:
                real, ours_file = swaps[info.filename]
                dst.writestr(real, data)
                dst.write(ours_file, info.filename)
                continue
            if info.filename == "modelDescription.xml":
                text = data.decode("utf-8")
                if fmi == 3:
                    if "<Annotations" in text or text.count("</ModelStructure>") != 1:
                        raise BuildError(f"{fmu}: unexpected model description (Annotations already there)")
                    at = text.index("</ModelStructure>") + len("</ModelStructure>\n")  # schema order: last
                    text = text[:at] + _annotation3(py) + text[at:]
                else:
                    if "<VendorAnnotations" in text or "<ModelVariables" not in text:
                        raise BuildError(f"{fmu}: unexpected model description (VendorAnnotations already there)")
                    at = text.rfind("\n", 0, text.index("<ModelVariables")) + 1  # schema order: just before
                    text = text[:at] + _vendor_annotation(py, windows_loader is not None) + text[at:]
                data = text.encode("utf-8")
            dst.writestr(info.filename, data)
    os.replace(part, fmu)


#: The Linux platform folder by FMI version: always built and tested here.
SHIPPED_PLATFORM = {2: "linux64", 3: "x86_64-linux"}
#: The Windows platform folder by FMI version, built where MinGW-w64 is present and tested under Wine.
#: FMI 3.0 has none: pythonfmu3's stock binaries/x86_64-windows DLL is removed (no FMI 3.0 host runs under
#: Wine here to test it).
WINDOWS_PLATFORM = {2: "win64"}


def shipped_platforms(fmi: int) -> set[str]:
    """The platform folders an FMU of FMI version ``fmi`` built on this machine carries."""
    win = {WINDOWS_PLATFORM[fmi]} if fmi in WINDOWS_PLATFORM and windows_compiler() else set()
    return {SHIPPED_PLATFORM[fmi]} | win


def _platforms(names: list[str] | set[str]) -> set[str]:
    """The platform folders under binaries/ that hold a file."""
    return {n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2 and not n.endswith("/")}


def ship_only_tested_binaries(fmu: Path, fmi: int, keep: set[str] | None = None) -> None:
    """Rewrite ``fmu`` in place without the binaries of any platform but ``keep`` (default: the Linux one,
    :data:`SHIPPED_PLATFORM`), and without the empty folders of those platforms."""
    keep = keep if keep is not None else {SHIPPED_PLATFORM[fmi]}
    with zipfile.ZipFile(fmu) as src:
        if _platforms(src.namelist()) <= keep:
            return
        part = fmu.with_name(fmu.name + ".part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as dst:
            for info in src.infolist():
                parts = info.filename.split("/")
                if parts[0] == "binaries" and len(parts) >= 2 and parts[1] != "" and parts[1] not in keep:
                    continue
                dst.writestr(info, src.read(info))
    os.replace(part, fmu)


def plan(model: str) -> Plan:
    """The inputs of one FMU and their hash."""
    if model in SLAVES3:
        return _plan3(model)
    script_name, short = SLAVES[model]
    script = _HERE / script_name
    h = hashlib.sha256()

    def add(label: str, data: bytes) -> None:
        h.update(f"{label}\0{len(data)}\0".encode())
        h.update(data)

    add("pythonfmu", _pythonfmu_version().encode())
    add("options", " ".join(BUILD_OPTIONS).encode())
    add("build.py", Path(__file__).read_bytes())
    add("slave", script.read_bytes())
    add("fmi_base.py", (_HERE / "fmi_base.py").read_bytes())
    add("fmi_decl.py", (_HERE / "fmi_decl.py").read_bytes())
    add("loader", LOADER_SOURCES[2].read_bytes())
    add("loader header", LOADER_HEADER.read_bytes())
    add("python", repr(build_python()).encode())
    add("compiler", _compiler_identity().encode())
    add("windows compiler", _windows_compiler_identity().encode())
    for f in _component_files():
        add(f"components/{f.name}", f.read_bytes())
    return Plan(model, short, script, h.hexdigest())


def _plan3(model: str) -> Plan:
    """The inputs of one FMI 3.0 FMU and their hash."""
    script_name, short = SLAVES[SLAVES3[model]]
    script = _HERE / script_name
    h = hashlib.sha256()
    for label, data in (("pythonfmu3", _pythonfmu3_version().encode()), ("options", " ".join(BUILD_OPTIONS).encode()),
                        ("build.py", Path(__file__).read_bytes()), ("slave", script.read_bytes()),
                        ("fmi3_base.py", (_HERE / "fmi3_base.py").read_bytes()),
                        ("fmi_decl.py", (_HERE / "fmi_decl.py").read_bytes()),
                        ("loader", LOADER_SOURCES[3].read_bytes()), ("loader header", LOADER_HEADER.read_bytes()),
                        ("python", repr(build_python()).encode()), ("compiler", _compiler_identity().encode()),
                        *((f"components/{f.name}", f.read_bytes()) for f in _component_files())):
        h.update(f"{label}\0{len(data)}\0".encode())
        h.update(data)
    return Plan(model, short + "3", script, h.hexdigest(), 3)


def default_out_dir() -> Path:
    """Where FMUs named by model name are built: ``<checkout>/build/fmus`` in a source checkout or an
    editable install (build/ is git-ignored); installed from a wheel, the per-user cache
    ``$XDG_CACHE_HOME/wmr-cosim/fmus`` (``~/.cache/wmr-cosim/fmus``), never inside the installed package.
    One cache serves every working folder; an FMU there is rebuilt when its inputs' hash differs."""
    root = _HERE.parent
    if (root / "pyproject.toml").is_file() and (root / "components").is_dir():
        return root / "build" / "fmus"
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "wmr-cosim" / "fmus"


def rewrite_imports(source: str, package: str) -> str:
    """The slave script with its ``wmr_cosim.components`` / ``wmr_cosim.fmus`` imports pointing at the
    bundled package; refuses a script that would still import wmr_cosim."""
    out = re.sub(r"^(\s*from\s+)wmr_cosim\.(components|fmus)\.", rf"\g<1>{package}.", source, flags=re.MULTILINE)
    if _IMPORT_RE.search(out):
        raise BuildError(f"slave script still imports wmr_cosim after rewriting to {package}: "
                         f"import only from wmr_cosim.components.<module> and wmr_cosim.fmus.fmi_base")
    return out


def _stage(p: Plan, stage: Path) -> Path:
    """Write the slave script and the bundled package into ``stage``; return the script's path."""
    pkg = stage / p.package
    pkg.mkdir(parents=True)
    for f in _component_files():
        text = f.read_bytes()
        if f.suffix == ".py" and _IMPORT_RE.search(text.decode("utf-8")):
            raise BuildError(f"components/{f.name} imports wmr_cosim: components must use relative imports only")
        (pkg / f.name).write_bytes(text)
    shutil.copyfile(_HERE / "fmi_decl.py", pkg / "fmi_decl.py")
    script = stage / f"{p.module}.py"
    source = rewrite_imports(p.script.read_text(encoding="utf-8"), p.package)
    if p.fmi == 2:
        shutil.copyfile(_HERE / "fmi_base.py", pkg / "fmi_base.py")
        script.write_text(source, encoding="utf-8")
        return script
    shutil.copyfile(_HERE / "fmi3_base.py", pkg / "fmi3_base.py")
    base = SLAVES3[p.model]
    (pkg / p.script.name).write_text(source.replace(f"from {p.package}.fmi_base import",
                                                    f"from {p.package}.fmi3_base import"), encoding="utf-8")
    script.write_text(f'"""{p.model}: {base} as an FMI 3.0 co-simulation slave (same declarations and component)."""\n'
                      f"from {p.package}.fmi3_base import Fmi3Slave\n"
                      f"from {p.package}.{p.script.stem} import {base} as _Model\n\n\n"
                      f"class {p.model}(_Model, Fmi3Slave):\n    pass\n", encoding="utf-8")
    return script


def _hash_file(fmu: Path) -> Path:
    return fmu.with_name(fmu.name + ".sha256")


def is_current(fmu: Path, p: Plan) -> bool:
    """True if ``fmu`` exists and was built from exactly the inputs of ``p``."""
    hf = _hash_file(fmu)
    try:
        return fmu.is_file() and hf.read_text(encoding="utf-8").strip() == p.digest
    except OSError:
        return False


def _check_archive(fmu: Path, p: Plan) -> None:
    with zipfile.ZipFile(fmu) as zf:
        names = set(zf.namelist())
        md = zf.read("modelDescription.xml").decode("utf-8")
    shipped = shipped_platforms(p.fmi)
    other = sorted(_platforms(names) - shipped)
    if other:
        raise BuildError(f"{fmu}: binaries for {', '.join(other)} in the built FMU: only "
                         f"{', '.join(sorted(shipped))} are built and tested")
    if p.fmi in WINDOWS_PLATFORM and WINDOWS_PLATFORM[p.fmi] in shipped:
        win = WINDOWS_PLATFORM[p.fmi]
        missing = sorted({f"binaries/{win}/{p.model}.dll", f"binaries/{win}/{REAL_BINARY_WINDOWS}"} - names)
        if missing:
            raise BuildError(f"{fmu}: entries missing from the built FMU: {', '.join(missing)}")
    if p.fmi == 3:
        need = {"modelDescription.xml", f"resources/{p.module}.py", f"resources/{p.package}/fmi3_base.py",
                f"resources/{p.package}/fmi_decl.py", f"resources/{p.package}/{p.script.name}",
                f"resources/{p.package}/paper_results.json", "resources/slavemodule.txt",
                f"binaries/x86_64-linux/{p.model}.so", f"binaries/x86_64-linux/{REAL_BINARY}"}
        missing = sorted(need - names)
        if missing:
            raise BuildError(f"{fmu}: entries missing from the built FMU: {', '.join(missing)}")
        if (f'modelName="{p.model}"' not in md or 'canGetAndSetFMUState="true"' not in md
                or f'override="{LIBPYTHON_ENV}"' not in md):
            raise BuildError(f"{fmu}: unexpected model description (model name or state capabilities)")
        return
    need = {"modelDescription.xml", f"resources/{p.module}.py", f"resources/{p.package}/__init__.py",
            f"resources/{p.package}/fmi_base.py", f"resources/{p.package}/paper_results.json",
            "resources/slavemodule.txt", f"binaries/linux64/{p.model}.so", f"binaries/linux64/{REAL_BINARY}"}
    missing = sorted(need - names)
    if missing:
        raise BuildError(f"{fmu}: entries missing from the built FMU: {', '.join(missing)}")
    if (f'modelName="{p.model}"' not in md or 'canGetAndSetFMUstate="true"' not in md
            or f'override="{LIBPYTHON_ENV}"' not in md):
        raise BuildError(f"{fmu}: unexpected model description (model name or state capabilities)")


def up_to_date(out_dir: Path | None = None, models: tuple[str, ...] | None = None) -> dict[str, bool]:
    """{model name: True if its FMU in ``out_dir`` is current} (what :func:`build_all` would skip)."""
    out = Path(out_dir) if out_dir is not None else default_out_dir()
    return {m: is_current(out / f"{m}.fmu", plan(m)) for m in (models or tuple(SLAVES))}


def models_for(fmi: int) -> tuple[str, ...]:
    """The model names of FMI version ``fmi`` (2 or 3)."""
    if fmi not in (2, 3):
        raise BuildError(f"FMI version {fmi}: 2 or 3")
    return tuple(SLAVES) if fmi == 2 else tuple(SLAVES3)


def build_all(out_dir: Path | None = None, force: bool = False, models: tuple[str, ...] | None = None,
              ) -> dict[str, Path]:
    """Build the FMUs into ``out_dir`` (default :func:`default_out_dir`); rebuild only those whose inputs
    changed (or all, with ``force``).  Returns {model name: path of the .fmu}."""
    out = Path(out_dir) if out_dir is not None else default_out_dir()
    if out.exists() and not out.is_dir():
        raise BuildError(f"output {out} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    models = tuple(SLAVES) if models is None else models
    unknown = [m for m in models if m not in FMI_VERSION]
    if unknown:
        raise BuildError(f"unknown FMU {', '.join(unknown)}: one of {', '.join(FMI_VERSION)}")
    result: dict[str, Path] = {}
    todo: list[tuple[Plan, Path]] = []
    for m in models:
        p = plan(m)
        fmu = out / f"{m}.fmu"
        result[m] = fmu
        if force or not is_current(fmu, p):
            todo.append((p, fmu))
    if not todo:
        return result
    py = build_python()
    if any(p.fmi == 3 for p, _ in todo) and _pythonfmu3_version() == "not installed":
        raise BuildError("building the FMI 3.0 FMUs needs pythonfmu3: pip install pythonfmu3")
    with tempfile.TemporaryDirectory(prefix="wmr_fmu_build_") as tmp:
        fmis = sorted({p.fmi for p, _ in todo})
        loaders = {fmi: compile_loader(Path(tmp) / f"loader{fmi}.so", py, fmi) for fmi in fmis}
        windows = {fmi: compile_loader(Path(tmp) / f"loader{fmi}.dll", py, fmi, windows=True)
                   for fmi in fmis if WINDOWS_PLATFORM.get(fmi) in shipped_platforms(fmi)}
        procs = []
        for p, fmu in todo:
            stage = Path(tmp) / p.model
            script = _stage(p, stage)
            dest = stage / "out"
            cmd = [sys.executable, "-m", "pythonfmu" if p.fmi == 2 else "pythonfmu3", "build", "-f", str(script),
                   "-d", str(dest), *p.options, str(stage / p.package)]
            env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
            procs.append((p, fmu, dest, subprocess.Popen(cmd, cwd=stage, env=env, stdout=subprocess.PIPE,
                                                          stderr=subprocess.STDOUT, text=True)))
        errors = []
        for p, fmu, dest, proc in procs:
            log, _ = proc.communicate()
            built = dest / f"{p.model}.fmu"
            if proc.returncode != 0 or not built.is_file():
                tail = "\n".join(log.strip().splitlines()[-15:])
                errors.append(f"{p.model}: pythonfmu build failed (exit {proc.returncode})\n{tail}")
                continue
            install_loader(built, p.model, loaders[p.fmi], py, p.fmi, windows.get(p.fmi))
            ship_only_tested_binaries(built, p.fmi, shipped_platforms(p.fmi))
            _check_archive(built, p)
            _hash_file(fmu).unlink(missing_ok=True)  # no stale hash beside a half-replaced FMU
            if not _same_fs(built, fmu):  # copy next to the target first, so the replace is atomic
                part = fmu.with_name(f".{fmu.name}.part")
                shutil.move(str(built), str(part))
                built = part
            os.replace(built, fmu)
            _hash_file(fmu).write_text(p.digest + "\n", encoding="utf-8")
        if errors:
            raise BuildError("\n".join(errors))
    return result


def _same_fs(a: Path, b: Path) -> bool:
    try:
        return os.stat(a).st_dev == os.stat(b.parent).st_dev
    except OSError:
        return False


def main(argv: list[str] | None = None) -> int:
    """``python -m wmr_cosim.fmus.build [--out DIR] [--force]``."""
    import argparse
    ap = argparse.ArgumentParser(prog="python -m wmr_cosim.fmus.build", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version (default 2)")
    args = ap.parse_args(argv)
    for model, path in build_all(args.out, args.force, models_for(args.fmi)).items():
        print(f"{model}: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
