"""The C test FMUs of linearisation (tests/c_fmus/lag.c, built by tests/linear_fmus.py) are right, under FMPy
alone: the Lag against its analytic response in Model Exchange (CVode) and Co-Simulation (exact steps),
the Gain's direct feedthrough, the FMU state, the directional derivatives, the builds without them, and
the state machine (fixed parameters, tau > 0, terminate, reset, logging)."""
from __future__ import annotations

import contextlib
import shutil
import subprocess
from ctypes import POINTER, byref, c_double, c_int, c_void_p
from pathlib import Path

import numpy as np
import pytest
from fmpy import calloc, extract, free, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Model, FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Real)
from fmpy.logging import addLoggerProxy
from fmpy.validation import validate_fmu

from linear_fmus import GAIN_VR, LAG_VR, SRC, build_lag, default_name, lag_response

#: The Lag's parameters in the tests: neither 1 nor 0, so that a k, tau or x0 left out or misplaced shows.
LAG = {"k": 2.5, "tau": 0.4, "x0": -1.0}
GAIN = {"kp": 2.5, "y0": -0.75}

VARIANTS = [dict(gain=g, directional=d, fmu_state=s) for g in (False, True) for d in (False, True)
            for s in (True, False)]


class _Builds(dict):
    """{name (default_name): folder of that build, extracted}, each build made when first asked for (a
    compilation takes a few tenths of a second: no test waits for the builds it does not use)."""

    def __init__(self, out: Path) -> None:
        super().__init__()
        self.out = out

    def __missing__(self, name: str) -> Path:
        (flags,) = [f for f in VARIANTS if default_name(**f) == name]
        fmu = build_lag(self.out, **flags)
        folder = self[name] = Path(extract(str(fmu), unzipdir=str(self.out / name)))
        return folder


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    return _Builds(tmp_path_factory.mktemp("linear_fmus"))


@contextlib.contextmanager
def instance(folder: Path, kind: str, *, logging_on: bool = False, log: list | None = None):
    """An instantiated FMU2Model (kind "me") or FMU2Slave ("cs") of the extracted FMU in ``folder``; its log
    messages (status, category, message) appended to ``log``; terminated (if it can be) and freed after."""
    md = read_model_description(str(folder))
    messages = [] if log is None else log

    def logger(env, name, status, category, message):  # noqa: ANN001 (ctypes callback)
        messages.append((status, (category or b"").decode(), (message or b"").decode()))

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(byref(cb))
    cls, ident = (FMU2Model, md.modelExchange) if kind == "me" else (FMU2Slave, md.coSimulation)
    fmu = cls(guid=md.guid, unzipDirectory=str(folder), modelIdentifier=ident.modelIdentifier, instanceName="it")
    fmu.instantiate(callbacks=cb, loggingOn=logging_on)
    try:
        yield fmu
    finally:
        with contextlib.suppress(FMICallException):
            fmu.terminate()
        fmu.freeInstance()


def initialise(fmu, parameters: dict[str, float], vr: dict[str, int], u: float | None = None) -> None:
    """Set up at t = 0, set the parameters (and u) in initialisation mode, exit it; a model exchange
    instance is left in continuous-time mode."""
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    names = list(parameters) + ([] if u is None else ["u"])
    values = list(parameters.values()) + ([] if u is None else [u])
    if names:
        fmu.setReal([vr[n] for n in names], values)
    fmu.exitInitializationMode()
    if isinstance(fmu, FMU2Model):
        assert fmu.newDiscreteStates()[0] is False   # nothing to iterate
        fmu.enterContinuousTimeMode()


def reals(a: np.ndarray):
    """``a`` (float64) as the fmi2Real* of fmi2GetContinuousStates and its kin."""
    return a.ctypes.data_as(POINTER(fmi2Real))


ERROR = 3   # fmi2Error


def raw_call(fmu, fname: str, *args) -> int:
    """The status of a call FMPy's class for this interface does not offer (a function of the other)."""
    f = getattr(fmu.dll, fname)
    f.argtypes, f.restype = [c_void_p, *(type(a) for a in args)], c_int
    return f(fmu.component, *args)


# ------------------------------------------------------------------------------- the archive and the source

