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
    assert "note: workers = 2: p0, p1 (isolated) step at once, up to 2 together; ft (in this process) on the " \
           "master's thread\n" in out
    code, _, err = _cli(capsys, "run", str(path), "--out", str(tmp_path / "o"), "--quiet")
    assert code == 0, err
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["stepping"]["workers"] == 2


@pytest.mark.parametrize("change, words", [
    ({"workers": 0}, "experiment.workers: 0: must be an integer >= 1"),
    ({"workers": 1.5}, "experiment.workers: 1.5: must be an integer >= 1"),
    ({"workers": 2, "algorithm": "iterated"},
     "stepping instances at once is algorithm \"gauss-seidel\" or \"jacobi\"'s, not 'iterated'"),
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


# ---------------------------------------------------------------------- C FMUs in this process, in threads
@pytest.mark.parametrize("n, workers", [(2, 2), (4, 2), (4, 3)])
def test_c_fmus_in_this_process_step_in_threads_with_the_serial_rows(probes, tmp_path, n, workers):
    """Probes and the Feedthrough, all in this process, dealt to ``workers`` lanes (the master's thread
    and workers - 1 threads) in the plan's order: the rows equal serial Jacobi's bit for bit."""
    doc = ring(probes["burn"], n, 1, isolate=(False,) * n)
    res1, serial = _run(doc, tmp_path / "serial")
    doc["experiment"]["workers"] = workers
    resn, par = _run(doc, tmp_path / "par")
    assert res1.status == resn.status == "ok", (res1.message, resn.message)
    assert par.tobytes() == serial.tobytes() and np.ptp(par["p0.y"]) > 0.0
    st = resn.summary["stepping"]
    order = [f"p{i}" for i in range(n)] + ["ft"]
    lanes = min(workers, n + 1)
    assert st["in_threads"] == [order[j::lanes] for j in range(lanes)]
    assert st["stepped_at_once"] == [] and st["in_this_process"] == [] and st["alone"] == {}


def test_threads_isolated_children_and_a_model_exchange_instance_together(probes, tmp_path):
    """Two probes in child processes, two in threads, Dahlquist as Model Exchange on the master's thread
    alone (its integrator runs in Python): the serial rows; the summary says why Dahlquist steps alone."""
    doc = ring(probes["burn"], 4, 1, isolate=(True, False, True, False))
    doc["instances"]["dq"] = {"fmu": str(REF / "fmi2" / "Dahlquist.fmu"), "interface": "model-exchange"}
    doc["record"]["variables"].append("dq.x")
    res1, serial = _run(doc, tmp_path / "serial")
    doc["experiment"]["workers"] = 2
    resn, par = _run(doc, tmp_path / "par")
    assert res1.status == resn.status == "ok", (res1.message, resn.message)
    assert par.tobytes() == serial.tobytes()
    st = resn.summary["stepping"]
    assert st["stepped_at_once"] == ["p0", "p2"] and st["in_threads"] == [["p1", "ft"], ["p3"]]
    assert st["in_this_process"] == ["dq"] and "Model Exchange" in st["alone"]["dq"]


def test_a_failure_in_a_thread_ends_the_run_as_the_serial_run_ends(tmp_path):
    """Probes that return fmi2Error at t = 0.05 s, two of them in a lane's thread (their log messages sent
    from that thread): the run fails with the serial run's message and rows; each log holds the serial
    run's lines, and those of a step that the serial run, stopping at the first failure, did not take."""
    fail = build_probe(tmp_path / "fmu", "Fail", ERROR_AT=0.05, VERBOSE=True)
    doc = ring(fail, 3, 1, isolate=(False,) * 3)
    for m in ("p0", "p1", "p2"):
        doc["instances"][m]["logging"] = "all"
    res1, serial = _run(doc, tmp_path / "serial")
    doc["experiment"]["workers"] = 2
    resn, par = _run(doc, tmp_path / "par")
    assert res1.status == resn.status == "failed"
    assert resn.message == res1.message and "p0" in resn.message
    assert par.tobytes() == serial.tobytes()
    for m in ("p0", "p1", "p2"):
        assert (tmp_path / "par" / "logs" / f"{m}.log").read_text().startswith(
            (tmp_path / "serial" / "logs" / f"{m}.log").read_text())


def test_the_threaded_step_lets_go_of_the_gil_and_a_pythonfmu_fmu_has_none(built_fmus, tmp_path):
    import ctypes

    from wmr_cosim.cosim.instances import in_process

    assert not in_process.runs_python(str(_unzipped(REF / "fmi2" / "Feedthrough.fmu", tmp_path / "ft")))
    assert in_process.runs_python(str(_unzipped(built_fmus["WmrSensor"], tmp_path / "sensor")))
    lib = ctypes.CDLL(None)
    f = in_process.released(lib, "abs")
    assert not f._flags_ & ctypes._FUNCFLAG_PYTHONAPI          # a CDLL function: the call releases the GIL
    assert in_process.raw(lib, "abs")._flags_ & ctypes._FUNCFLAG_PYTHONAPI   # the usual one holds it


def _unzipped(fmu: Path, dest: Path) -> Path:
    import zipfile

    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(dest)
    return dest


def test_check_says_which_instances_step_in_threads_and_which_alone_and_why(probes, built_fmus, tmp_path, capsys):
    """Children, lanes of threads, and on the master's thread alone a Model Exchange instance and a
    pythonfmu FMU (read from its archive: its binaries hold pythonfmu's exporter), each with why."""
    doc = ring(probes["burn"], 4, 2, isolate=(True, False, True, False))
    doc["instances"]["dq"] = {"fmu": str(REF / "fmi2" / "Dahlquist.fmu"), "interface": "model-exchange"}
    doc["instances"]["sensor"] = {"fmu": str(built_fmus["WmrSensor"])}
    code, out, err = _cli(capsys, "check", str(write_document(tmp_path / "p.toml", doc)))
    assert code == 0, err
    note = next(line for line in out.splitlines() if "note: workers" in line)
    assert note.endswith("note: workers = 2: p0, p2 (isolated) step at once, up to 2 together; p1, p3, ft (C FMUs in "
                         "this process) in 2 lanes, the master's thread and 1 thread; dq on the master's thread alone "
                         "(a Model Exchange instance: its integrator runs in Python, which holds the GIL (isolate = "
                         "true steps it in a process of its own)); sensor on the master's thread alone (a pythonfmu "
                         "FMU: its step runs Python code, which holds the GIL (isolate = true steps it in a process "
                         "of its own))"), note


def test_the_faster_way_is_kept_and_kept_longer_each_time_it_wins_again():
    """Probes of each way, the faster kept, then measured again: the choice follows the measured times; the
    same way winning again is kept twice as long; another way winning is kept for KEEP again."""
    from wmr_cosim.cosim.instances.handoff import Measured

    c = Measured(2)
    P, K = c.PROBE, c.KEEP
    ways = []

    def cycles(n: int, faster: int) -> None:
        for _ in range(n):
            w = c.way()
            ways.append(w)
            c.took(w, 1e-3 if w == faster else 2e-3)
    cycles(2 * P + K, faster=0)
    assert ways[:P] == [0] * P and ways[P:2 * P] == [1] * P and ways[2 * P:] == [0] * K
    ways.clear()
    cycles(2 * P + 2 * K, faster=0)          # the same way again: kept twice as long
    assert ways[2 * P:] == [0] * 2 * K and c.keep == 2 * K
    ways.clear()
    cycles(2 * P + K, faster=1)              # the other way wins: kept for KEEP
    assert ways[:P] == [0] * P and ways[P:2 * P] == [1] * P and ways[2 * P:] == [1] * K
    assert c.taken == [2 * P + 3 * K + P, 3 * P + K]
    ways.clear()
    c2 = Measured(2)                          # one pause does not decide
    for k in range(2 * P):
        w = c2.way()
        c2.took(w, 10.0 if k == 0 else (1e-5 if w == 0 else 1e-4))
    assert c2.way() == 0
    c3 = Measured(2)                          # a way far slower than one before it loses the round at once
    for _ in range(P + 1):
        w = c3.way()
        c3.took(w, 1e-5 if w == 0 else 1e-3)
    assert c3.taken == [P, 1] and c3.way() == 0 and c3.rounds == 1


def test_every_step_is_counted_in_threads_or_on_the_master_alone(probes, tmp_path):
    doc = ring(probes["burn"], 2, 2, isolate=(False, False))
    res, _ = _run(doc, tmp_path / "par")
    st = res.summary["stepping"]
    assert st["steps_in_threads"] + st["steps_on_the_master_alone"] == 100
    assert st["steps_on_the_master_alone"] >= 16 and st["steps_in_threads"] >= 16


def test_fmi3_fmus_in_threads_beside_fmi2_ones_give_the_serial_rows(tmp_path):
    """FMI 3.0 Dahlquist and VanDerPol and an FMI 2.0 Dahlquist in this process, each feeding an FMI 3.0
    Feedthrough: stepped in two lanes, the rows of serial Jacobi bit for bit."""
    doc = {"experiment": {"start": 0.0, "stop": 1.0, "step": 0.01, "algorithm": "jacobi", "workers": 1},
           "instances": {"d3": {"fmu": str(REF / "fmi3" / "Dahlquist.fmu"), "parameters": {"k": 2.0}},
                         "vdp": {"fmu": str(REF / "fmi3" / "VanDerPol.fmu")},
                         "d2": {"fmu": str(REF / "fmi2" / "Dahlquist.fmu")},
                         "ft": {"fmu": str(REF / "fmi3" / "Feedthrough.fmu")}},
           "connections": [{"from": "d3.x", "to": "ft.Float64_continuous_input"},
                           {"from": "vdp.x0", "to": "ft.Float64_discrete_input"}],
           "record": {"variables": ["d3.x", "vdp.x0", "vdp.x1", "d2.x", "ft.Float64_continuous_output",
                                    "ft.Float64_discrete_output"]}}
    res1, serial = _run(doc, tmp_path / "serial")
    doc["experiment"]["workers"] = 2
    res2, par = _run(doc, tmp_path / "par")
    assert res1.status == res2.status == "ok", (res1.message, res2.message)
    assert par.tobytes() == serial.tobytes() and np.ptp(par["vdp.x0"]) > 0.0
    assert res2.summary["stepping"]["in_threads"] == [["d3", "d2"], ["vdp", "ft"]]


def test_workers_travel_through_ssp_and_are_in_scenario_json(probes, tmp_path):
    """Exported with workers = 3, imported: the archive's run steps its C FMUs in three lanes, with the rows
    of the scenario's own run; scenario.json says workers = 3; a bad count in the archive is one line."""
    from wmr_cosim.cosim.plan.ssp import OWN_NS, export_ssp, load_ssp

    doc = ring(probes["burn"], 3, 3, isolate=(False,) * 3)
    plan = cosim.resolve(cosim.parse(doc, str(tmp_path / "par.toml")))
    res, rows = _run(doc, tmp_path / "toml")
    assert json.loads((tmp_path / "toml" / "scenario.json").read_text())["experiment"]["workers"] == 3
    archive = export_ssp(plan, tmp_path / "par.ssp")
    arch = load_ssp(archive)
    try:
        assert arch.scenario.workers == 3
        res2 = cosim.run(cosim.resolve(arch.scenario), tmp_path / "ssp", progress=False)
        assert res2.status == "ok", res2.message
        assert len(res2.summary["stepping"]["in_threads"]) == 3
        back = np.load(tmp_path / "ssp" / "signals.npy")
        assert all(back[c].tobytes() == rows[c].tobytes() for c in rows.dtype.names)
    finally:
        arch.cleanup()
    import zipfile
    with zipfile.ZipFile(archive) as zf, zipfile.ZipFile(tmp_path / "bad.ssp", "w") as out:
        for item in zf.infolist():
            data = zf.read(item)
            if item.filename == "SystemStructure.ssd":
                data = data.replace(b'workers="3"', b'workers="three"')
                assert b"three" in data and OWN_NS.encode() in data
            out.writestr(item, data)
    with pytest.raises(cosim.ScenarioError, match=r"Experiment.workers: 'three' is not an integer"):
        load_ssp(tmp_path / "bad.ssp")
