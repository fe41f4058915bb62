"""Real-time pacing (cosim.pacing) against a simulated wall clock: the due time of each step, the boundary
between on time and late, the first wait starting the clock, and the figures and line reported."""
from __future__ import annotations

import pytest

from cosim_support import FakeClock
from wmr_cosim.cosim import pacing


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