@pytest.mark.parametrize("flags", VARIANTS, ids=lambda f: default_name(**f))
def test_model_descriptions_are_valid_and_say_what_the_build_does(fmus, flags):
    """FMPy finds nothing wrong; both interfaces share the modelIdentifier and declare the FMU state and
    the directional derivatives exactly when the build has them; the Lag has one state, the Gain none, and
    only the Gain's output depends directly on u."""
    name = default_name(**flags)
    md = read_model_description(str(fmus[name]))
    assert validate_fmu(str(fmus[name])) == []
    for iface in (md.modelExchange, md.coSimulation):
        assert iface.modelIdentifier == name
        assert iface.canGetAndSetFMUstate is flags["fmu_state"]
        assert iface.providesDirectionalDerivative is flags["directional"]
    assert md.modelExchange.needsCompletedIntegratorStep is False   # completedIntegratorStepNotNeeded
    assert md.numberOfEventIndicators == 0
    assert md.numberOfContinuousStates == (0 if flags["gain"] else 1)
    variables = {v.name: v for v in md.modelVariables}
    assert {n: v.valueReference for n, v in variables.items()} == (GAIN_VR if flags["gain"] else LAG_VR)
    (out,) = md.outputs
    assert out.variable.name == "y"
    assert [d.name for d in out.dependencies] == (["u"] if flags["gain"] else ["x"])
    if not flags["gain"]:
        (der,) = md.derivatives
        assert der.variable.name == "der(x)" and der.variable.derivative is variables["x"]
        assert sorted(d.name for d in der.dependencies) == ["u", "x"]
        assert variables["tau"].unit == "s"
    assert all(variables[n].unit is None for n in variables if n not in ("tau", "der(x)"))


@pytest.mark.parametrize("name", ["Lag", "Gain"])
def test_the_start_values_declared_are_the_models_own(fmus, name):
    """Every start value in the model description (u and the parameters) is what the instance holds when
    none is set, and the initial unknowns follow from them (Lag: y = x = x0; Gain: y = kp u + y0)."""
    md = read_model_description(str(fmus[name]))
    starts = {v.name: float(v.start) for v in md.modelVariables if v.start is not None}
    vr = GAIN_VR if name == "Gain" else LAG_VR
    assert set(starts) == set(vr) - {"y", "x", "der(x)"}
    with instance(fmus[name], "cs") as fmu:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        assert fmu.getReal([vr[n] for n in starts]) == list(starts.values())
        expected = [starts["x0"]] * 2 if name == "Lag" else [starts["kp"] * starts["u"] + starts["y0"]]
        assert fmu.getReal([vr[n] for n in ("y", "x")[:len(expected)]]) == expected
        fmu.exitInitializationMode()


def test_each_build_compiles_without_warnings(tmp_path):
    """-Wall -Wextra -Werror, every combination of the defines."""
    import fmpy

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    inc = Path(fmpy.__file__).parent / "c-code"
    for flags in VARIANTS:
        defines = [f"-D{d}" for d, on in (("GAIN", flags["gain"]), ("DIRECTIONAL", flags["directional"]),
                                           ("NO_FMU_STATE", not flags["fmu_state"])) if on]
        p = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-fsyntax-only", f"-I{inc}", *defines, str(SRC)],
                           capture_output=True, text=True)
        assert p.returncode == 0, (defines, p.stderr)


# ------------------------------------------------------------------------------------- the Lag's response

@pytest.mark.parametrize("how", ["start value", "input table"])
def test_the_lag_in_model_exchange_follows_its_analytic_response(fmus, how):
    """Under FMPy's CVode (relative tolerance 1e-10), u = 2 held from t = 0, y(t) = k u + (x0 - k u)
    exp(-t/tau) to 1e-6 over 3 s (7.5 time constants)."""
    u = 2.0
    start = dict(LAG, **({"u": u} if how == "start value" else {}))
    table = np.array([(0.0, u), (3.0, u)], dtype=[("time", float), ("u", float)]) if how == "input table" else None
    res = simulate_fmu(str(fmus["Lag"]), fmi_type="ModelExchange", start_values=start, input=table,
                       stop_time=3.0, output_interval=0.01, relative_tolerance=1e-10, output=["y", "u"])
    assert len(res) == 301 and np.all(res["u"] == u)
    err = np.abs(res["y"] - lag_response(res["time"], u=u, **LAG))
    assert err.max() < 1e-6, err.max()


