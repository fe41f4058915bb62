"""Connections between variables whose units have an offset (degC, degF against K), with the scenario's
factor and offset: the value that arrives at the input during a run, row by row, against a hand
calculation, in both directions (``to = factor * convert(from) + offset``, the unit conversion first:
cosim.model.units.conversion folded with the factor and offset by cosim.plan.resolution into ConnectionPlan.factor and
.offset, applied by the generated loop (Float64 -> Float64) or by cosim.plan.wiring's converting copy (Float64
<-> Float32)); a bias on the source output (in its units: a difference, scaled, never offset) and one on
the input (in the input's units, added as it is).

The source is the C test FMU affine.c (y = b0 + b1 t = 20 + 10 t here), the destination another (its input
u read back as it was set), their units declared in UnitDefinitions (degF: K = 5/9 degF + 255.372...)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from c_fmu_support import build_c_fmu
from coupling_fmus import C_FMUS
from reference_fmus import REF
from wmr_cosim import cosim

UNITS = """  <UnitDefinitions>
    <Unit name="K"><BaseUnit K="1"/></Unit>
    <Unit name="degC"><BaseUnit K="1" offset="273.15"/></Unit>
    <Unit name="degF"><BaseUnit K="1" factor="0.5555555555555556" offset="255.3722222222222"/></Unit>
  </UnitDefinitions>
