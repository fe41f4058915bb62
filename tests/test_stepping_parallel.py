"""Jacobi with isolated instances stepped at once ([experiment] workers = N): the rows of the serial
Jacobi run bit for bit, with instances in this process among them; the checks; a child that dies while
the others step."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wmr_cosim import cli
from wmr_cosim import cosim

from c_fmu_support import build_probe
from cosim_support import write_document
from reference_fmus import REF


@pytest.fixture(scope="module")
def probes(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("probes")
    return {"burn": build_probe(out, "Burn", BURN_US=20), "crash": build_probe(out, "Crash", SEGFAULT_AT=0.05)}


def ring(probe: Path, n: int, workers: int, isolate: tuple[bool, ...] | None = None) -> dict[str, Any]:
    """n probes (y = p u + steps) in a ring with a Feedthrough in this process between the last and the
    first, 0.1 s of 1 ms steps."""
    names = [f"p{i}" for i in range(n)]
    iso = isolate or (True,) * n
    inst: dict[str, Any] = {m: {"fmu": str(probe), "isolate": iso[i], "parameters": {"p": 0.5 + 0.1 * i}}
                            for i, m in enumerate(names)}
    inst["ft"] = {"fmu": str(REF / "fmi2" / "Feedthrough.fmu")}
    conns = [{"from": f"{a}.y", "to": f"{b}.u"} for a, b in zip(names, names[1:])]
    conns += [{"from": f"{names[-1]}.y", "to": "ft.Float64_continuous_input", "factor": 0.3},
              {"from": "ft.Float64_continuous_output", "to": f"{names[0]}.u"}]
    return {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.001, "algorithm": "jacobi", "workers": workers},
            "instances": inst, "connections": conns,
            "record": {"variables": [f"{m}.y" for m in names] + ["ft.Float64_continuous_output"]}}


def _run(doc: dict[str, Any], out: Path) -> tuple[cosim.RunResult, np.ndarray]:
    res = cosim.run(cosim.resolve(cosim.parse(doc, "par.toml")), out, progress=False)
    return res, np.load(out / "signals.npy")


@pytest.mark.parametrize("n, workers", [(2, 2), (3, 2), (4, 4)])
def test_stepping_at_once_gives_the_serial_rows_bit_for_bit(probes, tmp_path, n, workers):
    """Up to ``workers`` children step together (3 probes on 2 workers: two batches), the Feedthrough in
    this process meanwhile: the rows equal serial Jacobi's; the summary says who stepped at once."""
    res1, serial = _run(ring(probes["burn"], n, 1), tmp_path / "serial")
    resn, par = _run(ring(probes["burn"], n, workers), tmp_path / "par")
    assert res1.status == resn.status == "ok", (res1.message, resn.message)
    assert par.tobytes() == serial.tobytes()
    assert np.ptp(par["p0.y"]) > 0.0
    st = resn.summary["stepping"]
    assert st["workers"] == workers and st["stepped_at_once"] == [f"p{i}" for i in range(n)]
    assert st["in_this_process"] == ["ft"]
    assert sorted(st["step_time_s"]) == sorted([f"p{i}" for i in range(n)] + ["ft"])
    assert all(0.0 < w < resn.wall_s for w in st["step_time_s"].values())


def test_events_that_change_the_copies_reach_the_instances_stepped_one_by_one(probes, tmp_path):
    """An override, then a bias, then the end of both on connected inputs change the copies mid-run: the
    instances stepped one by one (their part of a step made again for the new copies) give the generated
    Jacobi loop's rows bit for bit, and the events change them."""
    doc = ring(probes["burn"], 2, 2, (True, False))
    plain = {**doc, "experiment": {**doc["experiment"], "workers": 1}}
    doc = {**doc, "events": [{"time": 0.02, "variable": "p1.u", "action": "override", "value": 2.5},
                             {"time": 0.05, "variable": "p0.u", "action": "bias", "value": -0.75},
                             {"time": 0.07, "variable": "p1.u", "action": "reset"}]}
    serial_doc = {**doc, "experiment": {**doc["experiment"], "workers": 1}}
    _, untouched = _run(plain, tmp_path / "u")
    _, serial = _run(serial_doc, tmp_path / "s")
    res, par = _run(doc, tmp_path / "p")
    assert res.status == "ok" and par.tobytes() == serial.tobytes()
    assert par["p1.y"][25] != untouched["p1.y"][25] and par["p0.y"][60] != untouched["p0.y"][60]
    assert [e["action"] for e in res.events] == ["override", "bias", "reset"]


