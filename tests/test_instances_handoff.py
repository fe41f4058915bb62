"""How the master and the child processes wait for each other (cosim.instances.handoff): the way measured
as the run goes, every child told the spin count of the way taken, the counts in summary.json."""
from __future__ import annotations

import struct
from typing import Any

import numpy as np
import pytest

from wmr_cosim import cosim
from wmr_cosim.cosim.instances import handoff
from wmr_cosim.cosim.instances.handoff import Handoff, Measured

from reference_fmus import REF


class Waiter:
    def __init__(self) -> None:
        self.spins: list[int] = []

    def set_spin(self, spin: int) -> None:
        self.spins.append(spin)


def test_the_children_block_or_spin_as_measured(monkeypatch: pytest.MonkeyPatch) -> None:
    """Blocking first (the safe way), then spinning, each PROBE cycles of the first child's requests; spinning
    measured faster is kept, and every child is told each change; the other children's requests time
    nothing."""
    now = [0.0]
    monkeypatch.setattr(handoff.time, "perf_counter", lambda: now[0])
    h = Handoff(200)
    a, b = Waiter(), Waiter()
    h.add(a)
    h.add(b)
    assert a.spins == b.spins == [0]
    P = Measured.PROBE
    for k in range(2 * P + 10):
        spinning = h.current == 1
        now[0] += 30e-6 if spinning else 60e-6
        h.tick(b)            # (not the first child: no cycle)
        h.tick(a)
    assert a.spins == b.spins == [0, 200]
    assert h.current == 1
    s = h.summary()
    assert s["spin"] == 200 and s["steps"] == {"blocked": P, "spun": P + 9}


def test_on_a_busy_machine_the_children_block(monkeypatch: pytest.MonkeyPatch) -> None:
    """Spinning that costs milliseconds a cycle loses its probe at the first such cycle."""
    now = [0.0]
    monkeypatch.setattr(handoff.time, "perf_counter", lambda: now[0])
    h = Handoff(-50)
    a = Waiter()
    h.add(a)
    for _ in range(Measured.PROBE + 20):
        now[0] += 5e-3 if h.current == 1 else 100e-6
        h.tick(a)
    assert a.spins == [0, -50, 0] and h.summary()["steps"] == {"blocked": Measured.PROBE + 18, "spun": 1}


def test_ticks_only_where_the_way_may_change_measure_as_ticks_at_every_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """A child served in C ticks only when the steps it may skip (what the last tick returned) are done,
    giving their count with the next tick: the ways taken step by step and the counts are those of ticks at
    every step, over rounds where the kept way changes (the spinning step slower after a while)."""
    now = [0.0]
    monkeypatch.setattr(handoff.time, "perf_counter", lambda: now[0])
    n = 3 * (2 * Measured.PROBE + Measured.KEEP) + 7

    def cost(k: int, way: int) -> float:
        return (30e-6 if k < 1500 else 300e-6) if way == 1 else 60e-6

    every, sparse = Handoff(200), Handoff(200)
    wa, wb = Waiter(), Waiter()
    every.add(wa)
    sparse.add(wb)
    left = skipped = 0
    ticks = 0
    for k in range(n):
        assert every.current == sparse.current, k
        now[0] += cost(k, every.current)
        every.tick(wa)
        if left:
            left, skipped = left - 1, skipped + 1
        else:
            left, skipped, ticks = sparse.tick(wb, skipped), 0, ticks + 1
    sparse.settle(wb, skipped)
    assert every.summary() == sparse.summary() and wa.spins == wb.spins and len(wa.spins) > 3
    assert ticks < n / 10


def test_the_master_writes_the_spin_count_into_the_childs_slot(tmp_path) -> None:
    """The child reads how to wait for the next request from its slot's spin word (offset 24)."""
    from wmr_cosim.cosim.instances.isolation import Child

    c = Child("d", str(tmp_path), None, "warning", 5.0, 17)
    try:
        assert c.shm.buf is not None
        assert struct.unpack_from("<q", c.shm.buf, 24)[0] == 17 and c.spin == 17
        c.set_spin(-3)
        assert struct.unpack_from("<q", c.shm.buf, 24)[0] == -3 and c.spin == -3
    finally:
        c.kill()
        c.close()


def test_a_run_with_isolated_instances_says_how_they_waited(tmp_path) -> None:
    """summary.json's handoff: every step of the first child after the first counted, blocking or spinning,
    both probed; the rows those of the run in process."""
    doc: dict[str, Any] = {
        "experiment": {"start": 0.0, "stop": 0.2, "step": 0.001},
        "instances": {"d": {"fmu": str(REF / "fmi2" / "Dahlquist.fmu"), "isolate": True},
                      "f": {"fmu": str(REF / "fmi2" / "Feedthrough.fmu"), "isolate": True}},
        "connections": [{"from": "d.x", "to": "f.Float64_continuous_input"}],
        "record": {"variables": ["d.x", "f.Float64_continuous_output"]}}
    res = cosim.run(cosim.resolve(cosim.parse(doc, "h.toml")), tmp_path / "iso", progress=False)
    assert res.status == "ok", res.message
    h = res.summary["handoff"]
    assert h["steps"]["blocked"] + h["steps"]["spun"] == 199
    assert h["steps"]["blocked"] >= Measured.PROBE and h["steps"]["spun"] >= 1
    for inst in doc["instances"].values():
        inst["isolate"] = False
    res2 = cosim.run(cosim.resolve(cosim.parse(doc, "h.toml")), tmp_path / "here", progress=False)
    assert "handoff" not in res2.summary
    assert np.load(tmp_path / "iso" / "signals.npy").tobytes() == np.load(tmp_path / "here" / "signals.npy").tobytes()
