"""Build the C test FMU (tests/c_fmus/probe.c) with a chosen behaviour (not a test module): compiled with the
system C compiler against the FMI 2.0 headers FMPy ships, zipped with its model description."""
from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent / "c_fmus" / "probe.c"

MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{{probe-{name}}}" generationTool="wmr-cosim tests"
  variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true"/>
  <LogCategories>
    <Category name="logAll"/>
    <Category name="logStatusError"/>
  </LogCategories>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01"/>
  <ModelVariables>
    <ScalarVariable name="p" valueReference="0" causality="parameter" variability="fixed" initial="exact"><Real start="1" min="0" max="10"/></ScalarVariable>
    <ScalarVariable name="u" valueReference="1" causality="input"><Real start="0" unit="m"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="2" causality="output"><Real unit="m"/></ScalarVariable>
    <ScalarVariable name="c" valueReference="3" causality="local" initial="exact"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="b" valueReference="4" causality="input" variability="discrete"><Boolean start="false"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="5" causality="output" variability="discrete"><Integer/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="3" dependencies="2"/><Unknown index="6" dependencies=""/></Outputs>
    <InitialUnknowns><Unknown index="3" dependencies="1 2"/><Unknown index="6" dependencies=""/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def build_probe(out: Path, name: str = "Probe", **defines: object) -> Path:
    """``out/<name>.fmu`` compiled with ``-D<KEY>=<value>`` for each define (True: no value)."""
    return build_c_fmu(SRC, MODEL_DESCRIPTION.format(name=name), out, name, **defines)


def build_c_fmu(src: Path, model_description: str, out: Path, name: str, **defines: object) -> Path:
    """``out/<name>.fmu``: the C source ``src`` compiled with ``-D<KEY>=<value>`` for each define (True: no
    value) into ``binaries/linux64/<name>.so``, beside ``model_description``."""
    import fmpy

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    out.mkdir(parents=True, exist_ok=True)
    so = out / f"{name}.so"
    flags = [f"-D{k}" if v is True else f"-D{k}={v}" for k, v in defines.items()]
    inc = Path(fmpy.__file__).parent / "c-code"
    p = subprocess.run([cc, "-shared", "-fPIC", "-O1", f"-I{inc}", *flags, str(src), "-o", str(so), "-lm"],
                       capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(p.stderr)
    fmu = out / f"{name}.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        zf.writestr("modelDescription.xml", model_description)
        zf.write(so, f"binaries/linux64/{name}.so")
    so.unlink()
    return fmu
