"""Bad input is rejected at construction with one line naming the parameter and the bad value."""
import dataclasses
import importlib
import math
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

from wmr_cosim import components
from wmr_cosim.components import params as P
from wmr_cosim.components.controller import ControllerParams
from wmr_cosim.components.direct_loop import run_direct
from wmr_cosim.components.plant import Plant, PlantParams
from wmr_cosim.components.sensor import Sensor, SensorParams
from wmr_cosim.components.validation import ParameterError
from wmr_cosim.fmus.fmi_decl import UNITS


@pytest.mark.parametrize("make, words", [
    (lambda: SensorParams(ppr=-500), ["ppr", "-500"]),
    (lambda: SensorParams(gear=0), ["gear", "0"]),
    (lambda: SensorParams(phase2=1.5), ["phase2", "1.5"]),
    (lambda: SensorParams(filter_form="butterworth"), ["filter_form", "butterworth"]),
    (lambda: PlantParams(a1=0.1, a2=0.0, a3=0.0), ["a1", "a2", "a3", "singular"]),
    (lambda: PlantParams(a1=0.1, a2=0.0, a3=-0.1), ["a1", "a3", "not positive definite"]),
    (lambda: ControllerParams(a1=0.02, a2=0.1, a3=-0.05), ["a1", "a2", "a3", "M"]),
    (lambda: PlantParams(cF=math.nan), ["cF", "nan"]),
    (lambda: PlantParams(a5=math.nan), ["a5", "nan"]),
    (lambda: PlantParams(substeps=0), ["substeps", "0"]),
    (lambda: PlantParams(foam_on_region=True, foam_x_min=1, foam_x_max=0, foam_y_min=0, foam_y_max=1), ["foam region"]),
    (lambda: PlantParams(foam_on_time="maybe"), ["foam_on_time", "maybe"]),
    (lambda: ControllerParams(goal_x=0.0, goal_y=0.0), ["goal", "start"]),
    (lambda: ControllerParams(gamma=math.nan), ["gamma", "nan"]),
    (lambda: ControllerParams(W_init=(0.05, math.nan, 0.05)), ["W_init[1]", "nan"]),
    (lambda: ControllerParams(P_init=(1, 0, 0, -1, 0, 1)), ["P_init", "positive definite"]),
    (lambda: ControllerParams(R=0), ["R", "0"]),
    (lambda: ControllerParams(p_norm="trace"), ["p_norm", "trace"]),
    (lambda: ControllerParams(adapt_t_start=10, adapt_t_end=5), ["adapt_t_end", "5"]),
    (lambda: ControllerParams(task="line", line_b2=2.0), ["line_b2", "2.0"]),
    (lambda: ControllerParams(h_state_cost_sign=0.5), ["h_state_cost_sign", "0.5"]),
    (lambda: run_direct(h=0.0), ["step", "0.0"]),
    (lambda: run_direct(h=math.nan), ["step", "nan"]),
    (lambda: run_direct(t_stop=-1.0), ["t_stop", "-1.0"]),
    (lambda: Sensor().step(0.0, 0.0, 0.0), ["step", "0.0"]),
])
def test_rejected_with_one_line_naming_parameter_and_value(make, words):
    with pytest.raises(ParameterError) as exc:
        make()
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_valid_unusual_inertia_parameters_are_accepted():
    # grouped parameters need not each be positive: M only has to be positive definite
    Plant(a1=0.05, a2=0.06, a3=-0.02)


def test_cli_reports_bad_parameter_in_one_line_with_exit_code_2():
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "direct", "G1", "--set", "sensor.ppr=-5"],
                       capture_output=True, text=True)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "ppr" in lines[0] and "-5" in lines[0]
    assert "Traceback" not in p.stderr
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "direct", "--set", "plant.nosuch=1"],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "nosuch" in p.stderr and "Traceback" not in p.stderr


# ---------------------------------------------------------------------------------------------------------
# One source for each parameter fact: the dataclass fields' metadata (components/params.py).  The FMUs
# declare what the dataclasses validate, so the two cannot drift apart.

PARAMS = {"plant": (PlantParams, "WmrPlant"), "sensor": (SensorParams, "WmrSensor"),
          "controller": (ControllerParams, "WmrController")}
