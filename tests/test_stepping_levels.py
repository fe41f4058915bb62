"""Gauss-Seidel with instances stepped at once by levels ([experiment] workers = N, algorithm
"gauss-seidel"): the levels from the connections, each level's instances at once, the rows of the serial
Gauss-Seidel run bit for bit."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim import cli
from wmr_cosim import cosim
from wmr_cosim.cosim.stepping.graph import levels

from c_fmu_support import build_probe
from cosim_support import write_document
from reference_fmus import REF

FT2 = str(REF / "fmi2" / "Feedthrough.fmu")


@pytest.fixture(scope="module")
def burn(tmp_path_factory) -> Path:
    return build_probe(tmp_path_factory.mktemp("probes"), "Burn", BURN_US=20)


def _run(doc: dict[str, Any], out: Path) -> tuple[cosim.RunResult, np.ndarray]:
    res = cosim.run(cosim.resolve(cosim.parse(doc, "gs.toml")), out, progress=False)
    assert res.status == "ok", res.message
    return res, np.load(out / "signals.npy")


def _serial_and_parallel(doc: dict[str, Any], tmp_path: Path, workers: int = 2
                         ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    doc["experiment"]["workers"] = 1
    _, serial = _run(doc, tmp_path / "serial")
    doc["experiment"]["workers"] = workers
    res, par = _run(doc, tmp_path / "par")
    return serial, par, res.summary["stepping"]


def chains(probe: Path, isolate: tuple[bool, ...] = (False,) * 4) -> dict[str, Any]:
    """Two independent chains a0 -> a1 and b0 -> b1, in the order a0, b0, a1, b1; each chain's end feeds
    its start back (the previous step's value under Gauss-Seidel)."""
    names = ["a0", "b0", "a1", "b1"]
    inst = {m: {"fmu": str(probe), "isolate": isolate[i], "parameters": {"p": 0.4 + 0.1 * i}}
            for i, m in enumerate(names)}
    conns = [{"from": "a0.y", "to": "a1.u"}, {"from": "b0.y", "to": "b1.u", "factor": 0.5},
             {"from": "a1.y", "to": "a0.u", "factor": 0.25}, {"from": "b1.y", "to": "b0.u", "factor": -0.25}]
    return {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.001, "algorithm": "gauss-seidel",
                           "order": names},
            "instances": inst, "connections": conns, "record": {"variables": [f"{m}.y" for m in names]}}


def test_two_independent_chains_step_at_once_level_by_level_bit_for_bit(burn, tmp_path):
    """The chains' starts are one level, their ends the next: each level's two C FMUs in two lanes (the
    first steps measured in threads), the rows of serial Gauss-Seidel bit for bit."""
    serial, par, st = _serial_and_parallel(chains(burn), tmp_path)
    assert par.tobytes() == serial.tobytes() and np.ptp(par["a1.y"]) > 0.0
    assert st["algorithm"] == "gauss-seidel"
    assert st["levels"] == [["a0", "b0"], ["a1", "b1"]]
    assert st["in_threads"] == [["a0"], ["b0"], ["a1"], ["b1"]]
    assert st["steps_in_threads"] >= 2 * 16 and st["steps_in_threads"] + st["steps_on_the_master_alone"] == 200
    assert st["overlap"] is not None and st["overlap"] > 0.0


def test_isolated_chains_step_at_once_beside_chains_in_threads(burn, tmp_path):
    """Chain a's instances in child processes, chain b's in this process: each level's child and thread
    step together, the serial rows."""
    serial, par, st = _serial_and_parallel(chains(burn, (True, False, True, False)), tmp_path)
    assert par.tobytes() == serial.tobytes()
    assert st["stepped_at_once"] == ["a0", "a1"] and st["in_this_process"] == ["b0", "b1"]


def test_an_instance_that_feeds_one_before_it_is_not_read_before_its_time(tmp_path, burn):
    """Order c, f, a: c feeds f (this step's value), a feeds f back (the previous step's): a may step with f
    but not before it.  Were a a level below f, f would read a's output of this step: the rows show it."""
    doc = {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.001, "algorithm": "gauss-seidel",
                          "order": ["c", "f", "a"]},
           "instances": {"c": {"fmu": str(burn), "parameters": {"p": 0.5}}, "f": {"fmu": FT2},
                         "a": {"fmu": str(burn), "parameters": {"p": 0.7}}},
           "connections": [{"from": "c.y", "to": "f.Float64_continuous_input"},
                           {"from": "a.y", "to": "f.Float64_discrete_input"}],
           "record": {"variables": ["c.y", "f.Float64_continuous_output", "f.Float64_discrete_output", "a.y"]}}
    serial, par, st = _serial_and_parallel(doc, tmp_path)
    assert st["levels"] == [["c"], ["f", "a"]]
    assert par.tobytes() == serial.tobytes() and np.ptp(par["f.Float64_discrete_output"]) > 0.0


def test_a_connection_of_integers_orders_the_levels_as_a_float_one(tmp_path):
    """Stair's Integer counter (one more each second, in its step) read into a Feedthrough (an FMI get and
    set, not a copy of the row) puts the Feedthrough a level above: it reads the count of this step, as in
    the serial run."""
    doc = {"experiment": {"start": 0.0, "stop": 3.0, "step": 0.1, "algorithm": "gauss-seidel",
                          "order": ["stair", "f"]},
           "instances": {"stair": {"fmu": str(REF / "fmi2" / "Stair.fmu")}, "f": {"fmu": FT2}},
           "connections": [{"from": "stair.counter", "to": "f.Int32_input"}],
           "record": {"variables": ["stair.counter", "f.Int32_output"]}}
    serial, par, st = _serial_and_parallel(doc, tmp_path)
    assert st["levels"] == [["stair"], ["f"]]
    assert par.tobytes() == serial.tobytes() and np.ptp(par["f.Int32_output"]) > 0
    assert np.array_equal(par["f.Int32_output"], par["stair.counter"])   # (this step's count)


@pytest.mark.parametrize("fed_by, expect", [
    ([set(), set(), {0}, {1}], [[0, 1], [2, 3]]),            # two chains
    ([set(), {0}, {1}], [[0], [1], [2]]),                     # one chain
    ([set(), {0, 2}, set()], [[0], [1, 2]]),                  # 2 feeds 1 back: not below it
    ([{2}, set(), set()], [[0, 1, 2]]),                       # a feedback alone: one level
    ([{0}, {1}], [[0, 1]]),                                   # each feeds itself
    ([], []),
])
def test_levels(fed_by, expect):
    assert levels(len(fed_by), fed_by) == expect


def test_check_names_the_levels_and_says_when_workers_are_more_than_can_step(burn, tmp_path, capsys):
    path = write_document(tmp_path / "gs.toml", {**chains(burn), "experiment": {
        **chains(burn)["experiment"], "workers": 8}})
    code = cli.main(["check", str(path)])
    out = capsys.readouterr().out
    assert code == 0
    note = next(line for line in out.splitlines() if "note: workers" in line)
    assert "Gauss-Seidel by levels, the instances of a level (they do not feed each other) at once: a0, b0 | a1, b1" \
        in note
    assert "a0, b0, a1, b1 (C FMUs in this process) in 2 lanes" in note
    assert note.endswith("more workers than instances that can step at once (2): 2 workers will be busy at most")
