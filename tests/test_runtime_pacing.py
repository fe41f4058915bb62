"""Real-time pacing (cosim.runtime.pacing) against a simulated wall clock: the due time of each step, the boundary
between on time and late, the first wait starting the clock, and the figures and line reported."""
from __future__ import annotations

import pytest

from cosim_support import FakeClock
from wmr_cosim.cosim.runtime import pacing
from wmr_cosim import cosim
from wmr_cosim.cosim.runtime.execution import Execution
from wmr_cosim.cosim.runtime.observers import Observer


@pytest.fixture
def clock(monkeypatch) -> FakeClock:
    c = FakeClock(0.0)
    monkeypatch.setattr(pacing.time, "sleep", c.sleep)
    return c


@pytest.mark.parametrize("factor", [0, -2.5, float("nan"), "1"])
def test_a_bad_factor_is_named(factor):
    with pytest.raises(ValueError) as info:
        pacing.Pacer(factor)
    assert str(info.value) == f"real-time factor {factor!r}: must be a number > 0"


def test_due_times_count_from_the_start_time_of_the_run(clock):
    clock.now = 50.0
    p = pacing.Pacer(4.0, _clock=clock)
    p.start(10.0)                       # simulated 10 s is wall 50 s; step to 12 s is due at 50 + 2/4
    p.wait(12.0)
    assert clock.now == pytest.approx(50.5) and p.overruns == 0 and p.steps == 1


def test_the_first_wait_without_start_starts_the_clock_at_its_time(clock):
    clock.now = 7.0
    p = pacing.Pacer(1.0, _clock=clock)
    p.wait(3.0)                         # not a step: simulated 3 s is now
    assert p.steps == 0 and clock.slept == []
    p.wait(3.25)
    assert clock.now == pytest.approx(7.25) and p.steps == 1 and p.overruns == 0


def test_a_step_done_exactly_at_its_due_time_is_on_time(clock):
    clock.now = 100.0
    p = pacing.Pacer(1.0, _clock=clock)
    p.start(0.0)
    clock.now = 101.0
    p.wait(1.0)
    assert p.overruns == 0 and clock.slept == [] and p.summary()["late_max_s"] == 0.0


def test_lateness_is_reported_to_the_microsecond(clock):
    p = pacing.Pacer(1.0, _clock=clock)
    p.start(0.0)
    clock.now = 1.0 + 1.23456e-6        # late by 1.23456 us, rounded to 1 us
    p.wait(1.0)
    s = p.summary()
    assert s == {"factor": 1.0, "steps": 1, "overruns": 1, "late_max_s": 1e-6, "late_mean_s": 1e-6}


def test_the_average_lateness_is_shown_in_milliseconds(clock):
    p = pacing.Pacer(1.0, _clock=clock)
    p.start(0.0)
    clock.now = 1.0 + 0.0999            # 99.9 ms late
    p.wait(1.0)
    assert p.describe() == "real time x1: 1 of 1 steps finished late (by up to 99.9 ms, 99.9 ms on average)"


# ---------------------------------------------------------------------- through a run
class _Work(Observer):
    """Each step's work on the fake wall clock: ``work[k]`` [s] (else ``default``) passes before the step's
    pacing (observers are called before it)."""

    per_step = True

    def __init__(self, clock: FakeClock, work: dict[int, float], default: float) -> None:
        self.clock, self.work, self.default = clock, work, default

    def stepped(self, ex: Execution, k: int) -> None:
        self.clock.now += self.work.get(k, self.default)


def _paced_dahlquist(clock, tmp_path, start: float, stop: float, step: float, factor: float, now: float) -> Execution:
    """An execution of the Reference FMU Dahlquist from ``start`` to ``stop`` [s] in steps of ``step`` [s],
    paced at ``factor`` x real time by the fake ``clock`` (set to ``now`` [s])."""
    from reference_fmus import REF

    doc = {"experiment": {"start": start, "stop": stop, "step": step},
           "instances": {"d": {"fmu": str(REF / "fmi2" / "Dahlquist.fmu")}}, "record": {"variables": ["d.x"]}}
    clock.now = now
    ex = Execution(cosim.resolve(cosim.parse(doc, "paced.toml")), tmp_path / "out", real_time=factor)
    assert ex.pacer is not None
    ex.pacer._clock = clock
    return ex


def test_each_step_of_a_run_completes_no_earlier_than_its_due_time(clock, tmp_path):
    """A run from 0.5 s in steps of h = 10 ms at 4x real time, each step taking 1 ms of wall time, step 4
    taking 9 ms: step k completes (the pacing returns) exactly at its due time wall0 + k h / 4 = wall0 +
    2.5 k ms; steps 4 to 8 are late (never held, never skipped), and since the due times are absolute,
    steps 9 and 10 are back on them."""
    ex = _paced_dahlquist(clock, tmp_path, 0.5, 0.6, 0.01, 4.0, 1000.0)
    assert ex.pacer is not None
    done: list[tuple[float, float]] = []     # (simulated time, wall time) when each step's pacing returned
    wait = ex.pacer.wait

    def recorded(t: float) -> None:
        wait(t)
        done.append((t, clock.now))
    ex.pacer.wait = recorded                 # type: ignore[method-assign]
    ex.initialize()
    ex.add_observer(_Work(clock, {4: 0.009}, 0.001))
    wall0 = clock.now                        # the clock starts with the first step
    try:
        assert ex.simulate_until() == "ok"
    finally:
        res = ex.close()
    assert res.status == "ok" and [t for t, _ in done] == pytest.approx([0.5 + 0.01 * k for k in range(1, 11)])
    late = {4: 0.0165, 5: 0.0175, 6: 0.0185, 7: 0.0195, 8: 0.0205}   # [s] after wall0: the work's own end
    for k, (_, wall) in enumerate(done, start=1):
        due = wall0 + k * 0.01 / 4.0
        assert wall >= due - 1e-12, (k, wall - wall0)                          # never before its due time
        assert wall == pytest.approx(wall0 + late.get(k, k * 0.0025), abs=1e-12), (k, wall - wall0)
    assert (ex.pacer.steps, ex.pacer.overruns) == (10, 5)
    assert ex.pacer.late_max_s == pytest.approx(0.0165 - 0.01, abs=1e-12)
    assert ex.pacer.late_sum_s == pytest.approx(0.0065 + 0.005 + 0.0035 + 0.002 + 0.0005, abs=1e-12)


def test_the_clock_of_a_run_stepped_in_parts_starts_once(clock, tmp_path):
    """Stepped in two calls with a pause of 1 s between them (the Python API's run.step): the due times
    stay those of the first call's clock, so the steps after the pause are late until it is made up, none
    held; each step takes no wall time here."""
    ex = _paced_dahlquist(clock, tmp_path, 0.0, 2.0, 0.5, 1.0, 10.0)
    assert ex.pacer is not None
    ex.initialize()
    try:
        ex.step(2)                       # due at 10.5 and 11
        assert clock.now == pytest.approx(11.0, abs=1e-12) and ex.pacer.overruns == 0
        clock.now += 1.0                 # the script pauses: 12 s
        ex.step(2)                       # due at 11.5 (late by 0.5 s) and 12 (on time)
        assert clock.now == pytest.approx(12.0, abs=1e-12)
        assert (ex.pacer.steps, ex.pacer.overruns) == (4, 1)
        assert ex.pacer.late_max_s == pytest.approx(0.5, abs=1e-12)
    finally:
        ex.close()