@pytest.mark.parametrize("how", ["start value", "input table"])
def test_the_lag_in_co_simulation_steps_by_its_exact_solution(fmus, how):
    """u = 2 held from t = 0, communication step 10 ms: y(t) = k u + (x0 - k u) exp(-t/tau) to 1e-12 (the
    rounding of 300 steps)."""
    u = 2.0
    start = dict(LAG, **({"u": u} if how == "start value" else {}))
    table = np.array([(0.0, u), (3.0, u)], dtype=[("time", float), ("u", float)]) if how == "input table" else None
    res = simulate_fmu(str(fmus["Lag"]), fmi_type="CoSimulation", start_values=start, input=table,
                       stop_time=3.0, output_interval=0.01, output=["y"])
    assert len(res) == 301
    err = np.abs(res["y"] - lag_response(res["time"], u=u, **LAG))
    assert err.max() < 1e-12, err.max()


def test_a_co_simulation_step_holds_the_input_set_before_it(fmus):
    """Steps of unequal lengths, u changed between them: each step is the exact solution under the u set
    before it (to rounding), and fmi2GetRealStatus gives the time at its end."""
    k, tau, x0 = LAG["k"], LAG["tau"], LAG["x0"]
    x, t = x0, 0.0
    with instance(fmus["Lag"], "cs") as fmu:
        initialise(fmu, LAG, LAG_VR)
        assert fmu.getReal([LAG_VR["y"]]) == [x0]
        for u, h in ((1.0, 0.3), (-2.0, 0.05), (0.5, 0.7)):
            fmu.setReal([LAG_VR["u"]], [u])
            fmu.doStep(t, h)
            x, t = k * u + (x - k * u) * np.exp(-h / tau), t + h
            y, xs = fmu.getReal([LAG_VR["y"], LAG_VR["x"]])
            assert y == xs and abs(y - x) < 1e-14
            assert fmu.getRealStatus(2) == t   # fmi2LastSuccessfulTime


def test_the_lag_derivative_is_that_of_the_state_and_input_set(fmus):
    """Model Exchange: der(x) = (k u - x)/tau, for a state and an input set in continuous-time mode, and
    for an input set in event mode; fmi2GetDerivatives and the variable der(x) agree; y = x, the nominal
    of x is 1, no event indicators, and a completed step asks for no event."""
    k, tau = LAG["k"], LAG["tau"]
    with instance(fmus["Lag"], "me") as fmu:
        initialise(fmu, LAG, LAG_VR)
        x, dx, nominal = np.zeros(1), np.zeros(1), np.zeros(1)
        fmu.getContinuousStates(reals(x), 1)
        assert x[0] == LAG["x0"]
        for state, u in ((0.3, 1.5), (-4.0, -0.25)):
            fmu.setTime(1.0)
            fmu.setContinuousStates(reals(np.array([state])), 1)
            fmu.setReal([LAG_VR["u"]], [u])
            fmu.getDerivatives(reals(dx), 1)
            assert dx[0] == (k * u - state) / tau
            assert fmu.getReal([LAG_VR["der(x)"], LAG_VR["y"]]) == [dx[0], state]
            assert fmu.completedIntegratorStep() == (False, False)
        fmu.enterEventMode()
        fmu.setReal([LAG_VR["u"]], [3.0])
        assert fmu.getReal([LAG_VR["der(x)"]]) == [(k * 3.0 - (-4.0)) / tau]
        assert fmu.newDiscreteStates() == (False, False, False, False, False, 0.0)
        fmu.enterContinuousTimeMode()
        fmu.getNominalsOfContinuousStates(reals(nominal), 1)
        assert nominal[0] == 1.0
        fmu.getEventIndicators(None, 0)


# ------------------------------------------------------------------------------------------------ the Gain

@pytest.mark.parametrize("kind", ["me", "cs"])
def test_the_gain_output_follows_a_set_input_at_once(fmus, kind):
    """y = kp u + y0 read right after fmi2SetReal of u, without a step (or any other call): after the
    initialisation, and again for another u (in Model Exchange in continuous-time and in event mode)."""
    kp, y0 = GAIN["kp"], GAIN["y0"]
    with instance(fmus["Gain"], kind) as fmu:
        initialise(fmu, GAIN, GAIN_VR, u=3.0)
        assert fmu.getReal([GAIN_VR["y"]]) == [kp * 3.0 + y0]
        fmu.setReal([GAIN_VR["u"]], [-1.25])
        assert fmu.getReal([GAIN_VR["y"]]) == [kp * -1.25 + y0]
        if kind == "me":
            fmu.enterEventMode()
        else:
            fmu.doStep(0.0, 0.1)
        fmu.setReal([GAIN_VR["u"]], [7.0])
        assert fmu.getReal([GAIN_VR["y"]]) == [kp * 7.0 + y0]