"""

THERMO = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{{coupling-{name}}}" generationTool="wmr-cosim tests"
  variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true"/>
{units}  <LogCategories><Category name="logStatusError"/></LogCategories>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input"><Real unit="{unit}" start="0.0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="1" causality="output"><Real unit="{unit}"/></ScalarVariable>
    <ScalarVariable name="a" valueReference="10" causality="parameter" variability="fixed" initial="exact"><Real start="1.0"/></ScalarVariable>
    <ScalarVariable name="b0" valueReference="11" causality="parameter" variability="fixed" initial="exact"><Real unit="{unit}" start="0.0"/></ScalarVariable>
    <ScalarVariable name="b1" valueReference="12" causality="parameter" variability="fixed" initial="exact"><Real start="0.0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="2" dependencies="1"/></Outputs>
    <InitialUnknowns><Unknown index="2" dependencies="1"/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""

STEP, STOP = 0.01, 0.2
B0, B1 = 20.0, 10.0          # the source's output: 20 + 10 t, in its own unit


def source(t: np.ndarray) -> np.ndarray:
    return B0 + B1 * t


def to_k(unit: str, v: Any) -> Any:
    """A temperature in K by hand: degC + 273.15; (degF + 459.67) 5/9."""
    return {"K": v, "degC": v + 273.15, "degF": (v + 459.67) * 5.0 / 9.0}[unit]


def from_k(unit: str, v: Any) -> Any:
    return {"K": v, "degC": v - 273.15, "degF": v * 9.0 / 5.0 - 459.67}[unit]


@pytest.fixture(scope="module")
def thermo(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """affine.c with its input, output and b0 in each unit: {unit: FMU}."""
    out = tmp_path_factory.mktemp("thermo")
    return {u: build_c_fmu(C_FMUS / "affine.c", THERMO.format(name=f"Thermo_{u}", units=UNITS, unit=u), out,
                           f"Thermo_{u}") for u in ("K", "degC", "degF")}


def _document(src: Path, dst: Path, connection: dict[str, Any], events: list[dict[str, Any]] = ()) -> dict[str, Any]:
    return {"experiment": {"start": 0.0, "stop": STOP, "step": STEP},
            "instances": {"src": {"fmu": str(src), "parameters": {"a": 0.0, "b0": B0, "b1": B1}},
                          "dst": {"fmu": str(dst)}},
            "connections": [{"from": "src.y", "to": "dst.u", **connection}], "events": list(events),
            "record": {"variables": ["src.y", "dst.u"]}}


def _run(doc: dict[str, Any], out: Path) -> tuple[cosim.Plan, np.ndarray]:
    plan = cosim.resolve(cosim.parse(doc, "units.toml"))
    res = cosim.run(plan, out, progress=False)
    assert res.status == "ok", res.message
    return plan, np.load(out / "signals.npy")


# (from, to, factor, offset, the value at the input by hand, the folded factor and offset by hand)
CASES: list[tuple[str, str, float, float, Callable[[Any], Any], tuple[float, float]]] = [
    ("degC", "K", 2.0, 1.0, lambda v: 2.0 * (v + 273.15) + 1.0, (2.0, 547.3)),
    ("K", "degC", 2.0, 1.0, lambda v: 2.0 * (v - 273.15) + 1.0, (2.0, -545.3)),
    ("degF", "degC", 0.5, -3.0, lambda v: 0.5 * (v - 32.0) * 5.0 / 9.0 - 3.0, (5.0 / 18.0, -3.0 - 80.0 / 9.0)),
    ("degC", "degF", 0.5, -3.0, lambda v: 0.5 * (v * 1.8 + 32.0) - 3.0, (0.9, 13.0)),
    ("degF", "K", 1.0, 0.0, lambda v: (v + 459.67) * 5.0 / 9.0, (5.0 / 9.0, 459.67 * 5.0 / 9.0)),
    ("K", "degF", 3.0, 0.0, lambda v: 3.0 * (v * 1.8 - 459.67), (5.4, -1379.01)),
    ("degC", "degC", 2.0, 1.0, lambda v: 2.0 * v + 1.0, (2.0, 1.0)),
]


@pytest.mark.parametrize("src, dst, factor, offset, by_hand, folded", CASES,
                         ids=[f"{c[0]}-to-{c[1]}" for c in CASES])
def test_the_value_at_the_input_is_the_unit_conversion_then_the_factor_and_offset(thermo, tmp_path, src, dst, factor,
                                                                                  offset, by_hand, folded):
    plan, rows = _run(_document(thermo[src], thermo[dst], {"factor": factor, "offset": offset}), tmp_path / "out")
    (c,) = plan.connections
    assert (c.factor, c.offset) == pytest.approx(folded, rel=1e-14, abs=1e-12)
    t = np.arange(len(rows)) * STEP
    assert len(rows) == 21 and rows["time"] == pytest.approx(t, abs=1e-12)
    np.testing.assert_array_equal(rows["src.y"], source(rows["time"]))
    # every row, the initialised one first: the input got the hand-converted source value
    np.testing.assert_allclose(rows["dst.u"], by_hand(source(rows["time"])), rtol=1e-13, atol=1e-11)
    assert rows["dst.u"][0] == pytest.approx(by_hand(B0), rel=1e-14)


@pytest.mark.parametrize("src, dst", [("degC", "degF"), ("degF", "K")])
def test_a_bias_on_the_output_is_a_difference_in_its_unit_and_one_on_the_input_is_in_the_inputs(thermo, tmp_path,
                                                                                                 src, dst):
    """A bias of 1 on src.y (in src's unit) from 0.05 s changes the input by factor * 1 * (the units'
    ratio), never by an offset; a bias of 0.25 on dst.u (in dst's unit) from 0.1 s adds 0.25 on top of it.
    (A row at t holds the input set for the step that ended there: an event at 0.05 s shows from 0.06 s.)"""
    events = [{"time": 0.05, "variable": "src.y", "action": "bias", "value": 1.0},
              {"time": 0.1, "variable": "dst.u", "action": "bias", "value": 0.25}]
    _, rows = _run(_document(thermo[src], thermo[dst], {"factor": 0.5, "offset": -3.0}, events), tmp_path / "out")
    t = rows["time"]
    biased_src = source(t) + np.where(t > 0.05 + 1e-9, 1.0, 0.0)
    want = 0.5 * from_k(dst, to_k(src, biased_src)) - 3.0 + np.where(t > 0.1 + 1e-9, 0.25, 0.0)
    np.testing.assert_allclose(rows["dst.u"], want, rtol=1e-13, atol=1e-11)
    ratio = {("degC", "degF"): 1.8, ("degF", "K"): 5.0 / 9.0}[(src, dst)]
    k = int(round(0.06 / STEP))
    assert rows["dst.u"][k] - (0.5 * from_k(dst, to_k(src, source(t[k]))) - 3.0) == pytest.approx(0.5 * ratio, abs=1e-11)
    assert rows["dst.u"][k - 1] == pytest.approx(0.5 * from_k(dst, to_k(src, source(t[k - 1]))) - 3.0, abs=1e-11)


def test_a_bias_on_the_input_adds_to_an_override_of_its_source_output(thermo, tmp_path):
    """An override of src.y reaches dst.u as it is (no conversion: the value the input receives), a new
    value of it too, and a bias on dst.u adds to it; an override of dst.u replaces both."""
    events = [{"time": 0.05, "variable": "src.y", "action": "override", "value": 300.0},
              {"time": 0.08, "variable": "src.y", "action": "override", "value": 310.0},
              {"time": 0.1, "variable": "dst.u", "action": "bias", "value": 0.25},
              {"time": 0.15, "variable": "dst.u", "action": "override", "value": -7.0}]
    _, rows = _run(_document(thermo["degC"], thermo["K"], {"factor": 2.0, "offset": 1.0}, events), tmp_path / "out")
    t = rows["time"]
    overridden = np.where(t > 0.08 + 1e-9, 310.0, 300.0)
    want = np.where(t > 0.05 + 1e-9, overridden, 2.0 * (source(t) + 273.15) + 1.0) + np.where(t > 0.1 + 1e-9, 0.25, 0.0)
    want = np.where(t > 0.15 + 1e-9, -7.0, want)
    np.testing.assert_allclose(rows["dst.u"], want, rtol=1e-13, atol=1e-11)


def _feedthrough_in(unit: str, out: Path) -> Path:
    """The Reference FMU Feedthrough (FMI 3.0) with its Float32 continuous input and output in ``unit``."""
    import zipfile

    fmu = out / "Feedthrough.fmu"
    with zipfile.ZipFile(REF / "fmi3" / "Feedthrough.fmu") as zi, zipfile.ZipFile(fmu, "w") as zo:
        for info in zi.infolist():
            data = zi.read(info)
            if info.filename == "modelDescription.xml":
                text = data.decode()
                text = text.replace("  <TypeDefinitions>", UNITS + "  <TypeDefinitions>", 1)
                for name in ("Float32_continuous_input", "Float32_continuous_output"):
                    text = text.replace(f'name="{name}"', f'name="{name}" unit="{unit}"', 1)
                data = text.encode()
            zo.writestr(info, data)
    return fmu


def test_float32_ends_convert_units_through_the_factor_and_offset(thermo, tmp_path):
    """src.y [degC] -> ft.Float32_continuous_input [K] (factor 2, offset 1), ft.Float32_continuous_output [K]
    -> dst.u [degF] (factor 0.5, offset -3): both through the converting copy (another width), the Float32
    value the Float64 one rounded."""
    doc = _document(thermo["degC"], thermo["degF"], {})
    doc["instances"] = {"src": doc["instances"]["src"], "ft": {"fmu": str(_feedthrough_in("K", tmp_path))},
                        "dst": doc["instances"]["dst"]}     # (in this order: each sees this step's values)
    doc["connections"] = [
        {"from": "src.y", "to": "ft.Float32_continuous_input", "factor": 2.0, "offset": 1.0},
        {"from": "ft.Float32_continuous_output", "to": "dst.u", "factor": 0.5, "offset": -3.0}]
    doc["record"]["variables"] += ["ft.Float32_continuous_input", "ft.Float32_continuous_output"]
    plan, rows = _run(doc, tmp_path / "out")
    assert [x for c in plan.connections for x in (c.factor, c.offset)] == pytest.approx([2.0, 547.3, 0.9, -232.835],
                                                                                         abs=1e-12)
    k_in = np.float32(2.0 * (source(rows["time"]) + 273.15) + 1.0)
    np.testing.assert_array_equal(rows["ft.Float32_continuous_input"], k_in)
    np.testing.assert_array_equal(rows["ft.Float32_continuous_output"], k_in)
    np.testing.assert_allclose(rows["dst.u"], 0.5 * (k_in.astype(float) * 1.8 - 459.67) - 3.0, rtol=1e-13, atol=1e-11)