_P_IJ = ("11", "12", "13", "22", "23", "33")
#: Refusals of a value inside its own declared range by a check that involves several parameters.
CROSS_FIELD = re.compile(r"^(plant|controller) parameters a1 = .*: M of \(35\) is"
                         r"|^plant parameter foam region "
                         r"|^controller parameter P_init = .*: must be positive definite$"
                         r"|^controller parameter adapt_t_end = .*: before adapt_t_start"
                         r"|^controller parameter goal \(goal_x, goal_y\) = "
                         r"|^controller parameter line_b2 = .*: must be after b1")
#: The parameters a bound of whose declared range such a check refuses (with the other defaults): M of (35)
#: is not positive definite at a1, a2, a3 = +-DBL_MAX, the goal is within eps_G = DBL_MAX of the start, the
#: adaptation window is empty at its start = DBL_MAX or end = -DBL_MAX, P_init is not positive definite with
#: an off-diagonal entry of +-DBL_MAX, nor (numerically: its smallest eigenvalue computes as 0) with a
#: diagonal entry of DBL_MIN beside two of 100.
CROSS_LIMITED = {("plant", "a1"), ("plant", "a2"), ("plant", "a3"), ("controller", "a1"), ("controller", "a2"),
                 ("controller", "a3"), ("controller", "eps_G"), ("controller", "adapt_t_start"),
                 ("controller", "adapt_t_end"), ("controller", "P11_init"), ("controller", "P12_init"),
                 ("controller", "P13_init"), ("controller", "P22_init"), ("controller", "P23_init"),
                 ("controller", "P33_init")}


def test_every_parameter_dataclass_of_the_components_is_covered():
    found = set()
    for m in pkgutil.iter_modules(components.__path__):
        mod = importlib.import_module(f"wmr_cosim.components.{m.name}")
        found |= {obj for name, obj in vars(mod).items()
                  if name.endswith("Params") and dataclasses.is_dataclass(obj) and obj.__module__ == mod.__name__}
    assert found == {cls for cls, _ in PARAMS.values()}


@pytest.mark.parametrize("owner", PARAMS)
def test_every_field_declares_check_unit_doc_and_tunable(owner):
    cls = PARAMS[owner][0]
    for f in dataclasses.fields(cls):
        meta, default = f.metadata, f.default
        assert isinstance(meta.get("check"), P.Check), f.name
        assert isinstance(meta.get("doc"), str) and meta["doc"].strip() and "\n" not in meta["doc"], f.name
        assert isinstance(meta.get("tunable"), bool), f.name
        real = isinstance(default, float) or (isinstance(default, tuple) and all(isinstance(x, float) for x in default))
        if real:  # a real number (or a vector of them) has a unit the FMUs know
            assert meta["unit"] in UNITS, f.name
        else:     # flags, counts and choices have none
            assert meta["unit"] is None and isinstance(default, (bool, int, str)), f.name
        # the default passes its own check unchanged
        assert meta["check"].apply(owner, f.name, default) == default, f.name
        # every allowed value of a choice, a sign or a power is named in the meaning
        for v in meta["check"].values:
            text = {1.0: "+1", -1.0: "-1"}.get(v, str(v)) if meta["check"].kind == "sign" else str(v)
            assert text in meta["doc"], (f.name, v)
    cls()  # and the defaults pass the cross-field checks


def _declared_parameters():
    """(owner, FMU variable name, field name, element index or None) of every declared parameter."""
    out = []
    for owner, (cls, _) in PARAMS.items():
        for f in dataclasses.fields(cls):
            if f.name == "W_init":
                out += [(owner, f"W{i + 1}_init", f.name, i) for i in range(3)]
            elif f.name == "P_init":
                out += [(owner, f"P{ij}_init", f.name, k) for k, ij in enumerate(_P_IJ)]
            else:
                out.append((owner, f.name, f.name, None))
    return out


@pytest.fixture(scope="module")
def declared(built_fmus):
    """{owner: {variable name: model variable}} of the built FMUs' model descriptions."""
    from fmpy import read_model_description

    return {owner: {v.name: v for v in read_model_description(str(built_fmus[model])).modelVariables}
            for owner, (_, model) in PARAMS.items()}


def _value(owner, field, index, value):
    """``value`` for the field, or the default vector with element ``index`` set to it."""
    if index is None:
        return value
    vec = list(getattr(PARAMS[owner][0](), field))
    vec[index] = value
    return tuple(vec)


def _make(owner, field, index, value):
    """The dataclass with one parameter (or one element of a vector parameter) set to ``value``."""
    value = _value(owner, field, index, value)
    return PARAMS[owner][0](**{field: value}), value