def test_isolated_and_in_process_instances_mixed(probes, tmp_path):
    doc = ring(probes["burn"], 3, 2, (True, False, True))
    _, serial = _run({**doc, "experiment": {**doc["experiment"], "workers": 1}}, tmp_path / "s")
    res, par = _run(doc, tmp_path / "p")
    assert res.status == "ok" and par.tobytes() == serial.tobytes()
    assert res.summary["stepping"]["stepped_at_once"] == ["p0", "p2"]


def test_a_child_that_dies_while_others_step_ends_the_run_with_one_line(probes, tmp_path):
    """The second probe crashes at t = 0.05 s while the first steps beside it: the run fails naming it,
    the rows before it kept, the other child answered and shut down."""
    doc = ring(probes["burn"], 2, 2)
    doc["instances"]["p1"]["fmu"] = str(probes["crash"])
    res = cosim.run(cosim.resolve(cosim.parse(doc, "par.toml")), tmp_path / "x", progress=False)
    assert res.status != "ok"
    assert "p1" in res.message and "\n" not in res.message
    sig = np.load(tmp_path / "x" / "signals.npy")
    assert 40 <= len(sig) <= 52


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_check_says_who_steps_at_once(probes, tmp_path, capsys):
    """From the file's workers, and from --workers (--parallel) over a file that says 1."""
    path = write_document(tmp_path / "p.toml", ring(probes["burn"], 2, 1))
    code, out, _ = _cli(capsys, "check", str(path))
    assert code == 0 and "note: workers" not in out
    code, out, _ = _cli(capsys, "check", str(path), "--parallel", "2")
    assert code == 0 and "note: workers = 2: p0, p1 (isolated) step at once" in out
    code, _, err = _cli(capsys, "check", str(path), "--workers", "0")
    assert code == 2 and "experiment.workers: 0: must be an integer >= 1" in err
    path = write_document(tmp_path / "p.toml", ring(probes["burn"], 2, 2))
    code, out, _ = _cli(capsys, "check", str(path))
    assert code == 0
    assert ("note: workers = 2: p0, p1 (isolated) step at once, up to 2 together; in this process meanwhile, "
            "one after another: ft") in out
    code, _, err = _cli(capsys, "run", str(path), "--out", str(tmp_path / "o"), "--quiet")
    assert code == 0, err
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["stepping"]["workers"] == 2


@pytest.mark.parametrize("change, words", [
    ({"workers": 0}, "experiment.workers: 0: must be an integer >= 1"),
    ({"workers": 1.5}, "experiment.workers: 1.5: must be an integer >= 1"),
    ({"workers": 2, "algorithm": "gauss-seidel"}, "stepping instances at once is algorithm \"jacobi\"'s"),
    ({"workers": 2, "rate": 0.002}, "ft steps at its own rate; instances at their own rates step one at a time"),
])
def test_bad_workers_are_one_line_exit_2(probes, tmp_path, capsys, change, words):
    doc = ring(probes["burn"], 2, 2)
    change = dict(change)
    if "rate" in change:
        doc["instances"]["ft"]["step"] = change.pop("rate")
    doc["experiment"].update(change)
    path = write_document(tmp_path / "bad.toml", doc)
    for command in ("check", "run"):
        code, _, err = _cli(capsys, command, str(path), *(["--out", str(tmp_path / "o"), "--quiet"]
                                                          if command == "run" else []))
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and words in lines[0], (command, err)