def test_the_gain_in_both_interfaces_under_simulate_fmu(fmus):
    """A ramp input: y = kp u + y0 at every output point, in Model Exchange (u the ramp at that time) and
    Co-Simulation (u the ramp at the start of the step, held over it)."""
    table = np.array([(0.0, 0.0), (1.0, 2.0)], dtype=[("time", float), ("u", float)])
    for fmi_type in ("ModelExchange", "CoSimulation"):
        res = simulate_fmu(str(fmus["Gain"]), fmi_type=fmi_type, start_values=GAIN, input=table, stop_time=1.0,
                           output_interval=0.1, output=["u", "y"])
        assert np.allclose(res["y"], GAIN["kp"] * res["u"] + GAIN["y0"], rtol=0, atol=1e-15), fmi_type
        held = np.maximum(res["time"] - 0.1, 0.0) if fmi_type == "CoSimulation" else res["time"]
        assert np.allclose(res["u"], 2.0 * held, rtol=0, atol=1e-12), fmi_type


# ------------------------------------------------------------------------------------------- the FMU state

@pytest.mark.parametrize("name", ["Lag", "Gain"])
def test_a_restored_co_simulation_state_steps_again_bit_for_bit(fmus, name):
    """Step, save, step (another input), restore: the values are those saved; the same step again gives
    the same output and time to the bit."""
    vr = GAIN_VR if name == "Gain" else LAG_VR
    with instance(fmus[name], "cs") as fmu:
        initialise(fmu, GAIN if name == "Gain" else LAG, vr, u=1.0)
        fmu.doStep(0.0, 0.1)
        saved = fmu.getReal([vr["u"], vr["y"]]), fmu.getRealStatus(2)
        state = fmu.getFMUstate()
        fmu.setReal([vr["u"]], [-3.0])
        fmu.doStep(0.1, 0.25)
        after = fmu.getReal([vr["y"]]), fmu.getRealStatus(2)
        fmu.setFMUstate(state)
        assert (fmu.getReal([vr["u"], vr["y"]]), fmu.getRealStatus(2)) == saved
        fmu.setReal([vr["u"]], [-3.0])
        fmu.doStep(0.1, 0.25)
        assert (fmu.getReal([vr["y"]]), fmu.getRealStatus(2)) == after
        fmu.freeFMUstate(state)
        assert not state   # freed and cleared


def test_a_restored_model_exchange_state_gives_the_same_derivative(fmus):
    """Save in continuous-time mode; set another time, state and input; restore: the state, input and
    derivative are those saved, to the bit.  A state given back to fmi2GetFMUstate is overwritten."""
    with instance(fmus["Lag"], "me") as fmu:
        initialise(fmu, LAG, LAG_VR, u=1.0)
        fmu.setTime(0.5)
        fmu.setContinuousStates(reals(np.array([0.7])), 1)
        names = [LAG_VR[n] for n in ("x", "u", "der(x)", "y")]
        saved = fmu.getReal(names)
        state = fmu.getFMUstate()
        fmu.setTime(0.9)
        fmu.setContinuousStates(reals(np.array([-2.0])), 1)
        fmu.setReal([LAG_VR["u"]], [5.0])
        fmu.setFMUstate(state)
        assert fmu.getReal(names) == saved
        fmu.setReal([LAG_VR["u"]], [5.0])
        fmu.fmi2GetFMUstate(fmu.component, byref(state))   # into the same memory
        fmu.setReal([LAG_VR["u"]], [1.0])
        fmu.setFMUstate(state)
        assert fmu.getReal([LAG_VR["u"]]) == [5.0]
        fmu.freeFMUstate(state)


@pytest.mark.parametrize("name", ["LagNoFmuState", "GainNoFmuState"])
@pytest.mark.parametrize("kind", ["me", "cs"])
def test_a_build_without_fmu_state_refuses_it(fmus, name, kind):
    """-DNO_FMU_STATE: fmi2GetFMUstate and fmi2SetFMUstate return fmi2Error, with a message."""
    log: list = []
    with instance(fmus[name], kind, log=log) as fmu:
        initialise(fmu, {}, {})
        with pytest.raises(FMICallException, match="fmi2GetFMUstate"):
            fmu.getFMUstate()
        with pytest.raises(FMICallException, match="fmi2SetFMUstate"):
            fmu.setFMUstate(None)
    assert any("not supported" in m for _, _, m in log)


