"""The C plant on Windows, tested here: its win64 DLL (MinGW-w64 from the same sources and flags as
linux64) loaded and stepped by the plain C host built for Windows, under Wine, against the same host's
Linux build on the linux64 library: 25,000 steps of the inputs G1 gives the plant.  ``pytest -m windows``
runs these alone; they skip, saying which Debian package is missing, where MinGW-w64 or Wine is not
installed."""
from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path
from typing import Iterator

import numpy as np
import pytest

from host_tools import Model, build_c_host, host_outputs, spec_lines, system_cc
from windows_support import Wine, mingw_cc, pe_exports, pe_imports, wine_session

from wmr_cosim import cosim
from wmr_cosim.fmus import cplant_build
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
def g1_inputs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    """The C plant's four inputs over G1 (its torques and disturbances, 25,000 steps of 2 ms) as the host's
    table of doubles, and the number of steps."""
    sc = cosim.load(str(TESTS.parent / "scenarios" / "g1_c_plant.toml"), resolve_model)
    sc.record = ["plant.u1", "plant.u2", "plant.tau_d1", "plant.tau_d2"]
    out = tmp_path_factory.mktemp("g1_inputs")
    res = cosim.run(cosim.resolve(sc), out / "run", progress=False)
    assert res.status == "ok", res.message
    rows = np.load(out / "run" / "signals.npy")
    table = np.column_stack([rows[c] for c in sc.record]).astype("<f8")
    assert np.ptp(table[:, 0]) > 1.0
    table.tofile(out / "inputs.bin")
    return out / "inputs.bin", len(rows) - 1


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
                                                             wine: Wine, g1_inputs: tuple[Path, int],
                                                             tmp_path: Path) -> None:
    """25,000 steps of G1's plant inputs through the C host on each platform: every output within 1e-12
    relative (or 1e-300 absolute) of linux64's; the largest difference is printed."""
    table, n = g1_inputs
    m = Model(c_plant)
    lines = spec_lines(m, "plant", [(0, 0, 0, 0, 0)] * len(m.inputs)) + [f"table {table}", f"steps {n} 0.002"]
    spec = tmp_path / "plant.spec"
    spec.write_text("\n".join(lines) + "\n")
    linux = subprocess.run([str(hosts[0]), str(spec)], capture_output=True, text=True, timeout=300)
    windows = wine.run(hosts[1], spec, timeout=300)
    assert linux.returncode == 0 and linux.stdout.rstrip().endswith("DONE"), linux.stdout[-500:] + linux.stderr
    assert windows.returncode == 0 and windows.stdout.rstrip().endswith("DONE"), \
        windows.stdout[-500:] + windows.stderr
    a = np.array(host_outputs(linux.stdout)["plant"])
    b = np.array(host_outputs(windows.stdout)["plant"])
    assert a.shape == b.shape == (n + 1, len(m.outputs)) and np.ptp(a[:, 0]) > 1.0
    scale = np.maximum(np.abs(a), 1e-300)
    worst = float(np.max(np.abs(a - b) / scale))
    ulps = int(np.max(np.abs(a.view(np.int64) - b.view(np.int64))))
    print(f"win64 under Wine against linux64: largest relative difference {worst:.3g}, {ulps} ulps at most")
    assert worst <= 1e-12
