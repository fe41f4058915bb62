"""``wmr-cosim linearize``: its files (linear.npz, linear.mat, linear.json, the plots), its printout, bad
input as one line with exit code 2, and the G1 loop broken at the torques with the margins
docs/linearisation.md reports."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.io import loadmat

from wmr_cosim.cli import main
from wmr_cosim.cosim import LinearModel

from linear_fmus import build_lag

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("linear-fmus")
    return {"lag": build_lag(out), "gain": build_lag(out, gain=True), "lag_no_state": build_lag(out, fmu_state=False)}


def _loop_scenario(folder: Path, fmus: dict[str, Path], interface: str = "model-exchange") -> Path:
    text = (f'[experiment]\nstart = 0.0\nstop = 2.0\nstep = 0.01\n'
            f'[instances.lag]\nfmu = "{fmus["lag"]}"\ninterface = "{interface}"\n'
            f'[instances.lag.parameters]\ntau = 0.5\nk = 2.0\n'
            f'[instances.ctrl]\nfmu = "{fmus["gain"]}"\ninterface = "{interface}"\n'
            f'[instances.ctrl.parameters]\nkp = -3.0\n'
            '[[connections]]\nfrom = "lag.y"\nto = "ctrl.u"\n[[connections]]\nfrom = "ctrl.y"\nto = "lag.u"\n')
    path = folder / f"loop-{interface}.toml"
    path.write_text(text)
    return path


def test_an_fmu_alone_gives_its_model_in_every_file(fmus, tmp_path, capsys):
    out = tmp_path / "lin"
    assert main(["linearize", str(fmus["lag"]), "--at", "0.5", "--set", "Lag.tau=0.25", "--set", "Lag.k=3",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "linear model at t = 0.5 s (continuous time; Lag: central differences): 1 states, 1 inputs, 1 outputs" \
        in printed
    assert "eigenvalues: -4" in printed
    m = LinearModel.load(out / "linear.npz")
    np.testing.assert_allclose([m.A[0, 0], m.B[0, 0], m.C[0, 0], m.D[0, 0]], [-4.0, 12.0, 1.0, 0.0], rtol=1e-8,
                               atol=1e-12)
    assert (m.states, m.inputs, m.outputs, m.t, m.dt) == (["Lag.x"], ["Lag.u"], ["Lag.y"], 0.5, 0.0)
    mat = loadmat(out / "linear.mat")
    np.testing.assert_array_equal(mat["A"], m.A)
    # the names as a cell array of strings (MATLAB: inputs{1} is 'Lag.u')
    assert mat["inputs"].dtype == object and [str(np.ravel(c)[0]) for c in np.ravel(mat["inputs"])] == ["Lag.u"]
    summary = json.loads((out / "linear.json").read_text())
    assert summary["eigenvalues"][0][0] == pytest.approx(-4.0, rel=1e-8) and summary["continuous"]
    assert not (out / "bode.png").exists()   # no loop, no plots


def test_a_loop_broken_at_a_connection_prints_its_margins_and_draws_them(fmus, tmp_path, capsys):
    """L = 6 / (0.5 s + 1): no phase crossover; |L| = 1 at w = sqrt(35) / 0.5, phase margin 180 - atan(sqrt(35))."""
    out = tmp_path / "loop"
    assert main(["linearize", str(_loop_scenario(tmp_path, fmus)), "--break", "ctrl.y->lag.u", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    pm = 180.0 - np.degrees(np.arctan(np.sqrt(35.0)))
    assert f"phase margin {pm:.4g} deg" in printed, printed
    assert "gain margin inf" in printed and "closed loop stable" in printed
    loop = json.loads((out / "linear.json").read_text())["loop"]
    assert loop["gain_margin"] == "inf" and loop["phase_margin_deg"] == pytest.approx(pm, rel=1e-6)
    assert loop["closed_eigenvalues"] == [[pytest.approx(-14.0, rel=1e-6), 0.0]]
    assert (out / "bode.png").stat().st_size > 10_000 and (out / "nyquist.png").stat().st_size > 10_000


def _one_line(capsys, code: int, *words: str) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


def test_bad_input_is_one_line_and_exit_code_2(fmus, tmp_path, capsys):
    scenario = _loop_scenario(tmp_path, fmus)
    out = str(tmp_path / "o")
    # a model by rollback of an FMU that cannot save its state
    _one_line(capsys, main(["linearize", str(fmus["lag_no_state"]), "--discrete", "--out", out]),
              "LagNoFmuState", "cannot save and restore its state")
    # an unknown variable, with the nearest name
    _one_line(capsys, main(["linearize", str(scenario), "--inputs", "lag.uu", "--out", out]),
              "--inputs", "no variable 'uu'", "did you mean")
    _one_line(capsys, main(["linearize", str(scenario), "--inputs", "nobody.u", "--out", out]),
              "unknown instance 'nobody'")
    _one_line(capsys, main(["linearize", str(scenario), "--inputs", "lag.y", "--out", out]), "not an input")
    # a break at a connection that does not exist, with the system's connections
    _one_line(capsys, main(["linearize", str(scenario), "--break", "lag.y->lag.u", "--out", out]),
              "--break", "no connection lag.y -> lag.u", "lag.y -> ctrl.u")
    _one_line(capsys, main(["linearize", str(scenario), "--break", "lag.y=>ctrl.u", "--out", out]), "FROM->TO")
    # a time beyond the run
    _one_line(capsys, main(["linearize", str(scenario), "--at", "7", "--inputs", "lag.u", "--out", out]),
              "--at", "outside the run (0 s to 2 s)")
    # responses that run past the stop time, a state that is none, a bad state value
    _one_line(capsys, main(["linearize", str(_loop_scenario(tmp_path, fmus, "co-simulation")), "--at", "1.5",
                            "--break", "ctrl.y->lag.u", "--out", out]), "--steps", "reach the run's stop time")
    _one_line(capsys, main(["linearize", str(scenario), "--inputs", "lag.u", "--state", "lag.y=1", "--out", out]),
              "--state", "no continuous state of lag", "lag.x")
    _one_line(capsys, main(["linearize", str(scenario), "--inputs", "lag.u", "--state", "lag.x=abc", "--out", out]),
              "--state", "INSTANCE.STATE=VALUE")
    assert not Path(out).exists()   # refused before anything is written


def _chain_scenario(folder: Path, fmus: dict[str, Path], stop: float = 2.0, **extra: str) -> Path:
    """Two lags in series in co-simulation (lag1.y -> lag2.u, taus 0.1 s and 0.5 s): order 2 from lag1.u to
    lag2.y; ``extra``: more TOML text appended by name (not used by name)."""
    text = (f'[experiment]\nstart = 0.0\nstop = {stop}\nstep = 0.01\n'
            f'[instances.lag1]\nfmu = "{fmus["lag"]}"\ninterface = "co-simulation"\n'
            f'[instances.lag1.parameters]\ntau = 0.1\n'
            f'[instances.lag2]\nfmu = "{fmus["lag"]}"\ninterface = "co-simulation"\n'
            f'[instances.lag2.parameters]\ntau = 0.5\n'
            '[[connections]]\nfrom = "lag1.y"\nto = "lag2.u"\n' + "".join(extra.values()))
    path = folder / "chain.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def scenarios(fmus, tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("linear-scenarios")
    out = {"me": _loop_scenario(folder, fmus), "cs": _loop_scenario(folder, fmus, "co-simulation"),
           "chain": _chain_scenario(folder, fmus), "lag": fmus["lag"]}
    (folder / "a-file").write_text("not a folder\n")
    out["file"] = folder / "a-file"
    return out


#: (target, arguments, words of the one line): bad input, refused before anything runs, nothing written.
BAD_INPUTS = [
    # --order: a positive whole number, no more than the responses realise, of a realisation only
    ("cs", ["--at", "0.5", "--break", "ctrl.y->lag.u", "--steps", "50", "--order", "0"], ["--order", "positive"]),
    ("cs", ["--at", "0.5", "--break", "ctrl.y->lag.u", "--steps", "50", "--order", "-1"], ["--order", "positive"]),
    ("cs", ["--at", "0.5", "--break", "ctrl.y->lag.u", "--steps", "50", "--order", "26"],
     ["--order", "at most 25", "--steps"]),
    ("cs", ["--at", "0.5", "--break", "ctrl.y->lag.u", "--steps", "50", "--order", "1.5"], ["--order", "whole"]),
    ("cs", ["--at", "0.5", "--break", "ctrl.y->lag.u", "--steps", "50", "--order", "two"], ["--order", "number"]),
    ("me", ["--break", "ctrl.y->lag.u", "--order", "2"], ["--order", "continuous-time", "--discrete"]),
    ("me", ["--break", "ctrl.y->lag.u", "--steps", "20"], ["--steps", "continuous-time"]),
    ("me", ["--break", "ctrl.y->lag.u", "--pulse", "0.1"], ["--pulse", "continuous-time"]),
    # --steps
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "0"], ["--steps", "at least 2"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "-1"], ["--steps", "at least 2"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "1e9"], ["--steps", "stop time"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "2.5"], ["--steps", "whole"]),
    # the responses may not reach the stop time, where the run ends (200 steps of 0.01 s from 0 s: 2 s)
    ("cs", ["--break", "ctrl.y->lag.u"], ["--steps", "reach the run's stop time 2 s"]),
    # --pulse: finite and positive; one beyond the floating point numbers at the input
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "50", "--pulse", "0"], ["--pulse", "positive"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "50", "--pulse", "-1"], ["--pulse", "positive"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "50", "--pulse", "nan"], ["--pulse", "finite"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "50", "--pulse", "inf"], ["--pulse", "finite"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "50", "--pulse", "1e308"], ["--pulse", "range"]),
    # --at
    ("lag", ["--at", "nan"], ["--at", "finite"]),
    ("lag", ["--at", "inf"], ["--at", "finite"]),
    ("lag", ["--at", "-1"], ["--at", "outside the run"]),
    ("lag", ["--at", "soon"], ["--at", "number"]),
    ("lag", ["--at", "5"], ["--at", "stop time 5 s"]),       # (the FMU's default experiment: 0 s to 5 s)
    ("lag", ["--at", "4.999999"], ["--at", "t = 4.999999 s", "stop time"]),
    # --inputs, --outputs: empty, unknown, given twice
    ("lag", ["--inputs", ""], ["--inputs", "empty name"]),
    ("lag", ["--inputs", "Lag.u,"], ["--inputs", "empty name"]),
    ("lag", ["--outputs", ""], ["--outputs", "empty name"]),
    ("lag", ["--outputs", "Lag.yy"], ["--outputs", "no variable 'yy'"]),
    ("lag", ["--inputs", "Lag.u", "--inputs", "Lag.u"], ["--inputs", "twice"]),
    ("lag", ["--outputs", "Nobody.y"], ["--outputs", "unknown instance"]),
    # --break: malformed, or no such connection
    ("me", ["--break", ""], ["--break", "FROM->TO"]),
    ("me", ["--break=->"], ["--break", "FROM->TO"]),
    ("me", ["--break", "lag.y->ctrl.u->lag.u"], ["--break", "FROM->TO"]),
    ("me", ["--break", "ctrl.y->"], ["--break", "FROM->TO"]),
    ("me", ["--break", "ctrl.y-lag.u"], ["--break", "FROM->TO"]),
    ("me", ["--break", "ctrl->lag.u"], ["--break", "no connection"]),
    # --state: malformed, not a state, twice, on a co-simulation instance
    ("lag", ["--state", ""], ["--state", "INSTANCE.STATE=VALUE"]),
    ("lag", ["--state", "=1"], ["--state", "INSTANCE.STATE=VALUE"]),
    ("lag", ["--state", "Lag.x"], ["--state", "INSTANCE.STATE=VALUE"]),
    ("lag", ["--state", "Lag.x=nan"], ["--state", "finite"]),
    ("lag", ["--state", "x=1"], ["--state", "instance.variable"]),
    ("lag", ["--state", "Lag.x=1", "--state", "Lag.x=2"], ["--state", "twice"]),
    ("lag", ["--state", "Lag.u=1"], ["--state", "no continuous state"]),
    ("lag", ["--discrete", "--state", "Lag.x=1"], ["--state", "Model Exchange"]),
    # --method: directional where the model description declares none; a Jacobian's method for a realisation
    ("lag", ["--method", "directional"], ["--method", "declares no directional derivatives"]),
    ("cs", ["--break", "ctrl.y->lag.u", "--steps", "50", "--method", "differences"], ["--method", "pulse responses"]),
    # --out: an existing file, or under one
    ("lag", ["--out", "FILE"], ["--out", "not a folder"]),
    ("lag", ["--out", "FILE/sub"], ["--out", "not a folder"]),
    ("lag", ["--out", ""], ["--out", "give a folder"]),   # (not the working folder)
]


@pytest.mark.parametrize("target, args, words", BAD_INPUTS, ids=[" ".join(a) for _, a, _ in BAD_INPUTS])
def test_each_bad_option_is_one_line_exit_2_before_the_run_with_nothing_written(scenarios, tmp_path, capsys,
                                                                                monkeypatch, target, args, words):
    monkeypatch.chdir(tmp_path)   # (nothing written in the working folder either)
    out = tmp_path / "o"
    args = [str(scenarios["file"]) + a[4:] if a.startswith("FILE") else a for a in args]
    code = main(["linearize", str(scenarios[target]), *args] + ([] if "--out" in args else ["--out", str(out)]))
    _one_line(capsys, code, *words)
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == []
    assert scenarios["file"].read_text() == "not a folder\n"


def test_an_order_below_the_singular_values_is_a_truncation_and_says_so(scenarios, tmp_path, capsys):
    """Two lags in series realise order 2; --order 1 discards the second Hankel singular value, which the
    printout and linear.json say, with its value."""
    base = ["linearize", str(scenarios["chain"]), "--at", "0.5", "--inputs", "lag1.u", "--outputs", "lag2.y",
            "--steps", "60"]
    assert main([*base, "--out", str(tmp_path / "auto")]) == 0
    auto = json.loads((tmp_path / "auto" / "linear.json").read_text())
    sv = auto["hankel_singular_values"]
    assert len(auto["states"]) == 2 and sv[1] > 1e-3 * sv[0] and auto["notes"] == []
    capsys.readouterr()
    assert main([*base, "--order", "1", "--out", str(tmp_path / "one")]) == 0
    printed = capsys.readouterr().out
    one = json.loads((tmp_path / "one" / "linear.json").read_text())
    assert len(one["states"]) == 1
    note = [n for n in one["notes"] if "truncation" in n]
    assert len(note) == 1 and f"({sv[1]:.3g})" in note[0] and "realise order 2" in note[0], one["notes"]
    assert f"note: {note[0]}" in printed and "0 states" not in printed


def test_a_return_that_does_not_respond_to_the_injection_is_no_loop_not_a_stable_one(fmus, tmp_path, capsys):
    """A controller of gain 0: the loop's responses are all 0; no margins, no "closed loop stable"."""
    text = _loop_scenario(tmp_path, fmus, "co-simulation").read_text().replace("kp = -3.0", "kp = 0.0")
    (tmp_path / "open.toml").write_text(text)
    _one_line(capsys, main(["linearize", str(tmp_path / "open.toml"), "--at", "0.5", "--break", "ctrl.y->lag.u",
                            "--steps", "50", "--out", str(tmp_path / "o")]), "--break", "does not respond")
    assert not (tmp_path / "o").exists()


