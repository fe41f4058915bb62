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


# ---------------------------------------------------------------------------------------------- Ramp
#: The Ramp model (tests/c_fmus/ramp/: x' = s from x = 0, x its event indicator; a reset and an end of the
#: simulation at time events), on the Reference FMUs' common code.
RAMP = Path(__file__).resolve().parent / "c_fmus" / "ramp"
REFERENCE_COMMON = Path(__file__).resolve().parent / "data" / "reference-fmus" / "common"
RAMP_TOKEN = "{6b0c7a52-4a5e-4f1c-9c1e-52a3c7d0ramp}"
RAMP_PARAMETERS = (("s", 3, 1.0), ("T_reset", 4, -1.0), ("s_after", 5, 1.0), ("T_stop", 6, 1e300))

RAMP_FMI3 = f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Ramp" generationTool="wmr-cosim tests" instantiationToken="{RAMP_TOKEN}">
  <ModelExchange modelIdentifier="Ramp"/>
  <CoSimulation modelIdentifier="Ramp" canHandleVariableCommunicationStepSize="true" fixedInternalStepSize="1e-3"/>
  <LogCategories><Category name="logEvents"/><Category name="logStatusError"/></LogCategories>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="x" valueReference="1" causality="output" variability="continuous" initial="exact" start="0"/>
    <Float64 name="der(x)" valueReference="2" causality="local" variability="continuous" initial="calculated" derivative="1"/>
{"".join(f'    <Float64 name="{n}" valueReference="{vr}" causality="parameter" variability="fixed" initial="exact" start="{v!r}"/>{chr(10)}' for n, vr, v in RAMP_PARAMETERS)}    <Float64 name="crossings" valueReference="7" causality="output" variability="discrete" initial="calculated"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="1" dependencies=""/>
    <Output valueReference="7" dependencies=""/>
    <ContinuousStateDerivative valueReference="2" dependencies=""/>
    <InitialUnknown valueReference="2" dependencies=""/>
    <InitialUnknown valueReference="7" dependencies=""/>
    <EventIndicator valueReference="1" dependencies=""/>
  </ModelStructure>