@pytest.mark.parametrize("owner, name, field, index", _declared_parameters())
def test_declared_range_is_what_validation_accepts(declared, owner, name, field, index):
    """A value just outside the FMU's declared [min, max] is refused with one line naming the parameter;
    the bounds themselves (or the values of a sign or a power) are accepted by the parameter's check,
    and by the dataclass unless a check involving several parameters refuses them."""
    cls = PARAMS[owner][0]
    var = declared[owner][name]
    meta = cls.__dataclass_fields__[field].metadata
    check = meta["check"]
    if index is None:
        assert var.description == meta["doc"]
    assert var.variability == ("tunable" if meta["tunable"] else "fixed")
    if var.type not in ("Real", "Integer"):
        assert var.min is None and var.max is None
        return
    assert var.unit == (meta["unit"] if var.type == "Real" else None)
    integer = var.type == "Integer"
    num = int if integer else float
    lo = None if var.min is None else num(var.min)
    hi = None if var.max is None else num(var.max)
    assert lo is not None  # every Real and Integer parameter is bounded below
    inside, outside = [], []
    if check.values and not isinstance(check.values[0], str):
        inside += list(check.values)
        assert (lo, hi) == (min(check.values), max(check.values))
    else:
        inside.append(lo)
        inside.append(math.inf if hi is None else math.nextafter(hi, -math.inf) if check.hi_open else hi)
    if integer:
        outside += [lo - 1, hi + 1]
    else:
        # min = DBL_MIN encodes "> 0" (the subnormals below it are positive too): 0 is the value just outside
        outside.append(0.0 if lo == sys.float_info.min else math.nextafter(lo, -math.inf))
        if hi is not None:
            outside.append(hi if check.hi_open else math.nextafter(hi, math.inf))
    for v in outside:
        with pytest.raises(ParameterError) as exc:
            _make(owner, field, index, v)
        msg = str(exc.value)
        assert "\n" not in msg
        if index is None:
            assert msg.startswith(f"{owner} parameter {name} = {v!r}: "), msg
        else:
            assert msg.startswith(f"{owner} parameter {field}"), msg
            assert repr(v) in msg, msg
    for v in inside:
        value = _value(owner, field, index, v)
        assert check.apply(owner, field, value) == value, (name, v)
        try:
            obj, value = _make(owner, field, index, v)
        except ParameterError as e:
            assert (owner, name) in CROSS_LIMITED and CROSS_FIELD.search(str(e)), str(e)
        else:
            assert getattr(obj, field) == value


@pytest.mark.parametrize("owner", PARAMS)
def test_choices_and_flags_refuse_other_values_in_one_line(owner):
    cls = PARAMS[owner][0]
    for f in dataclasses.fields(cls):
        check = f.metadata["check"]
        if check.kind == "choice":
            bad = "no_such_" + f.name
            with pytest.raises(ParameterError) as exc:
                cls(**{f.name: bad})
            assert str(exc.value) == (f"{owner} parameter {f.name} = {bad!r}: must be one of "
                                      f"{', '.join(check.values)}")
            for v in check.values:
                assert check.apply(owner, f.name, v) == v
        elif check.kind == "boolean":
            with pytest.raises(ParameterError) as exc:
                cls(**{f.name: 2})
            assert str(exc.value) == f"{owner} parameter {f.name} = 2: must be true or false"


def test_components_import_no_fmi_code():
    root = Path(components.__file__).resolve().parent
    for py in root.glob("*.py"):
        src = py.read_text(encoding="utf-8")
        assert not re.search(r"^\s*(from|import)\s+(pythonfmu|pythonfmu3|fmpy|wmr_cosim|\.\.)", src, re.MULTILINE), py.name


def test_as_dict_gives_every_parameter_and_rebuilds_an_equal_instance():
    from wmr_cosim.components.controller import ControllerParams
    from wmr_cosim.components.plant import PlantParams
    from wmr_cosim.components.sensor import SensorParams

    for cls, change in ((PlantParams, {"a5": 0.7}), (SensorParams, {"noise_std": 0.1}),
                        (ControllerParams, {"gamma": 9.0})):
        p = cls(**change)
        d = p.as_dict()
        assert set(d) == {f.name for f in dataclasses.fields(cls)}
        assert all(d[k] == v for k, v in change.items())
        assert cls(**d) == p and cls(**d) != cls()
