"""Parallel stepping (cosim.stepping.parallel: [experiment] workers = N, algorithm jacobi, isolated instances) when
one instance fails while others step: every step started is answered (each child's step requests and the
answers awaited match), the run ends cleanly with the first failure (one line naming the instance and the
time), the rows up to the failure on disk exactly as the serial Jacobi run's, every instance's log kept, no
hang and no child process left.

Three isolated probes (tests/c_fmus/probe.c, about 20 us of work per step) in a ring with a fourth probe in
this process, on 2 workers: p0 and p1 step together, then p2, while q steps in this process beside the
first batch.  One of them fails in the step from 0.05 s: its process crashes (SIGSEGV) or its step returns
Error."""
from __future__ import annotations

import collections
import json
from pathlib import Path
from typing import Any

import numpy as np
import psutil
import pytest

from c_fmu_support import build_probe
from wmr_cosim import cosim
from wmr_cosim.cosim.instances import isolation

NAMES = ("p0", "p1", "p2", "q")
TAIL = "(isolated: the other instances are terminated and freed, the recording kept)"


@pytest.fixture(scope="module")
def probes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("probes")
    return {"burn": build_probe(out, "Burn", BURN_US=20), "crash": build_probe(out, "Crash", SEGFAULT_AT=0.05),
            "error": build_probe(out, "Error", ERROR_AT=0.05, BURN_US=20)}


@pytest.fixture
def steps(monkeypatch: pytest.MonkeyPatch) -> collections.Counter[tuple[str, str]]:
    """How many step requests each isolated instance's fast path sent ("start") and how many answers it
    awaited ("finish"), counted around the halves the parallel algorithm calls."""
    counts: collections.Counter[tuple[str, str]] = collections.Counter()
    fast_path = isolation.IsolatedInstance.fast_path

    def counted(self: isolation.IsolatedInstance, *args: Any) -> Any:
        fp = fast_path(self, *args)
        start, finish = fp.start_step, fp.finish_step
        assert start is not None and finish is not None

        def start_step(*a: Any) -> None:
            start(*a)
            counts[(self.name, "start")] += 1

        def finish_step(spin: bool = True) -> int:
            counts[(self.name, "finish")] += 1
            return finish(spin)
        fp.start_step, fp.finish_step = start_step, finish_step
        return fp
    monkeypatch.setattr(isolation.IsolatedInstance, "fast_path", counted)
    return counts


def _document(probes: dict[str, Path], failing: str, how: str, workers: int) -> dict[str, Any]:
    inst: dict[str, Any] = {n: {"fmu": str(probes[how if n == failing else "burn"]), "isolate": n != "q",
                                "parameters": {"p": 0.5 + 0.1 * i}}
                            for i, n in enumerate(NAMES)}
    for n in NAMES[:3]:
        inst[n]["step_timeout"] = 10.0
    return {"experiment": {"start": 0.0, "stop": 0.1, "step": 0.001, "algorithm": "jacobi", "workers": workers},
            "instances": inst,
            "connections": [{"from": f"{a}.y", "to": f"{b}.u", "factor": 0.3} for a, b in zip(NAMES, NAMES[1:] + NAMES[:1])],
            "record": {"variables": [f"{n}.{v}" for n in NAMES for v in ("y", "n")]}}


def _children() -> list[psutil.Process]:
    """This process's children that host isolated instances (not multiprocessing's resource tracker)."""
    out = []
    for p in psutil.Process().children(recursive=True):
        try:
            if "wmr_cosim.cosim.instances.isolation" in " ".join(p.cmdline()):
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


def _run(doc: dict[str, Any], out: Path) -> tuple[cosim.RunResult, np.ndarray, dict[str, Any]]:
    res = cosim.run(cosim.resolve(cosim.parse(doc, "par.toml")), out, progress=False)
    return res, np.load(out / "signals.npy"), json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("failing, how, message", [
    ("p0", "crash", f"p0: the FMU's process was killed by SIGSEGV during fmi2DoStep at t = 0.05 s {TAIL}"),
    ("p1", "crash", f"p1: the FMU's process was killed by SIGSEGV during fmi2DoStep at t = 0.05 s {TAIL}"),
    ("p2", "crash", f"p2: the FMU's process was killed by SIGSEGV during fmi2DoStep at t = 0.05 s {TAIL}"),
    ("p0", "error", "p0: fmi2DoStep returned Error at t = 0.05 s; last log: [Error] logStatusError: fmi2DoStep: the error asked for"),
    ("q", "error", "q: fmi2DoStep returned Error at t = 0.05 s; last log: [Error] logStatusError: fmi2DoStep: the error asked for"),
])
def test_a_failure_while_others_step_at_once_ends_the_run_as_the_serial_one(probes, steps, tmp_path, failing, how,
                                                                            message):
    res, rows, summary = _run(_document(probes, failing, how, 2), tmp_path / "parallel")
    assert summary["stepping"]["stepped_at_once"] == ["p0", "p1", "p2"]
    # the first failure, in one line; the rows up to 0.05 s; the steps done
    assert (res.status, res.message, res.steps, res.t_end) == ("failed", message, 50, 0.05)
    assert (summary["status"], summary["message"], summary["steps"], summary["t_end"]) == ("failed", message, 50, 0.05)
    assert len(rows) == 51 and rows["time"][-1] == 0.05 and rows["q.n"].tolist() == list(range(51))
    # every step started was answered (also those beside the one that failed); nothing left running
    for n in NAMES[:3]:
        assert steps[(n, "start")] == steps[(n, "finish")] >= 50, (n, dict(steps))
    # (the second batch, p2, is not started when the first fails; it is when q fails beside the first: the
    # serial run steps p2 before q, and would report p2's failure first)
    assert steps[("p0", "start")] == steps[("p1", "start")] == 51
    assert steps[("p2", "start")] == (51 if failing in ("p2", "q") else 50)
    assert _children() == []
    # the serial Jacobi run of the same system: the same end, the same rows, the same logs
    res1, rows1, summary1 = _run(_document(probes, failing, how, 1), tmp_path / "serial")
    assert (res1.status, res1.message, res1.steps, res1.t_end) == (res.status, res.message, res.steps, res.t_end)
    assert rows1.tobytes() == rows.tobytes()
    logs = sorted(p.name for p in (tmp_path / "parallel" / "logs").iterdir())
    assert logs == sorted(p.name for p in (tmp_path / "serial" / "logs").iterdir())
    assert {f"{n}.log" for n in NAMES} <= set(logs)
    for name in logs:
        assert (tmp_path / "parallel" / "logs" / name).read_bytes() == (tmp_path / "serial" / "logs" / name).read_bytes()
