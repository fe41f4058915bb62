"""The run's event table (summary.json's ``events``, the result's ``events``): the bounces of BouncingBall at
the closed form's times, Stair's time events and its end, the scenario's timed and condition events,
in the order of time, each with its source, kind and what it did."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from reference_fmus import REF
from wmr_cosim import Simulation
from wmr_cosim.cli import main
from wmr_cosim.cosim.results import event_log
from wmr_cosim import cosim


def _bounce_times(n: int, h0: float = 1.0, g: float = 9.81, e: float = 0.7) -> list[float]:
    """The closed form: the fall from h0 at rest, then each flight 2 e^k v1 / g long (v1 = sqrt(2 g h0))."""
    v1 = math.sqrt(2.0 * g * h0)
    t, out = math.sqrt(2.0 * h0 / g), []
    for k in range(n):
        out.append(t)
        t += 2.0 * e ** (k + 1) * v1 / g
    return out


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text(encoding="utf-8"))


@pytest.mark.parametrize("isolate", [False, True])
def test_bouncing_ball_under_cvode_lists_its_bounces_at_the_closed_forms_times(tmp_path, capsys, monkeypatch, isolate):
    monkeypatch.chdir(tmp_path)
    args = ["run", str(REF / "fmi2" / "BouncingBall.fmu"), "--solver", "cvode", "--set", "experiment.tolerance=1e-9",
            "--out", "out", "--quiet"]
    assert main(args + (["--isolate"] if isolate else [])) == 0, capsys.readouterr().err
    events = _summary(tmp_path / "out")["events"]
    assert len(events) >= 10
    assert {(e["source"], e["kind"]) for e in events} == {("BouncingBall", "state")}
    assert all(e["what"] == event_log.INSTANCE_KINDS["state"] for e in events)
    times = [e["time"] for e in events]
    assert max(abs(a - b) for a, b in zip(times, _bounce_times(len(times)))) < 1e-6


def test_stairs_time_events_and_its_end_are_in_the_table(tmp_path):
    sim = Simulation(file="stair.toml").experiment(stop=12.0, step=0.2)
    sim.instance("stair", REF / "fmi2" / "Stair.fmu", fields={"solver": "cvode"})
    res = cosim.run(sim.check(), tmp_path / "out", progress=False)
    assert res.status == "terminated"
    assert [(e["time"], e["kind"]) for e in res.events] == [(float(t), "time") for t in range(1, 10)] + [(9.0, "terminate")]
    assert {e["source"] for e in res.events} == {"stair"}
    assert _summary(tmp_path / "out")["events"] == json.loads(json.dumps(res.events))


def test_the_scenarios_timed_and_condition_events_with_an_instances_events_in_time_order(tmp_path):
    sim = Simulation(file="bb.toml").experiment(stop=2.0, step=0.01)
    sim.instance("ball", REF / "fmi2" / "BouncingBall.fmu", fields={"solver": "cvode", "tolerance": 1e-9})
    sim.event(time=0.2, variable="ball.e", action="set", value=0.8)
    sim.event(when="ball.h < 0.5", variable="ball.e", action="set", value=0.6)
    res = cosim.run(sim.check(), None, progress=False)
    assert res.status == "ok", res.message
    kinds = [(e["source"], e["kind"]) for e in res.events]
    timed, cond = kinds.index(("events[0]", "scenario")), kinds.index(("events[1]", "condition"))
    assert res.events[timed]["time"] == pytest.approx(0.2) and res.events[timed]["what"] == "set ball.e = 0.8"
    c = res.events[cond]
    assert c["what"].startswith("set ball.e = 0.6 (when ball.h < 0.5: true at t = ") and c["condition_time"] <= c["time"]
    assert ("ball", "state") in kinds
    assert [e["time"] for e in res.events] == sorted(e["time"] for e in res.events)
    # the first bounce: after the timed event, the condition's first firing before it
    first_bounce = kinds.index(("ball", "state"))
    assert timed < cond < first_bounce


def test_a_co_simulation_run_has_no_instance_events(tmp_path):
    sim = Simulation(file="bb.toml").experiment(stop=1.0, step=0.01)
    sim.instance("ball", REF / "fmi2" / "BouncingBall.fmu")
    res = cosim.run(sim.check(), None, progress=False)
    assert res.status == "ok" and res.events == []


def test_the_table_keeps_at_most_its_limit_and_counts_the_rest():
    many = [{"time": float(i), "source": "x", "kind": "time", "what": ""} for i in range(event_log.MAX_ENTRIES + 5)]
    kept, left_out = event_log.table([], many)
    assert len(kept) == event_log.MAX_ENTRIES and left_out == 5 and kept[-1]["time"] == event_log.MAX_ENTRIES - 1


def test_at_one_time_the_instances_entries_come_before_the_scenarios():
    scen = [{"time": 1.0, "source": "events[0]", "kind": "scenario", "what": "stop"}]
    inst = [{"time": 1.0, "source": "a", "kind": "time", "what": ""}, {"time": 0.5, "source": "a", "kind": "state",
                                                                       "what": ""}]
    kept, _ = event_log.table(scen, inst)
    assert [(e["time"], e["source"]) for e in kept] == [(0.5, "a"), (1.0, "a"), (1.0, "events[0]")]