</fmiModelDescription>
"""

RAMP_FMI2 = f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Ramp" guid="{RAMP_TOKEN}" generationTool="wmr-cosim tests"
  variableNamingConvention="structured" numberOfEventIndicators="1">
  <ModelExchange modelIdentifier="Ramp"/>
  <CoSimulation modelIdentifier="Ramp" canHandleVariableCommunicationStepSize="true"/>
  <LogCategories><Category name="logEvents"/><Category name="logStatusError"/></LogCategories>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01"/>
  <ModelVariables>
    <ScalarVariable name="time" valueReference="0" causality="independent" variability="continuous"><Real/></ScalarVariable>
    <ScalarVariable name="x" valueReference="1" causality="output" variability="continuous" initial="exact"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="der(x)" valueReference="2" causality="local" variability="continuous" initial="calculated"><Real derivative="2"/></ScalarVariable>
{"".join(f'    <ScalarVariable name="{n}" valueReference="{vr}" causality="parameter" variability="fixed" initial="exact"><Real start="{v!r}"/></ScalarVariable>{chr(10)}' for n, vr, v in RAMP_PARAMETERS)}    <ScalarVariable name="crossings" valueReference="7" causality="output" variability="discrete" initial="calculated"><Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="2" dependencies=""/><Unknown index="8" dependencies=""/></Outputs>
    <Derivatives><Unknown index="3" dependencies=""/></Derivatives>
    <InitialUnknowns><Unknown index="3" dependencies=""/><Unknown index="8" dependencies=""/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def build_ramp(out: Path, version: int) -> Path:
    """``out/fmi<version>/Ramp.fmu`` (version 2 or 3, co-simulation and model exchange): tests/c_fmus/ramp/
    compiled with the Reference FMUs' common code against the FMI headers FMPy ships."""
    import fmpy

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    folder = out / f"fmi{version}"
    folder.mkdir(parents=True, exist_ok=True)
    so = folder / "Ramp.so"
    sources = [RAMP / "model.c", REFERENCE_COMMON / "cosimulation.c", REFERENCE_COMMON / f"fmi{version}Functions.c"]
    flags = [f"-DFMI_VERSION={version}", "-DDISABLE_PREFIX", f"-I{Path(fmpy.__file__).parent / 'c-code'}",
             f"-I{RAMP}", f"-I{REFERENCE_COMMON}"]
    p = subprocess.run([cc, "-shared", "-fPIC", "-O1", *flags, *map(str, sources), "-o", str(so), "-lm"],
                       capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(p.stderr)
    fmu = folder / "Ramp.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        zf.writestr("modelDescription.xml", RAMP_FMI3 if version == 3 else RAMP_FMI2)
        zf.write(so, f"binaries/{'x86_64-linux' if version == 3 else 'linux64'}/Ramp.so")
    so.unlink()
    return fmu


# -------------------------------------------------------------------------------------------- Ticker
#: The Ticker model (tests/c_fmus/ticker/: an input clock r, periodic, whose ticks n counts; a triggered
#: input clock s with its clocked input u and output y = 2 u; an output clock o raised at every
#: ``every``-th tick of r, whose rises m counts), on the Reference FMUs' common code, FMI 3.0.
TICKER = Path(__file__).resolve().parent / "c_fmus" / "ticker"
TICKER_TOKEN = "{3f6a2b1c-0d4e-4c8a-9b7e-5a1d2c3eticker}"

TICKER_FMI3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Ticker" generationTool="wmr-cosim tests" instantiationToken="{token}">
  <ModelExchange modelIdentifier="Ticker"/>
  <CoSimulation modelIdentifier="Ticker" canHandleVariableCommunicationStepSize="true" fixedInternalStepSize="1e-4"
    hasEventMode="{event_mode}"/>
  <LogCategories><Category name="logEvents"/><Category name="logStatusError"/></LogCategories>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.0005"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Clock name="r" valueReference="1" causality="input" intervalVariability="{variability}"{interval}/>
    <Clock name="s" valueReference="2" causality="input" intervalVariability="triggered"/>
    <Clock name="o" valueReference="3" causality="output" intervalVariability="triggered"/>
    <Float64 name="n" valueReference="4" causality="output" variability="discrete" clocks="1" initial="exact" start="0"/>
    <Float64 name="u" valueReference="5" causality="input" variability="discrete" clocks="2" start="0"/>
    <Float64 name="y" valueReference="6" causality="output" variability="discrete" clocks="2" initial="exact" start="0"/>
    <Float64 name="m" valueReference="7" causality="output" variability="discrete" clocks="3" initial="exact" start="0"/>
    <Float64 name="every" valueReference="8" causality="parameter" variability="fixed" start="3"/>
    <Float64 name="t_o" valueReference="9" causality="parameter" variability="fixed" start="-1"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="3"/>
    <Output valueReference="4"/>
    <Output valueReference="6"/>
    <Output valueReference="7"/>
  </ModelStructure>
</fmiModelDescription>
"""


def ticker_bytes(interval: str = "0.002", variability: str = "constant", event_mode: bool = True) -> bytes:
    """The Ticker FMU's bytes, its clock r of ``variability`` with ``interval`` [s] ("": none declared),
    ``hasEventMode`` as ``event_mode`` (built in a temporary folder, removed after)."""
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="ticker-"))
    try:
        return build_ticker(tmp, interval, variability, event_mode).read_bytes()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def build_ticker(out: Path, interval: str = "0.002", variability: str = "constant", event_mode: bool = True) -> Path:
    """``out/Ticker.fmu`` (FMI 3.0 co-simulation and model exchange): tests/c_fmus/ticker/ compiled with the
    Reference FMUs' common code against the FMI headers FMPy ships (see :func:`ticker_bytes`)."""
    import fmpy

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    out.mkdir(parents=True, exist_ok=True)
    so = out / "Ticker.so"
    sources = [TICKER / "model.c", REFERENCE_COMMON / "cosimulation.c", REFERENCE_COMMON / "fmi3Functions.c"]
    flags = ["-DFMI_VERSION=3", "-DDISABLE_PREFIX", f"-I{Path(fmpy.__file__).parent / 'c-code'}", f"-I{TICKER}",
             f"-I{REFERENCE_COMMON}"]
    p = subprocess.run([cc, "-shared", "-fPIC", "-O1", *flags, *map(str, sources), "-o", str(so), "-lm"],
                       capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(p.stderr)
    fmu = out / "Ticker.fmu"
    md = TICKER_FMI3.format(token=TICKER_TOKEN, variability=variability, event_mode=str(event_mode).lower(),
                            interval=f' intervalDecimal="{interval}"' if interval else "")
    with zipfile.ZipFile(fmu, "w") as zf:
        zf.writestr("modelDescription.xml", md)
        zf.write(so, "binaries/x86_64-linux/Ticker.so")
    so.unlink()
    return fmu


def ticker_scenario(fmu: Path | str, interface: str = "co-simulation", extra: str = "", step: str = "0.0005",
                     a: str = 'clock_ticks = { s = [0.001] }', order: str = "", record: str = "") -> str:
    """Two Tickers through ``interface``: A's output clock o ticks B's input clock s, A's m (clocked by o)
    feeds B's u (clocked by s); A's s ticked by ``a``'s clock_ticks; ``extra`` before the record; ``order``
    in the experiment; ``record`` more keys of the record."""
    return f'''[experiment]
stop = 0.02
step = {step}
{order}
[instances.A]
fmu = "{fmu}"
interface = "{interface}"
{a}
[instances.B]
fmu = "{fmu}"
interface = "{interface}"
[[connections]]
from = "A.o"
to = "B.s"
[[connections]]
from = "A.m"
to = "B.u"
{extra}
[record]
variables = ["A.n", "A.m", "B.n", "B.y", "B.u"]
{record}
'''