# ---------------------------------------------------------------------------- the directional derivatives

def test_the_lag_directional_derivatives_in_model_exchange_are_exact(fmus):
    """Knowns x and u, unknowns der(x) and y, one unit seed at a time: the columns (-1/tau, 1) and
    (k/tau, 0), equal to the bit; in continuous-time and in event mode; a seed scales them."""
    k, tau = LAG["k"], LAG["tau"]
    der, y, x, u = (LAG_VR[n] for n in ("der(x)", "y", "x", "u"))
    with instance(fmus["LagDirectional"], "me") as fmu:
        initialise(fmu, LAG, LAG_VR, u=1.0)
        for _ in range(2):
            assert fmu.getDirectionalDerivative([der, y], [x], [1.0]) == [-1.0 / tau, 1.0]
            assert fmu.getDirectionalDerivative([der, y], [u], [1.0]) == [k / tau, 0.0]
            assert fmu.getDirectionalDerivative([y, der], [u, x], [1.0, 0.0]) == [0.0, k / tau]
            assert fmu.getDirectionalDerivative([der], [x], [-2.0]) == [2.0 / tau]
            fmu.enterEventMode()


def test_the_gain_directional_derivative_in_model_exchange_is_kp(fmus):
    with instance(fmus["GainDirectional"], "me") as fmu:
        initialise(fmu, GAIN, GAIN_VR)
        assert fmu.getDirectionalDerivative([GAIN_VR["y"]], [GAIN_VR["u"]], [1.0]) == [GAIN["kp"]]


@pytest.mark.parametrize("name", ["LagDirectional", "GainDirectional"])
def test_the_co_simulation_directional_derivative_is_that_of_y_by_u_only(fmus, name):
    """Co-Simulation gives dy/du (Lag 0, Gain kp) after a step too, and refuses the state or its
    derivative as a known or an unknown."""
    gain = name.startswith("Gain")
    vr = GAIN_VR if gain else LAG_VR
    with instance(fmus[name], "cs") as fmu:
        initialise(fmu, GAIN if gain else LAG, vr, u=1.0)
        fmu.doStep(0.0, 0.1)
        assert fmu.getDirectionalDerivative([vr["y"]], [vr["u"]], [1.0]) == [GAIN["kp"] if gain else 0.0]
        if not gain:
            with pytest.raises(FMICallException):
                fmu.getDirectionalDerivative([vr["der(x)"]], [vr["u"]], [1.0])
            with pytest.raises(FMICallException):
                fmu.getDirectionalDerivative([vr["y"]], [vr["x"]], [1.0])


@pytest.mark.parametrize("name", ["Lag", "Gain"])
@pytest.mark.parametrize("kind", ["me", "cs"])
def test_a_build_without_directional_derivatives_refuses_them(fmus, name, kind):
    vr = GAIN_VR if name == "Gain" else LAG_VR
    with instance(fmus[name], kind) as fmu:
        initialise(fmu, {}, {})
        with pytest.raises(FMICallException):
            fmu.getDirectionalDerivative([vr["y"]], [vr["u"]], [1.0])


def test_a_parameter_is_not_a_known_of_the_directional_derivatives(fmus):
    with instance(fmus["LagDirectional"], "me") as fmu:
        initialise(fmu, {}, {})
        with pytest.raises(FMICallException):
            fmu.getDirectionalDerivative([LAG_VR["y"]], [LAG_VR["k"]], [1.0])


# ------------------------------------------------------------------------------------ the state machine

@pytest.mark.parametrize("tau", [0.0, -1.0])
@pytest.mark.parametrize("kind", ["me", "cs"])
def test_a_non_positive_tau_is_an_error_at_the_end_of_the_initialisation(fmus, kind, tau):
    log: list = []
    with instance(fmus["Lag"], kind, log=log) as fmu:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([LAG_VR["tau"]], [tau])   # accepted here: the parameters are checked together at the end
        with pytest.raises(FMICallException, match="fmi2ExitInitializationMode"):
            fmu.exitInitializationMode()
    assert any("tau" in m and "must be > 0" in m for _, _, m in log)