def _shell(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    import os
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "linearize", *args], capture_output=True,
                          text=True, timeout=300, env={**os.environ, **(env or {})})


def test_an_fmu_failing_in_a_response_ends_the_run_with_one_line_not_a_crash(fmus, tmp_path):
    """A lag of gain 1e300 pulsed by 1e10: its output overflows in the first response and the run fails
    there.  The saved point's FMU states are freed before the instances (freeing them after, in a library
    FMPy has unloaded, was a segmentation fault); in a shell, so that a crash shows as the return code."""
    text = _loop_scenario(tmp_path, fmus, "co-simulation").read_text().replace("k = 2.0", "k = 1e300")
    (tmp_path / "big.toml").write_text(text)
    p = _shell(str(tmp_path / "big.toml"), "--at", "0.5", "--break", "ctrl.y->lag.u", "--pulse", "1e10", "--steps",
               "20", "--out", str(tmp_path / "o"))
    assert p.returncode == 1, (p.returncode, p.stderr[-3000:])
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, p.stderr
    assert "the response to a pulse of +1e+10 at lag.u from t = 0.5 s failed" in p.stderr, p.stderr
    assert "non-finite" in p.stderr and not (tmp_path / "o").exists()


def test_a_response_that_is_not_finite_is_a_failed_run_naming_the_output(fmus, tmp_path, capsys):
    """An FMU alone (no connection to carry the overflow to): its output itself is not finite."""
    code = main(["linearize", str(fmus["lag"]), "--discrete", "--inputs", "Lag.u", "--set", "Lag.k=1e10",
                 "--pulse", "1e300", "--steps", "10", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, err
    assert "the response to a pulse of +1e+300 at Lag.u from t = 0 s is not finite: Lag.y = " in err, err
    assert not (tmp_path / "o").exists()


def test_a_state_that_makes_the_jacobian_non_finite_is_one_line_naming_the_entries(tmp_path, capsys):
    """Van der Pol at x0 = 1e200: der(x1) = mu (1 - x0^2) x1 - x0 overflows; exit code 1, the model at the
    point the user chose cannot be taken (the value itself is a valid one: the FMU declares no range)."""
    from reference_fmus import fmi2

    code = main(["linearize", str(fmi2("VanDerPol")), "--state", "VanDerPol.x0=1e200", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "--state VanDerPol.x0=1e+200 is not finite: d der(VanDerPol.x1)/d VanDerPol.x0 = " in err, err
    assert not (tmp_path / "o").exists()


BLOCKER = """import sys
class _Blocker:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] == {name!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, _Blocker())
"""


@pytest.mark.parametrize("missing, named", [("scipy", "scipy"), ("control", "python-control")])
def test_without_the_linear_extra_one_line_says_how_to_install_it(fmus, tmp_path, missing, named):
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(BLOCKER.format(name=missing))
    import os
    p = _shell(str(fmus["lag"]), "--out", str(tmp_path / "o"),
               env={"PYTHONPATH": os.pathsep.join([str(site), str(ROOT)])})
    assert p.returncode == 2, p.stderr[-3000:]
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, p.stderr
    assert f"linearize needs {named}" in p.stderr and "wmr-cosim[linear]" in p.stderr, p.stderr
    assert not (tmp_path / "o").exists()


def test_the_command_runs_from_a_shell_with_python_control_named_where_missing(fmus, tmp_path):
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "linearize", str(fmus["lag"]), "--at", "0.1",
                        "--out", str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "results in" in p.stdout and (tmp_path / "o" / "linear.npz").is_file()


# ---------------------------------------------------------------- the G1 loop, as docs/linearisation.md reports it
G1_COMMAND = ["linearize", "g1_learn.toml", "--at", "20", "--break", "controller.u1->plant.u1", "--set",
              "sensor.ppr=5e6", "--pulse", "1e-2", "--steps", "300"]


def _documented() -> dict[str, float]:
    """The figures of the G1 loop in docs/linearisation.md's table (| figure | value |)."""
    text = (ROOT / "docs" / "linearisation.md").read_text()
    block = text.split("<!-- g1-loop -->")[1]
    return {m.group(1).strip(): float(m.group(2)) for m in re.finditer(r"^\| ([^|]+) \| ([-0-9.e+]+) \|", block, re.M)}


@pytest.mark.slow
def test_the_g1_loop_broken_at_the_right_torque_has_the_documented_margins(tmp_path, capsys):
    """The command as the docs give it: the margins they report (the run is deterministic: to the printed
    digits), the closed loop stable, and the closed loop through the break against the system realised as
    a whole at the same order."""
    assert main([*G1_COMMAND, "--out", str(tmp_path / "g1")]) == 0
    capsys.readouterr()
    s = json.loads((tmp_path / "g1" / "linear.json").read_text())
    doc = _documented()
    loop = s["loop"]
    assert loop["order"] == doc["realised order"]
    assert loop["upper_gain_margin"] == pytest.approx(doc["upper gain margin"], rel=1e-3)
    assert loop["lower_gain_margin"] == pytest.approx(doc["lower gain margin"], rel=1e-3)
    assert [c["kind"] for c in loop["phase_crossovers"]] == ["lower", "upper"]
    # the integrator from torque to wheel angle, realised just outside the unit circle (within 1e-3): said
    assert [abs(complex(*z)) for z in loop["open_loop_poles_on_or_outside"]] == \
        [pytest.approx(doc["open-loop pole on the unit circle"], abs=1e-4)]
    assert loop["phase_margin_deg"] == pytest.approx(doc["phase margin [deg]"], rel=1e-3)
    assert loop["phase_crossovers"][1]["rad_s"] == pytest.approx(doc["phase crossover [rad/s]"], rel=1e-3)
    assert loop["gain_crossover_rad_s"] == pytest.approx(doc["gain crossover [rad/s]"], rel=1e-3)
    assert loop["closed_loop_stable"]
    closed = np.array([complex(*z) for z in loop["closed_eigenvalues"]])
    whole = np.array([complex(*z) for z in s["whole_eigenvalues"]])
    apart = np.abs(np.sort_complex(closed) - np.sort_complex(whole)).max()
    assert apart <= doc["closed against whole, largest difference"]


# ---------------------------------------------------------------- the operating point, the plots' titles
def test_the_operating_point_is_saved_with_its_names_and_units_and_read_back(fmus, tmp_path, capsys):
    """The Lag alone from x0 = 0.5 under u = 2 (k = 3, tau = 0.25 s): at t = 0.5 s its state and output are
    6 + (0.5 - 6) exp(-2) (the run's integrator's tolerance); the input the value set."""
    from linear_fmus import lag_response

    out = tmp_path / "lin"
    assert main(["linearize", str(fmus["lag"]), "--at", "0.5", "--set", "Lag.tau=0.25", "--set", "Lag.k=3",
                 "--set", "Lag.x0=0.5", "--set", "Lag.u=2", "--out", str(out)]) == 0
    capsys.readouterr()
    y = float(lag_response(0.5, u=2.0, k=3.0, tau=0.25, x0=0.5))
    m = LinearModel.load(out / "linear.npz")
    np.testing.assert_allclose([m.x[0], m.u[0], m.y[0]], [y, 2.0, y], rtol=1e-4)
    assert m.y[0] == m.x[0]   # y = x, exactly
    point = json.loads((out / "linear.json").read_text())["operating_point"]
    assert point["time"] == 0.5
    assert point["states"] == [{"name": "Lag.x", "unit": "", "value": m.x[0]}]
    assert point["inputs"] == [{"name": "Lag.u", "unit": "", "value": 2.0}]
    assert point["outputs"] == [{"name": "Lag.y", "unit": "", "value": m.y[0]}]
    mat = loadmat(out / "linear.mat")
    np.testing.assert_array_equal(np.ravel(mat["x"]), m.x)


def test_a_realisation_saves_the_point_of_its_inputs_and_outputs_not_of_its_coordinates(fmus, tmp_path, capsys):
    """Co-simulation, the loop lag -> ctrl (kp = -3) -> lag (k = 2, tau = 0.5 s) from x0 = 1, broken at the
    controller's output: the point's input (lag.u) and output (ctrl.y) at t = 0.5 s are the run's there
    (a run to the same time, bit for bit); the realisation's states have no value at the point (nan, null)."""
    from wmr_cosim.cosim import Execution
    from wmr_cosim.runner import load_plan

    scenario = _loop_scenario(tmp_path, fmus, "co-simulation")
    scenario.write_text(scenario.read_text().replace("k = 2.0\n", "k = 2.0\nx0 = 1.0\n"))
    out = tmp_path / "lin"
    assert main(["linearize", str(scenario), "--at", "0.5", "--break", "ctrl.y->lag.u", "--steps", "100",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    m = LinearModel.load(out / "linear.npz")
    ex = Execution(load_plan(scenario), None)
    try:
        ex.initialize()
        ex.step_to(0.5)
        expected_u, expected_y = float(ex.get("lag.u")), float(ex.get("ctrl.y"))
    finally:
        ex.close()
    assert (m.inputs, m.outputs) == (["lag.u"], ["ctrl.y"])
    assert (m.u[0], m.y[0]) == (expected_u, expected_y) and expected_y != 0.0
    assert np.isnan(m.x).all() and m.x.size == len(m.states)
    point = json.loads((out / "linear.json").read_text())["operating_point"]
    assert [s["value"] for s in point["states"]] == [None] * len(m.states)


def test_the_plots_are_titled_by_the_loop_without_choosing_a_backend(fmus, tmp_path, capsys):
    import matplotlib
    from PIL import Image

    from wmr_cosim.runs.linear_model import linearize
    from wmr_cosim.runs.loop_plot import loop_figures

    lin = linearize(_loop_scenario(tmp_path, fmus), at=0.25, breaks=("ctrl.y", "lag.u"))
    bode, nyquist = loop_figures(lin.loop)
    assert bode.get_suptitle() == "Loop broken at ctrl.y -> lag.u, t = 0.25 s: L = -G"
    assert nyquist.get_suptitle() == "Loop broken at ctrl.y -> lag.u, t = 0.25 s: Nyquist of L = -G"
    # the margins line over the Bode plot: every crossover (here none of the phase; L = 6 / (0.5 s + 1))
    pm = 180.0 - np.degrees(np.arctan(np.sqrt(35.0)))
    assert bode.axes[0].get_title() == f"GM inf; PM {pm:.4g} deg at {np.sqrt(35.0) / 0.5:.4g} rad/s"
    before = matplotlib.get_backend()
    matplotlib.use("svg")   # a backend of the caller's: the plots must leave it as it is
    try:
        assert main(["linearize", str(_loop_scenario(tmp_path, fmus)), "--at", "0.25", "--break", "ctrl.y->lag.u",
                     "--out", str(tmp_path / "o")]) == 0
        assert matplotlib.get_backend() == "svg"
    finally:
        matplotlib.use(before)
    capsys.readouterr()
    with Image.open(tmp_path / "o" / "bode.png") as im:
        assert im.text["Title"] == "Loop broken at ctrl.y -> lag.u, t = 0.25 s: L = -G"


@pytest.mark.parametrize("algorithm,delay", [("gauss-seidel", 0.5), ("jacobi", 1.5)])
def test_a_continuous_loop_is_shown_beside_the_co_simulated_one(fmus, tmp_path, capsys, algorithm, delay):
    """L = 6 / (0.5 s + 1) at 10 ms: the co-simulated loop's phase margin is short of the continuous one's by
    w_c h d at the gain crossover w_c = sqrt(35) / 0.5, to the O(h^2) left out: Gauss-Seidel (lag, ctrl)
    adds the lag's hold alone (d = 1/2: the controller reads the lag at t_k+1), Jacobi a step more (d = 3/2:
    the controller's output at t_k+1 is what it made of the lag at t_k). The largest step within the budget
    ~ budget / (w_c d); printed and in linear.json."""
    out = tmp_path / "loop"
    scenario = _loop_scenario(tmp_path, fmus)
    scenario.write_text(scenario.read_text().replace("step = 0.01\n", f'step = 0.01\nalgorithm = "{algorithm}"\n'))
    assert main(["linearize", str(scenario), "--break", "ctrl.y->lag.u", "--phase-budget", "3", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    wc = np.sqrt(35.0) / 0.5
    cost = np.degrees(wc * 0.01 * delay)
    def strict(constant: str) -> None:
        raise AssertionError(f"linear.json holds {constant}: not JSON")
    c = json.loads((out / "linear.json").read_text(), parse_constant=strict)["coupling"]
    assert c["algorithm"] == algorithm and c["step_s"] == 0.01 and c["phase_budget_deg"] == 3.0
    assert c["phase_cost_deg"] == pytest.approx(cost, rel=0.05)
    assert c["cosimulated"]["phase_margin_deg"] == pytest.approx(c["continuous"]["phase_margin_deg"] - c["phase_cost_deg"])
    assert c["largest_step_s"] == pytest.approx(0.01 * 3.0 / cost, rel=0.1) and c["largest_step_limit"] == "the budget"
    assert f"the loop as {algorithm} realises it at the step 0.01 s" in printed
    assert f"the coupling costs {c['phase_cost_deg']:.4g} deg" in printed
    assert f"the largest step that keeps the cost within 3 deg: {c['largest_step_s']:.4g} s" in printed


@pytest.mark.parametrize("budget", ["0", "-1", "nan", "inf", "abc"])
def test_a_phase_budget_that_is_not_a_positive_finite_angle_is_refused(fmus, tmp_path, capsys, budget):
    out = tmp_path / "o"
    _one_line(capsys, main(["linearize", str(_loop_scenario(tmp_path, fmus)), "--break", "ctrl.y->lag.u",
                            f"--phase-budget={budget}", "--out", str(out)]), "--phase-budget", "finite")
    assert not out.exists()


def test_a_phase_budget_where_no_coupling_cost_is_derived_is_refused(fmus, tmp_path, capsys):
    """--phase-budget bounds the step of a continuous loop under Gauss-Seidel or Jacobi: without a break, for a
    model realised from responses, or under another algorithm it could not be honoured: refused, named."""
    scenario, out = _loop_scenario(tmp_path, fmus), tmp_path / "o"
    _one_line(capsys, main(["linearize", str(scenario), "--inputs", "lag.u", "--phase-budget", "2", "--out", str(out)]),
              "--phase-budget", "no loop is broken")
    _one_line(capsys, main(["linearize", str(scenario), "--break", "ctrl.y->lag.u", "--discrete", "--steps", "50",
                            "--phase-budget", "2", "--out", str(out)]), "--phase-budget", "realised from pulse responses")
    iterated = tmp_path / "iterated.toml"
    iterated.write_text(scenario.read_text().replace("step = 0.01\n", 'step = 0.01\nalgorithm = "iterated"\n'))
    _one_line(capsys, main(["linearize", str(iterated), "--break", "ctrl.y->lag.u", "--phase-budget", "2",
                            "--out", str(out)]), "--phase-budget", "the algorithm is iterated")
    assert not out.exists()

@pytest.mark.slow
def test_g1_pulsed_beyond_its_encoder_fails_in_one_line(tmp_path):
    """The issue's case: G1's loop pulsed by 1e10 at the right torque; the encoder's count no longer fits a C
    long and the sensor (pythonfmu) leaves its Python error behind its fmi2GetInteger: the run fails there,
    in one line naming the sensor, the call and the error (it was a segmentation fault in fmi2FreeFMUstate)."""
    p = _shell("g1_learn.toml", "--at", "0.5", "--break", "controller.u1->plant.u1", "--pulse", "1e10", "--steps",
               "5", "--out", str(tmp_path / "o"))
    assert p.returncode == 1, (p.returncode, p.stderr[-3000:])
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, p.stderr
    for words in ("the response to a pulse of +1e+10 at plant.u1 from t = 0.5 s failed", "sensor: fmi2Get",
                  "fmi2GetInteger: OverflowError"):
        assert words in p.stderr, p.stderr


# ---------------------------------------------------------------- a Model Exchange FMU's discrete inputs
def test_an_fmu_alone_is_linearised_from_its_continuous_inputs_only(tmp_path, capsys):
    """The Reference FMU Feedthrough as Model Exchange: its discrete input is set at events only (FMI 2.0,
    3.2.3), so the model's inputs are the continuous one; D = [1, 0] (the continuous output passes it through,
    the discrete output does not see it between events). Named on its own, the discrete input is refused
    before the run."""
    from reference_fmus import REF

    ft = REF / "fmi2" / "Feedthrough.fmu"
    out = tmp_path / "lin"
    assert main(["linearize", str(ft), "--out", str(out)]) == 0
    capsys.readouterr()
    m = LinearModel.load(out / "linear.npz")
    assert m.inputs == ["Feedthrough.Float64_continuous_input"]
    np.testing.assert_allclose(m.D, [[1.0], [0.0]], atol=1e-9)
    out2 = tmp_path / "lin2"
    _one_line(capsys, main(["linearize", str(ft), "--inputs", "Feedthrough.Float64_discrete_input", "--out",
                            str(out2)]), "--inputs", "discrete input", "--discrete")
    assert not out2.exists()
