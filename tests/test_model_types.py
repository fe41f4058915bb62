"""The FMI type and FMI version decisions, each in one place (cosim.model.types, cosim.model.description):
which variables are 64-bit floats (FMI 2.0 Real, FMI 3.0 Float64), of an integer, numeric or text kind;
which FMI versions the master runs and how the major version is read."""
from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from wmr_cosim.cosim.model.description import Variable, fmi2_cs_declares, fmi_major, fmi_of
from wmr_cosim.cosim.model.types import KINDS

COSIM = Path(__file__).resolve().parents[1] / "cosim"


def _var(fmi_type: str) -> Variable:
    return Variable("x", 1, KINDS.get(fmi_type, fmi_type), "output", "continuous", None, None, None, None,
                    fmi_type=fmi_type)


@pytest.mark.parametrize("fmi_type, f64, integer, numeric, text", [
    ("Real", True, False, True, False), ("Float64", True, False, True, False),
    ("Float32", False, False, True, False), ("Integer", False, True, True, False),
    ("Int8", False, True, True, False), ("UInt64", False, True, True, False),
    ("Enumeration", False, True, True, False), ("Boolean", False, False, False, False),
    ("String", False, False, False, True), ("Binary", False, False, False, True)])
def test_a_variables_type_tests(fmi_type, f64, integer, numeric, text):
    v = _var(fmi_type)
    assert (v.is_float64, v.is_integer, v.is_numeric, v.is_text) == (f64, integer, numeric, text)


def test_an_fmi2_variable_made_by_hand_is_a_float64_by_its_type():
    """(FMI 2.0's type is its FMI type: a Real made without one is a 64-bit float.)"""
    assert Variable("x", 1, "Real", "input", "continuous", None, None, None, 0.0).is_float64


@pytest.mark.parametrize("version, major", [("2.0", 2), ("3.0", 3), ("3.1", 3), ("3.0-beta.2", 3), ("1.0", None),
                                            ("2.0.1", None), ("2", None), ("3", None), ("4.0", None), ("?", None)])
def test_the_fmi_versions_the_master_runs(version, major):
    assert fmi_major(version) == major


def test_the_version_of_a_description_and_its_fmi2_only_capabilities():
    cs = SimpleNamespace(canInterpolateInputs=True)
    assert (fmi_of(SimpleNamespace(fmiVersion="2.0")), fmi_of(SimpleNamespace(fmiVersion="3.0"))) == (2, 3)
    assert fmi2_cs_declares(SimpleNamespace(fmiVersion="2.0", coSimulation=cs), "canInterpolateInputs")
    assert not fmi2_cs_declares(SimpleNamespace(fmiVersion="3.0", coSimulation=cs), "canInterpolateInputs")


def test_only_the_model_description_module_reads_the_fmi_version_attribute():
    """Everything else reads FmuModel.fmi (decided at load) or fmi_of: no second reading of fmiVersion."""
    readers = sorted(str(p.relative_to(COSIM)) for p in COSIM.rglob("*.py")
                     if re.search(r"\.fmiVersion\b", p.read_text(encoding="utf-8")))
    assert readers == ["model/description.py"]
