"""FMI 3.0 co-simulation with clocks and event mode: the public synchronous-clock example (a periodic
input clock, an output clock raised at a state event and connected to a triggered input clock, a clocked
variable exchanged at its clock's ticks) run by the master equals the FMI 3.0 semantics computed from the
FMUs' equations, the instants where both clocks tick together included (dependency order); a periodic
clock of 2 ms ticks every 4th step of 0.5 ms; what the master cannot run exactly is refused at ``check`` in
one line (exit 2)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from c_fmu_support import build_ticker, ticker_scenario
from clock_fmus import build_example, expected, scenario
from wmr_cosim import cosim


@pytest.fixture(scope="module")
def example(tmp_path_factory) -> dict[str, Path]:
    return build_example(tmp_path_factory.mktemp("sync-clocks"))


def _cli(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wmr_cosim.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


def _run(tmp: Path, text: str) -> tuple[np.ndarray, cosim.Execution]:
    path = tmp / "sync.toml"
    path.write_text(text)
    plan = cosim.resolve(cosim.load(path))
    ex = cosim.Execution(plan, tmp / "out")
    ex.initialize()
    ex.simulate_until()
    res = ex.close()
    assert ex.status == "ok", ex.message
    return np.load(tmp / "out" / "signals.npy"), ex


@pytest.mark.parametrize("step, r_every", [(0.01, 10), (0.025, 4)])
def test_the_example_in_cosimulation_equals_the_fmi_semantics(example, tmp_path, step, r_every):
    n = round(10.0 / step)
    ours, ex = _run(tmp_path, scenario(example, step=step))
    want = expected(step, n, r_every)
    assert len(ours) == len(want) == n + 1
    for col, j in (("Plant.x", 1), ("Controller.ur", 2), ("Supervisor.as", 3)):
        assert ours[col].tolist() == [w[j] for w in want], col
    flips = [w[0] for a, w in zip(want, want[1:]) if a[3] != w[3]]   # (a row: the values after its events)
    assert len(flips) > 10                                    # the Supervisor's clock s rose many times ...
    sup, ctl = ex.instances["Supervisor"], ex.instances["Controller"]
    assert [t for t, c in sup.raised] == pytest.approx(flips)  # ... at its state events, raised by the FMU
    s_ticks = [t for t, c in ctl.ticked if c == "s"]
    assert s_ticks == [t for t, _ in sup.raised]              # and ticked the Controller's s at those instants
    r_ticks = [t for t, c in ctl.ticked if c == "r"]
    assert len(r_ticks) == n // r_every + 1   # (from t = 0 to the stop time, whose events end the last step)
    together = sorted({round(t, 9) for t in s_ticks} & {round(t, 9) for t in r_ticks})
    assert together == sorted({round(t, 9) for t in flips} & {round(k * step, 9) for k in range(0, n + 1, r_every)})
    assert together == {0.01: [], 0.025: [2.3, 2.8]}[step]   # both clocks tick together there


def test_both_clocks_together_take_the_new_value_first(example, tmp_path):
    """At 2.3 s (steps of 25 ms) s and r tick together: ur takes the Supervisor's new as (-1), not the
    old one: 5 + (-1) = 4 (seen in the row of 2.3 s: a row holds the values after the events of its time);
    the Controller stepping before the Supervisor is refused (its clock s would tick a step late)."""
    ours, ex = _run(tmp_path, scenario(example, step=0.025))
    assert (2.3, "s") in [(round(t, 9), c) for t, c in ex.instances["Controller"].ticked]
    assert (2.3, "r") in [(round(t, 9), c) for t, c in ex.instances["Controller"].ticked]
    i = int(np.flatnonzero(np.isclose(ours["time"], 2.3))[0])
    assert (ours["Supervisor.as"][i - 1], ours["Supervisor.as"][i]) == (1.0, -1.0)
    assert (ours["Controller.ur"][i - 1], ours["Controller.ur"][i]) == (5.0, 4.0)
    bad = tmp_path / "bad.toml"
    bad.write_text(scenario(example, step=0.025, order='["Controller", "Supervisor", "Plant"]'))
    p = _cli("check", bad)
    assert p.returncode == 2
    assert p.stderr.strip().splitlines()[-1].endswith(
        "experiment.order: Supervisor.s -> Controller.s: Supervisor must step before Controller (an output clock "
        "ticks the input clocks of the instances after it)")


@pytest.fixture(scope="module")
def ticker(tmp_path_factory) -> Path:
    return build_ticker(tmp_path_factory.mktemp("ticker"))


@pytest.mark.parametrize("interface", ["co-simulation", "model-exchange"])
def test_a_2_ms_clock_ticks_every_4th_step_of_half_a_millisecond(ticker, tmp_path, interface):
    """The Ticker's periodic clock r of 2 ms at steps of 0.5 ms: an event at every 4th communication
    point, at the end of the step that ends there (event mode entered, r set, its clocked output n read,
    the discrete states updated, step mode), n counting the ticks, the stop time's included; A's output clock o, raised at every 3rd tick, ticks B's s at that instant
    and B takes A's m of that instant (its new value: the dependency order): B.y = 2 A.m."""
    ours, ex = _run(tmp_path, ticker_scenario(ticker, interface))
    a, b = ex.instances["A"], ex.instances["B"]
    assert [round(t / 0.0005) for t, c in a.ticked if c == "r"] == list(range(0, 41, 4))   # (the stop time's too)
    assert [round(t / 0.0005) for t, c in a.ticked if c == "s"] == [2]
    assert [round(t, 9) for t, _ in a.raised] == [0.004, 0.01, 0.016]
    assert [round(t, 9) for t, c in b.ticked if c == "s"] == [0.004, 0.01, 0.016]
    k = np.arange(41)
    n_want = k // 4 + 1   # (a row: the values after the events of its time)
    assert ours["A.n"].tolist() == n_want.tolist() == ours["B.n"].tolist()
    m_want = (n_want // 3).tolist()
    assert ours["A.m"].tolist() == m_want
    assert ours["B.y"].tolist() == [2.0 * m for m in m_want]   # 2 x the m of the same tick, not the one before
    assert ours["B.u"].tolist() == m_want


def test_the_order_is_checked(ticker, tmp_path):
    """B stepping before A would take A's o, or A's m, a step late: refused at check, one line (exit 2)."""
    (tmp_path / "t.toml").write_text(ticker_scenario(ticker, order='order = ["B", "A"]'))
    p = _cli("check", tmp_path / "t.toml")
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
    assert "experiment.order: A.o -> B.s: A must step before B" in p.stderr
    text = ticker_scenario(ticker, order='order = ["B", "A"]').replace('from = "A.o"\nto = "B.s"',
                                                                       'from = "A.o"\nto = "A.s"')
    (tmp_path / "t.toml").write_text(text.replace('clock_ticks = { s = [0.001] }', "").replace(
        '[instances.B]\nfmu = "' + str(ticker) + '"', '[instances.B]\nfmu = "' + str(ticker) + '"\n'
        'clock_ticks = { s = [0.001] }'))
    p = _cli("check", tmp_path / "t.toml")
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert "experiment.order: A.m -> B.u: A must step before B" in p.stderr


@pytest.mark.parametrize("kw, field, words", [
    ({"step": "0.0003"}, "experiment.step", "0.0003 s: clock A.r ticks every 0.002 s, not a whole number of steps"),
    ({"a": 'clock_ticks = { s = [0.00025] }'}, "instances.A.clock_ticks.s", "0.00025 s is not on the grid of "
                                                                             "0.0005 s steps from 0 s"),
    ({"a": ""}, "instances.A.clock_ticks", "triggered input clock s has no source"),
    ({"a": 'clock_ticks = { s = [0.001], r = [0.002] }'}, "instances.A.clock_ticks.r",
     "Ticker.fmu has no triggered input clock 'r'"),
    ({"extra": '[[connections]]\nfrom = "A.o"\nto = "B.u"\n'}, "connections[2]",
     "A.o -> B.u: an output clock connects to an input clock only (B.u is not a clock)"),
    ({"extra": '[[connections]]\nfrom = "A.n"\nto = "A.s"\n'}, "connections[2]",
     "A.n -> A.s: an input clock is ticked by an output clock only (A.n is not a clock)"),
    ({"extra": '[[connections]]\nfrom = "A.o"\nto = "B.r"\n'}, "connections[2].to",
     "B.r is a constant clock: an output clock ticks a triggered input clock only"),
    ({"extra": '[[connections]]\nfrom = "A.s"\nto = "B.r"\n'}, "connections[2].from",
     "A.s is an input clock, not an output clock"),
    ({"extra": '[[events]]\ntime = 0.001\nvariable = "A.u"\naction = "override"\nvalue = 1.0\n'},
     "events[0].variable", "A.u: clocked by s, set at its ticks only: events on it are not supported"),
    ({"order": 'algorithm = "jacobi"'}, "experiment.algorithm", "jacobi: an instance with clocks (A) runs under "
                                                                "gauss-seidel only"),
    ({"order": "workers = 2"}, "experiment.workers", "2: an instance with clocks (A) steps in the plan's order"),
    ({"a": 'clock_ticks = { s = [0.001] }\nisolate = true'}, "instances.A.isolate",
     "not supported for an instance with clocks"),
    ({"a": 'clock_ticks = { s = [0.001] }\nstep = 0.001'}, "instances.A.step",
     "not supported for an instance with clocks"),
    ({"record": "event_rows = true"}, "record.event_rows", "rows at the events are not recorded for an instance "
                                                           "with clocks (A)"),
])
def test_bad_clock_settings_of_the_ticker_are_one_line_at_check(ticker, tmp_path, kw, field, words):
    (tmp_path / "t.toml").write_text(ticker_scenario(ticker, **kw))
    p = _cli("check", tmp_path / "t.toml")
    assert p.returncode == 2, p.stdout
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert f"{field}: {words}" in lines[0]


@pytest.mark.parametrize("interval, variability, event_mode, words", [
    ("", "fixed", True, "clock r: a fixed clock with no intervalDecimal is not supported yet"),
    ("0.002", "changing", True, "clock r: a changing input clock is not supported in co-simulation and model "
                                "exchange yet"),
    ("0.002", "countdown", True, "clock r: a countdown input clock is not supported in co-simulation and model "
                                 "exchange yet"),
    ("0.002", "constant", False, "Ticker.fmu has clocks but its co-simulation interface does not declare "
                                 "hasEventMode"),
])
def test_clocks_the_master_cannot_run_are_refused(tmp_path, interval, variability, event_mode, words):
    fmu = build_ticker(tmp_path / "fmu", interval, variability, event_mode)
    (tmp_path / "t.toml").write_text(ticker_scenario(fmu))
    p = _cli("check", tmp_path / "t.toml")
    assert p.returncode == 2, p.stdout
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "instances.A.fmu: " + words in lines[0], lines


def test_a_system_with_clocks_is_neither_exported_nor_linearised(ticker, tmp_path):
    (tmp_path / "t.toml").write_text(ticker_scenario(ticker))
    for args, words in ((("export-ssp", tmp_path / "t.toml", "--out", tmp_path / "t.ssp"),
                         "instances.A: Ticker.fmu has clocks, which cannot be exported to SSP yet"),
                        (("export-fmu", tmp_path / "t.toml", "--out", tmp_path / "T.fmu"),
                         "instances.A: Ticker.fmu has clocks (its events and clocked variables are run by the master "
                         "only): it cannot be exported as an FMU container yet"),
                        (("linearize", tmp_path / "t.toml", "--inputs", "B.u", "--outputs", "B.y", "--out",
                          tmp_path / "lin"), "instances.A: A (Ticker.fmu) has clocks: systems with clocks are not "
                                             "linearised")):
        p = _cli(*args)
        assert p.returncode == 2, (args, p.stdout, p.stderr)
        assert len(p.stderr.strip().splitlines()) == 1 and words in p.stderr, p.stderr
    assert not (tmp_path / "t.ssp").exists() and not (tmp_path / "T.fmu").exists() and not (tmp_path / "lin").exists()


@pytest.mark.parametrize("edit, field, words", [
    (("step = 0.01", "step = 0.03"), "experiment.step", "0.03 s: clock Controller.r ticks every 0.1 s, not a whole "
                                                        "number of steps"),
    (('[[connections]]\nfrom = "Supervisor.s"\nto = "Controller.s"\n', ""), "instances.Controller.clock_ticks",
     "triggered input clock s has no source"),
    (('from = "Supervisor.s"\nto = "Controller.s"', 'from = "Supervisor.s"\nto = "Plant.u_r"'), "connections[2]",
     "Supervisor.s -> Plant.u_r: an output clock connects to an input clock only (Plant.u_r is not a clock)"),
    (('from = "Supervisor.s"\nto = "Controller.s"', 'from = "Plant.x"\nto = "Controller.s"'), "connections[2]",
     "Plant.x -> Controller.s: an input clock is ticked by an output clock only (Plant.x is not a clock)"),
])
def test_bad_clock_settings_are_one_line_at_check(example, tmp_path, edit, field, words):
    text = scenario(example).replace(*edit)
    (tmp_path / "bad.toml").write_text(text)
    p = _cli("check", tmp_path / "bad.toml")
    assert p.returncode == 2, p.stdout
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert f"{field}: {words}" in lines[0]


def test_check_lists_the_clocks_and_notes_what_is_read_between_ticks(example, tmp_path):
    (tmp_path / "s.toml").write_text(scenario(example))
    p = _cli("check", tmp_path / "s.toml")
    assert p.returncode == 0, p.stderr
    out = p.stdout
    assert "Controller: co-simulation with event mode" in out
    assert "clock r: periodic input clock (constant); interval 0.1 s; clocks ur" in out
    assert "clock s: triggered input clock; clocks as; ticked by Supervisor.s" in out
    assert "clock s: output clock, raised by the FMU; clocks as; ticks Controller.s" in out
    assert ("note: Controller.ur -> Plant.u_r: the output is clocked by r, defined at its ticks only; the input "
            "holds the value of the last tick") in out


@pytest.mark.parametrize("step, r_every", [(0.01, 10), (0.025, 4)])
def test_the_example_in_model_exchange_equals_the_fmi_semantics(example, tmp_path, step, r_every):
    """The three FMUs in Model Exchange (the Plant integrated by Euler, one step per communication step):
    the Supervisor's indicator moves with its input, so its state event, and the output clock s, come at
    the communication point where the input crosses, at the start of the Supervisor's step from there (its
    input x(t_k) is the Plant's, which steps after it); the Controller, past t_k already (its r ticked at
    the end of its step to t_k), takes that tick of s at the start of its own step from t_k.  Both clocks
    tick at one instant then (3.1 s with steps of 10 ms), in two events: r, then s."""
    n = round(10.0 / step)
    ours, ex = _run(tmp_path, scenario(example, step=step, interface="model-exchange"))
    want = expected(step, n, r_every, me=True)
    # (the master's Euler steps over t_(k+1) - t_k, which may differ from h in its last bit)
    np.testing.assert_allclose(ours["Plant.x"], [w[1] for w in want], rtol=1e-12, atol=0)
    for col, j in (("Controller.ur", 2), ("Supervisor.as", 3)):
        assert ours[col].tolist() == [w[j] for w in want], col
    sup, ctl = ex.instances["Supervisor"], ex.instances["Controller"]
    flips = [a[0] for a, w in zip(want, want[1:]) if a[3] != w[3]]   # (raised at t_k, shown from t_(k+1))
    assert len(flips) > 10 and [t for t, _ in sup.raised] == pytest.approx(flips)
    assert [t for t, c in ctl.ticked if c == "s"] == [t for t, _ in sup.raised]
    r_ticks = {round(t, 9) for t, c in ctl.ticked if c == "r"}
    together = [round(t, 9) for t, c in ctl.ticked if c == "s" and round(t, 9) in r_ticks]
    assert together == sorted({round(t, 9) for t in flips} & {round(k * step, 9) for k in range(0, n + 1, r_every)})
    assert together == {0.01: [3.1], 0.025: [1.5, 3.1, 3.9]}[step]
    for t in together:   # (r at the end of the step to t, then s at the start of the step from t)
        at = [c for u, c in ctl.ticked if round(u, 9) == t]
        assert at == ["r", "s"], (t, at)


def _states(pairs: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The successive discrete states (u_r, a_s): each change once."""
    out: list[tuple[float, float]] = []
    for p in pairs:
        if not out or out[-1] != p:
            out.append(p)
    return out


def test_the_discrete_states_follow_the_published_reference(example, tmp_path):
    """The published results (synchronous_control_me_out_ref.csv; the co-simulation's
    synchronous_control_cs_out.csv) come from the example's own orchestrations (src/synchronous_control_*.c),
    which time their events otherwise than the FMI semantics the master follows.  Co-simulation: the three
    FMUs step from the same point with the inputs of that point (Jacobi: the Supervisor's x is set after
    the steps), then the events of the point where the steps end are handled, after its row is written (a
    row holds the values before those events, and is labelled with the time the steps started: a step
    late); model exchange: at each point the events first, then an explicit Euler step of the Plant, then
    the row.  Both tick r by a timer decremented by h = 10 ms and compared with 0, which its floating-point
    error makes tick every 0.11 s, not the 0.1 s the Controller declares; s ticks where the Supervisor
    reports its state event; where both are due, the Supervisor's partition runs first.  So their times,
    and the Plant's x, are not comparable with ours (r every 0.1 s from t = 0, the events of t_(k+1) at the
    end of the step that ends there, Gauss-Seidel); what is comparable is the logic: the sequence of the
    discrete states (u_r, a_s).  At steps of 10 ms, in co-simulation and in model exchange, ours is theirs,
    all of their states (110 and 109; ours has more: r ticks more often in 10 s)."""
    import csv
    src = example["Controller"].parent / "src"
    me, _ = _run(tmp_path, scenario(example, interface="model-exchange"))
    ours_me = _states(list(zip(me["Controller.ur"].tolist(), me["Supervisor.as"].tolist())))
    (tmp_path / "out").rename(tmp_path / "out-me")
    cs, _ = _run(tmp_path, scenario(example))
    ours_cs = _states(list(zip(cs["Controller.ur"].tolist(), cs["Supervisor.as"].tolist())))
    for name, n in (("synchronous_control_me_out_ref.csv", 110), ("synchronous_control_cs_out.csv", 109)):
        with open(src / name, newline="") as fh:
            ref = _states([(float(r["u_r"]), float(r["a_s"])) for r in csv.DictReader(fh)])
        assert ref[0] == (0.0, 1.0)
        ref = ref[1:]   # (their r first ticks at 0.1 s, ours at the start time)
        assert len(ref) == n and len(ours_me) > n and len(ours_cs) > n, name
        assert ours_me[:n] == ref, name
        assert ours_cs[:n] == ref, name


@pytest.mark.parametrize("interface", ["co-simulation", "model-exchange"])
def test_an_output_clock_raised_at_the_fmus_own_time_event(ticker, tmp_path, interface):
    """A's o raised at its own time event at 3 ms (t_o; not at r's ticks: every = 100): in co-simulation the
    step ending at 3 ms asks for event handling (eventHandlingNeeded), the event runs at 3 ms at the end of
    that step; in model exchange the integration stops at the time event.  Either way B's s ticks at 3 ms,
    at the end of its own step to 3 ms, with A's m of that instant: both show in the row of 3 ms."""
    text = ticker_scenario(ticker, interface,
                           a='clock_ticks = { s = [0.001] }\nparameters = { every = 100, t_o = 0.003 }')
    ours, ex = _run(tmp_path, text)
    assert [round(t, 9) for t, _ in ex.instances["A"].raised] == [0.003]
    assert [round(t, 9) for t, c in ex.instances["B"].ticked if c == "s"] == [0.003]
    assert ours["A.m"].tolist() == [0.0] * 6 + [1.0] * 35   # (a row: the values after the events of its time)
    assert ours["B.y"].tolist() == [0.0] * 6 + [2.0] * 35


def test_an_output_clock_raised_between_communication_points_ends_the_run_in_one_line(ticker, tmp_path):
    """A model exchange FMU's time event at 3.25 ms raises A's o, connected to B's s: B is at 3 ms, and
    stops at communication points only: the run ends there (exit 1), saying why."""
    text = ticker_scenario(ticker, "model-exchange",
                           a='clock_ticks = { s = [0.001] }\nparameters = { every = 100, t_o = 0.00325 }')
    (tmp_path / "t.toml").write_text(text)
    p = _cli("run", tmp_path / "t.toml", "--out", tmp_path / "out", "--quiet")
    assert p.returncode == 1, p.stderr
    first = p.stderr.strip().splitlines()[0]   # (then where what was recorded is)
    assert first.startswith("wmr-cosim: run failed: A: ")
    assert "A: output clock o raised at t = 0.00325 s, between communication points" in first
