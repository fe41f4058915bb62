"""Who feeds whom: what ``check`` prints of the coupling (its coupling loops, Gauss-Seidel's levels under
``workers``) is what the run steps by (the iterated coupling's loops, the parallel levels), and the graph the
run is given is the one its copies make, for the shipped scenarios and for generated wirings of Reference
FMUs (Float64 copies and connections of other types, overrides that cut a copy)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from wmr_cosim import cosim
from wmr_cosim.cosim.plan.loops import describe_coupling
from wmr_cosim.cosim.stepping.graph import FeedGraph, levels, strongly_connected

from reference_fmus import REF

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted(p for p in (ROOT / "scenarios").rglob("*.toml")
                 if p.name != "paper.toml" and not p.name.startswith(("sweep-", "falsify-")))


def _graph_of_copies(ios: list[Any]) -> tuple[list[set[int]], list[set[int]]]:
    """Who feeds whom as the run's instances are wired now, read from their copies (the row's outputs of
    which instance each copy reads) and their other connections, without the plan's graph."""
    owner = {id(io.out_val): i for i, io in enumerate(ios)}
    index = {io.name: i for i, io in enumerate(ios)}
    copies = [{owner[id(c.src)] for c in io.copies if id(c.src) in owner} for io in ios]
    return copies, [copies[i] | {index[n] for n in io.reads} for i, io in enumerate(ios)]


def _loops_of(ios: list[Any]) -> list[list[str]]:
    copies, _ = _graph_of_copies(ios)
    succ: list[list[int]] = [[] for _ in ios]
    for b, srcs in enumerate(copies):
        for a in sorted(srcs):
            succ[a].append(b)
    return [[ios[i].name for i in comp] for comp in strongly_connected(len(ios), succ)
            if len(comp) > 1 or comp[0] in copies[comp[0]]]


def _levels_of(ios: list[Any]) -> list[list[str]]:
    return [[ios[i].name for i in lv] for lv in levels(len(ios), _graph_of_copies(ios)[1])]


def _printed_loops(plan: Any) -> list[list[str]]:
    """The coupling loops as ``check`` prints them."""
    return [line.split(":")[0].removeprefix("coupling loop ").split(" <-> ")
            for line in describe_coupling(plan.coupling, plan.scenario.algorithm) if line.startswith("coupling loop ")]


def _printed_levels(plan: Any) -> list[list[str]]:
    """Gauss-Seidel's levels as ``check`` prints them (its note on ``workers``)."""
    head = "the instances of a level (they do not feed each other) at once: "
    (note,) = [n for n in plan.notes if head in n]
    return [g.split(", ") for g in note.split(head)[1].split(";")[0].split(" | ")]


def _agree(plan: Any, steps: int = 0) -> Any:
    """Initialise the plan's run (and take ``steps``): the graph the algorithm was given is the one its
    instances' copies make, and the groups it steps by are those ``check`` prints.  Returns the execution's
    algorithm's summary."""
    with cosim.Execution(plan, None) as ex:
        ex.initialize()
        if steps:
            ex.step(steps)
        alg, ios = ex.algorithm, ex.ios
        assert alg.feeds is not None
        copies, depends = _graph_of_copies(ios)
        assert [set(s) for s in alg.feeds.copies] == copies and alg.feeds.depends == depends
        assert alg.feeds.named(alg.feeds.loops) == _loops_of(ios)
        if not steps:   # (no override has cut a copy yet: the plan's graph itself)
            assert alg.feeds == plan.feeds and _printed_loops(plan) == _loops_of(ios)
        summary = alg.summary()
        if plan.scenario.workers > 1 and plan.scenario.algorithm == "gauss-seidel":
            assert summary["levels"] == _levels_of(ios)
            if not steps:
                assert summary["levels"] == _printed_levels(plan)
        if plan.scenario.algorithm == "iterated":   # (its summary keeps the loops it stepped before, too)
            assert [lp.names for lp in alg.step.loops.values()] == _loops_of(ios)
            if not steps:
                assert [lp["instances"] for lp in summary["loops"]] == _printed_loops(plan)
        return summary


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT / "scenarios")))
def test_the_shipped_scenarios_run_by_the_graph_check_prints(path):
    from wmr_cosim.runner import load_plan

    plan = load_plan(path, {"experiment.workers": 2})
    assert _printed_loops(plan) == plan.feeds.named(plan.feeds.loops) != []
    _agree(plan)