@pytest.mark.parametrize("kind", ["me", "cs"])
def test_parameters_are_fixed_after_the_initialisation_and_the_input_is_not(fmus, kind):
    """Before the end of the initialisation a parameter (x0 with it the start state) may be set; after it,
    setting one is an error and changes nothing; u may be set at any time; y, x and der(x) never."""
    with instance(fmus["Lag"], kind) as fmu:
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([LAG_VR["x0"]], [5.0])   # instantiated
        fmu.enterInitializationMode()
        assert fmu.getReal([LAG_VR["y"], LAG_VR["x"]]) == [5.0, 5.0]
        fmu.setReal([LAG_VR["x0"]], [LAG["x0"]])
        assert fmu.getReal([LAG_VR["y"]]) == [LAG["x0"]]
        fmu.exitInitializationMode()
        for name in ("k", "tau", "x0"):
            with pytest.raises(FMICallException):
                fmu.setReal([LAG_VR[name]], [9.0])
        assert fmu.getReal([LAG_VR[n] for n in ("k", "tau", "x0")]) == [1.0, 1.0, LAG["x0"]]
        fmu.setReal([LAG_VR["u"]], [2.0])
        for name in ("y", "x", "der(x)"):
            with pytest.raises(FMICallException):
                fmu.setReal([LAG_VR[name]], [9.0])
        assert fmu.getReal([LAG_VR["u"], LAG_VR["y"]]) == [2.0, LAG["x0"]]


def test_calls_out_of_order_are_errors(fmus):
    """A step before the initialisation, a Model Exchange call on a co-simulation instance, a state set in
    event mode, a non-positive step, the wrong number of states."""
    with instance(fmus["Lag"], "cs") as fmu:
        fmu.setupExperiment(startTime=0.0)
        with pytest.raises(FMICallException):
            fmu.doStep(0.0, 0.1)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        assert raw_call(fmu, "fmi2SetTime", c_double(1.0)) == ERROR
        with pytest.raises(FMICallException):
            fmu.doStep(0.0, 0.0)
    with instance(fmus["Lag"], "me") as fmu:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        with pytest.raises(FMICallException):   # event mode: states are set in continuous-time mode
            fmu.setContinuousStates(reals(np.array([1.0])), 1)
        fmu.enterContinuousTimeMode()
        with pytest.raises(FMICallException):
            fmu.getDerivatives(reals(np.zeros(2)), 2)
        assert raw_call(fmu, "fmi2DoStep", c_double(0.0), c_double(0.1), c_int(1)) == ERROR


@pytest.mark.parametrize("kind", ["me", "cs"])
def test_terminate_then_reset_starts_afresh(fmus, kind):
    """After fmi2Terminate the values can be read but neither the input set nor a step made; fmi2Reset
    brings back the defaults (k = tau = 1, x0 = 0) and a second run from them matches the analytic
    response."""
    with instance(fmus["Lag"], kind) as fmu:
        initialise(fmu, LAG, LAG_VR, u=1.0)
        if kind == "cs":
            fmu.doStep(0.0, 0.5)
        fmu.terminate()
        assert fmu.getReal([LAG_VR["k"]]) == [LAG["k"]]
        with pytest.raises(FMICallException):
            fmu.setReal([LAG_VR["u"]], [0.0])
        if kind == "cs":
            with pytest.raises(FMICallException):
                fmu.doStep(0.5, 0.5)
        fmu.reset()
        initialise(fmu, {}, LAG_VR, u=1.0)
        assert fmu.getReal([LAG_VR[n] for n in ("k", "tau", "x0", "y")]) == [1.0, 1.0, 0.0, 0.0]
        if kind == "cs":
            fmu.doStep(0.0, 0.5)
            assert abs(fmu.getReal([LAG_VR["y"]])[0] - lag_response(0.5, u=1.0)) < 1e-15


def test_logging_is_off_by_default_and_errors_are_logged_still(fmus):
    """A run with loggingOn false logs nothing; an error is logged even so; with loggingOn true the end of
    the initialisation is logged (category logEvents)."""
    log: list = []
    with instance(fmus["Lag"], "cs", log=log) as fmu:
        initialise(fmu, LAG, LAG_VR, u=1.0)
        fmu.doStep(0.0, 0.1)
        assert log == []
        with pytest.raises(FMICallException):
            fmu.setReal([LAG_VR["k"]], [1.0])
        assert [(s, c) for s, c, _ in log] == [(3, "logStatusError")]
    log.clear()
    with instance(fmus["Lag"], "me", logging_on=True, log=log) as fmu:
        initialise(fmu, LAG, LAG_VR)
    assert [(s, c) for s, c, _ in log] == [(0, "logEvents")] and "x = -1" in log[0][2]
