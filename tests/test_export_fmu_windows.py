"""``wmr-cosim export-fmu`` for Windows: where MinGW-w64 is on PATH and every inner FMU has a win64 binary,
the container carries ``binaries/win64/NAME.dll`` (KERNEL32 and msvcrt alone, every FMI 2.0 function), which
loads its inner FMUs' DLLs with LoadLibrary.  Our C plant alone in a container, in the project's C host on
Linux and, built for Windows, under Wine: every output within 1e-12 relative of linux64's.  Where an inner
FMU has no win64 binary the container is linux64 alone and a note says why; asked for, win64 is refused.

``pytest -m windows`` runs these with the other Windows tests; they skip, saying which package is missing,
where MinGW-w64 or Wine is not installed."""
from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

from wmr_cosim.cli import main

from cosim_support import write_document
from coupling_fmus import TwoMass, build_mass, two_mass_document
from host_tools import Model, build_c_host, host_outputs, spec_lines, system_cc
from test_windows import FMI2_FUNCTIONS, compare
from windows_support import Wine, mingw_cc, pe_exports, pe_imports, wine_session

pytestmark = pytest.mark.windows

STOP, STEP = 10.0, 0.002
N = round(STOP / STEP)
MODEL_EXCHANGE = {"fmi2EnterEventMode", "fmi2NewDiscreteStates", "fmi2EnterContinuousTimeMode",
                  "fmi2CompletedIntegratorStep", "fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives",
                  "fmi2GetEventIndicators", "fmi2GetContinuousStates", "fmi2GetNominalsOfContinuousStates"}


@pytest.fixture(scope="module")
def wine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Wine]:
    yield from wine_session(tmp_path_factory.mktemp("wine"))


@pytest.fixture(scope="module")
def container(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """WmrCPlant alone (its inputs the container's), exported with both binaries, extracted."""
    mingw_cc()
    d = tmp_path_factory.mktemp("container")
    sc = write_document(d / "plant.toml", {"instances": {"plant": {"fmu": "WmrCPlant"}},
                                           "experiment": {"stop": STOP, "step": STEP}})
    assert main(["export-fmu", str(sc), "--out", str(d / "Plant.fmu"), "--platforms", "linux64,win64"]) == 0
    with zipfile.ZipFile(d / "Plant.fmu") as zf:
        zf.extractall(d / "unzipped")
    return d / "unzipped"


def test_the_container_carries_a_win64_dll_that_needs_only_windows_itself(container: Path) -> None:
    from fmpy.validation import validate_fmu

    assert sorted(p.name for p in (container / "binaries").iterdir()) == ["linux64", "win64"]
    dll = container / "binaries" / "win64" / "plant.dll"
    assert sorted(n.lower() for n in pe_imports(dll)) == ["kernel32.dll", "msvcrt.dll"]
    assert FMI2_FUNCTIONS - MODEL_EXCHANGE <= pe_exports(dll)   # (every co-simulation function)
    assert validate_fmu(str(container)) == []


def test_the_win64_container_under_wine_steps_as_the_linux64_one(container: Path, wine: Wine,
                                                                 tmp_path: Path) -> None:
    """10 s of smooth voltages and disturbances at the plant's inputs (a table of doubles: no libm between
    the platforms), 5,000 steps of the container in the C host on each platform: every output within 1e-12
    relative (or 1e-300 absolute) of linux64's."""
    m = Model(container)
    assert len(m.inputs) == 4   # (two torques, two disturbances)
    t = np.arange(N + 1) * STEP
    table = np.column_stack([0.5 * np.sin(0.7 * t), 0.4 * np.cos(0.3 * t), 0.01 * np.sin(2.0 * t),
                             -0.01 * np.cos(1.1 * t)]).astype("<f8")
    table.tofile(tmp_path / "inputs.bin")
    lines = spec_lines(m, "one", [(0, 0, 0, 0, 0)] * len(m.inputs)) + [f"table {tmp_path / 'inputs.bin'}",
                                                                        f"steps {N} {STEP!r}"]
    spec = tmp_path / "one.spec"
    spec.write_text("\n".join(lines) + "\n")
    linux_host = build_c_host(tmp_path / "fmi_host", system_cc())
    windows_host = build_c_host(tmp_path / "fmi_host.exe", mingw_cc(), windows=True)
    linux = subprocess.run([str(linux_host), str(spec)], capture_output=True, text=True, timeout=300)
    windows = wine.run(windows_host, spec, timeout=300)
    assert linux.returncode == 0 and linux.stdout.rstrip().endswith("DONE"), linux.stdout[-500:] + linux.stderr
    assert windows.returncode == 0 and windows.stdout.rstrip().endswith("DONE"), \
        windows.stdout[-500:] + windows.stderr
    a, b = np.array(host_outputs(linux.stdout)["one"]), np.array(host_outputs(windows.stdout)["one"])
    assert a.shape == b.shape == (N + 1, len(m.outputs))
    assert np.ptp(a, axis=0).max() > 1.0
    assert compare(a, b, "the C plant's container, win64 under Wine against linux64")[0] <= 1e-12


def test_an_inner_fmu_without_win64_makes_a_linux64_container_with_a_note(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """The two-mass FMUs built here (linux64 alone): the container is linux64 alone, one note says why; with
    ``--platforms linux64,win64`` the export is refused in one line, nothing written."""
    mingw_cc()
    doc: dict[str, Any] = two_mass_document(build_mass(tmp_path), TwoMass(), stop=1.0, step=0.01)
    sc = write_document(tmp_path / "system.toml", doc)
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "S.fmu")]) == 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: note: linux64 only") and "has no binaries/win64/" in err and "\n" not in err
    assert not any(n.startswith("binaries/win64") for n in zipfile.ZipFile(tmp_path / "S.fmu").namelist())
    assert main(["export-fmu", str(sc), "--out", str(tmp_path / "W.fmu"), "--platforms", "linux64,win64"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: error: ") and "--platforms: win64 cannot be built" in err and "\n" not in err
    assert not (tmp_path / "W.fmu").exists()