FLOAT_OUT = ("Float64_continuous_output", "Float64_discrete_output")
PORTS = {"Float64_continuous_input": FLOAT_OUT, "Float64_discrete_input": FLOAT_OUT,
         "Int32_input": ("Int32_output",), "Boolean_input": ("Boolean_output",)}


@st.composite
def wirings(draw: Any) -> dict[str, Any]:
    """2 to 4 Feedthroughs, each input connected (or not) to an output of its type of any instance, itself
    included; perhaps an override of a Float64 input, or of an output, from the second step on."""
    n = draw(st.integers(2, 4))
    names = [f"f{i}" for i in range(n)]
    conns = []
    for dst in names:
        for port, outs in PORTS.items():
            src = draw(st.sampled_from([None, *names]))
            if src is not None:
                conns.append({"from": f"{src}.{draw(st.sampled_from(outs))}", "to": f"{dst}.{port}"})
    events = []
    floats = [c for c in conns if c["to"].split(".")[1].startswith("Float64")]
    if floats and draw(st.booleans()):
        c = draw(st.sampled_from(floats))
        events.append({"time": 0.002, "variable": c[draw(st.sampled_from(["from", "to"]))], "action": "override",
                       "value": 1.0})
    return {"instances": {m: {"fmu": str(REF / "fmi2" / "Feedthrough.fmu")} for m in names},
            "connections": conns, "events": events}


@settings(max_examples=40, deadline=None, derandomize=True, database=None, print_blob=False,
          suppress_health_check=list(HealthCheck))
@given(wiring=wirings(), algorithm=st.sampled_from(["iterated", "gauss-seidel"]))
def test_generated_wirings_run_by_the_graph_check_prints(wiring, algorithm):
    """Iterated: its loops are check's coupling loops; Gauss-Seidel with two workers: its levels are
    check's; after an override cut a copy, both follow the copies as they are."""
    doc = {"experiment": {"start": 0.0, "stop": 0.005, "step": 0.001, "algorithm": algorithm,
                          "workers": 2 if algorithm == "gauss-seidel" else 1},
           **{k: v for k, v in wiring.items() if v}}
    plan = cosim.resolve(cosim.parse(doc, "wiring.toml"))
    _agree(plan)
    if wiring["events"]:
        _agree(plan, steps=4)


def test_an_override_that_cuts_the_loop_leaves_nothing_to_iterate():
    """Two Feedthroughs in a Float64 ring: one coupling loop, iterated; the override of one of its inputs
    cuts it, and the iterated coupling then steps them one after the other (no loop)."""
    ft = str(REF / "fmi2" / "Feedthrough.fmu")
    doc = {"experiment": {"start": 0.0, "stop": 0.005, "step": 0.001, "algorithm": "iterated"},
           "instances": {"a": {"fmu": ft}, "b": {"fmu": ft}},
           "connections": [{"from": "a.Float64_continuous_output", "to": "b.Float64_continuous_input"},
                           {"from": "b.Float64_continuous_output", "to": "a.Float64_continuous_input"}],
           "events": [{"time": 0.002, "variable": "b.Float64_continuous_input", "action": "override", "value": 1.0}]}
    plan = cosim.resolve(cosim.parse(doc, "ring.toml"))
    assert _printed_loops(plan) == [["a", "b"]]
    assert plan.feeds == FeedGraph.of(["a", "b"], [("a", "b", True), ("b", "a", True)])
    with cosim.Execution(plan, None) as ex:
        ex.initialize()
        assert ex.algorithm.feeds.named(ex.algorithm.feeds.loops) == [["a", "b"]]
        ex.step(4)
        assert ex.algorithm.feeds.loops == [] and ex.algorithm.step.loops == {}
