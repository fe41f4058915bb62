"""The C test FMUs of linearisation (tests/c_fmus/lag.c), built with their model descriptions (not a test
module): a first-order lag and a static gain, each with a Model Exchange and a Co-Simulation interface.

* Lag: x' = (k u - x) / tau, y = x (no direct feedthrough), x(start) = x0; u, y, x, k, x0 [1], tau [s].
* Gain: y = kp u + y0 (direct feedthrough); u, y, kp, y0 [1].

The value references (the same in every build) are in ``LAG_VR`` and ``GAIN_VR``; lag.c's header says
what each interface computes.
"""
from __future__ import annotations

from pathlib import Path

from c_fmu_support import build_c_fmu

SRC = Path(__file__).resolve().parent / "c_fmus" / "lag.c"

#: name: value reference.
LAG_VR = {"u": 0, "y": 1, "x": 2, "der(x)": 3, "k": 10, "tau": 11, "x0": 12}
GAIN_VR = {"u": 0, "y": 1, "kp": 10, "y0": 11}

# (name, vr, causality, unit, start); the model description lists them in this order (its indices: 1, 2, ...)
_LAG_VARIABLES = [("u", 0, "input", "", 0.0), ("y", 1, "output", "", None), ("x", 2, "local", "", None),
                  ("der(x)", 3, "local", "1/s", None), ("k", 10, "parameter", "", 1.0),
                  ("tau", 11, "parameter", "s", 1.0), ("x0", 12, "parameter", "", 0.0)]
_GAIN_VARIABLES = [("u", 0, "input", "", 0.0), ("y", 1, "output", "", None), ("kp", 10, "parameter", "", 1.0),
                   ("y0", 11, "parameter", "", 0.0)]

# ModelStructure by variable name: Outputs (and Derivatives) on the inputs and states they depend on;
# InitialUnknowns on the inputs and exact-start variables (parameters) they are computed from.
_LAG_STRUCTURE = {"outputs": {"y": ["x"]}, "derivatives": {"der(x)": ["u", "x"]},
                  "initial": {"y": ["x0"], "x": ["x0"], "der(x)": ["u", "k", "tau", "x0"]}}
_GAIN_STRUCTURE = {"outputs": {"y": ["u"]}, "derivatives": {},
                   "initial": {"y": ["u", "kp", "y0"]}}


def default_name(*, gain: bool = False, directional: bool = False, fmu_state: bool = True) -> str:
    """The build's default name: "Lag" or "Gain", then "Directional" if it gives directional derivatives
    and "NoFmuState" if it cannot get and set its state: each variant its own, so that several can share a
    folder."""
    return "".join(("Gain" if gain else "Lag", "Directional" if directional else "",
                    "" if fmu_state else "NoFmuState"))


def build_lag(out: Path, *, gain: bool = False, directional: bool = False, fmu_state: bool = True,
              name: str | None = None) -> Path:
    """``out/<name>.fmu``: the Lag (or, ``gain``, the Gain), with Model Exchange and Co-Simulation under the
    one modelIdentifier ``name`` (default: ``default_name``); ``directional``: fmi2GetDirectionalDerivative
    works and is declared (-DDIRECTIONAL); not ``fmu_state``: fmi2GetFMUstate and fmi2SetFMUstate return
    fmi2Error and canGetAndSetFMUstate is false (-DNO_FMU_STATE)."""
    name = name or default_name(gain=gain, directional=directional, fmu_state=fmu_state)
    defines: dict[str, object] = {}
    if gain:
        defines["GAIN"] = True
    if directional:
        defines["DIRECTIONAL"] = True
    if not fmu_state:
        defines["NO_FMU_STATE"] = True
    md = model_description(name, gain=gain, directional=directional, fmu_state=fmu_state)
    return build_c_fmu(SRC, md, out, name, **defines)


def model_description(name: str, *, gain: bool = False, directional: bool = False, fmu_state: bool = True) -> str:
    """The modelDescription.xml of a build of lag.c (see ``build_lag``)."""
    variables = _GAIN_VARIABLES if gain else _LAG_VARIABLES
    structure = _GAIN_STRUCTURE if gain else _LAG_STRUCTURE
    index = {v[0]: i + 1 for i, v in enumerate(variables)}
    caps = (f' canGetAndSetFMUstate="{"true" if fmu_state else "false"}"'
            + (' providesDirectionalDerivative="true"' if directional else ""))
    base = {"s": 's="1"', "1/s": 's="-1"'}
    used = dict.fromkeys(v[3] for v in variables if v[3])
    units = ("  <UnitDefinitions>\n" + "".join(f'    <Unit name="{u}"><BaseUnit {base[u]}/></Unit>\n' for u in used)
             + "  </UnitDefinitions>\n") if used else ""

    def var(n: str, vr: int, causality: str, unit: str, start: float | None) -> str:
        attrs = (f' unit="{unit}"' if unit else "") + ("" if start is None else f' start="{start!r}"')
        if n == "der(x)":
            attrs += f' derivative="{index["x"]}"'
        if causality == "parameter":
            kind = ' variability="fixed" initial="exact"'
        elif causality == "input":
            kind = ' variability="continuous"'
        else:   # the output and the Lag's state and derivative: computed from the parameters at the start
            kind = ' variability="continuous" initial="calculated"'
        return (f'    <ScalarVariable name="{n}" valueReference="{vr}" causality="{causality}"{kind}>'
                f"<Real{attrs}/></ScalarVariable>\n")

    def unknowns(deps: dict[str, list[str]]) -> str:
        return "".join(f'<Unknown index="{index[o]}" dependencies="{" ".join(str(index[d]) for d in ds)}"/>'
                       for o, ds in sorted(deps.items(), key=lambda kv: index[kv[0]]))

    derivatives = (f"    <Derivatives>{unknowns(structure['derivatives'])}</Derivatives>\n"
                   if structure["derivatives"] else "")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{{linear-{name}}}" generationTool="wmr-cosim tests"
  variableNamingConvention="structured" numberOfEventIndicators="0">
  <ModelExchange modelIdentifier="{name}" completedIntegratorStepNotNeeded="true"{caps}/>
  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true"{caps}/>
{units}  <LogCategories><Category name="logEvents"/><Category name="logStatusError"/></LogCategories>
  <DefaultExperiment startTime="0" stopTime="5" stepSize="0.01"/>
  <ModelVariables>
{"".join(var(*v) for v in variables)}  </ModelVariables>
  <ModelStructure>
    <Outputs>{unknowns(structure["outputs"])}</Outputs>
{derivatives}    <InitialUnknowns>{unknowns(structure["initial"])}</InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""

def lag_response(t, *, u: float = 0.0, k: float = 1.0, tau: float = 1.0, x0: float = 0.0):
    """y(t) [1] of the Lag from x0 at t = 0 under a constant input u: k u + (x0 - k u) exp(-t / tau), at
    each time t [s] (a float or an array)."""
    import numpy as np

    return k * u + (x0 - k * u) * np.exp(-np.asarray(t, dtype=float) / tau)
