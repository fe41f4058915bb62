"""State events of a Model Exchange FMU against FMI's domains of an event indicator, z > 0 and z <= 0
(FMI 2.0 and 3.0): an indicator that begins a step at exactly 0, at the start or after an event handled
there, is in z <= 0, so moving above 0 is a crossing (one state event, right there) and moving below 0 is
none.  The FMU is the Ramp test model (tests/c_fmus/ramp/): x' = s from x = 0, x its event indicator; at
the time event T_reset x is set back to 0 and the slope becomes s_after; its output ``crossings`` counts
the events at which x is in the other domain than at the event before."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from c_fmu_support import build_ramp
from wmr_cosim import cosim
from wmr_cosim.cosim.instances import integrators

SOLVERS = [("cvode", {}), ("euler", {"max_step": 0.01}), ("rk4", {"max_step": 0.01})]
T_RESET = 0.1


@pytest.fixture(scope="module")
def ramps(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    out = tmp_path_factory.mktemp("ramps")
    return {v: build_ramp(out, v) for v in (2, 3)}


def _events(fmu: Path, out: Path, solver: str, fields: dict[str, Any], **parameters: float
            ) -> tuple[list[tuple[float, str]], np.ndarray]:
    """The ramp run as model exchange for 0.2 s of 50 ms steps: the events its instance handled, the rows."""
    doc = {"experiment": {"start": 0.0, "stop": 0.2, "step": 0.05},
           "instances": {"r": {"fmu": str(fmu), "interface": "model-exchange", "solver": solver, **fields,
                               "parameters": parameters}},
           "record": {"variables": ["r.x", "r.crossings"]}}
    ex = cosim.Execution(cosim.resolve(cosim.parse(doc, "ramp.toml")), out)
    ex.initialize()
    try:
        assert ex.simulate_until(0.2) == "ok"
        events = list(ex.instances["r"].events)
    finally:
        res = ex.close()
    assert res.status == "ok", res.message
    return events, np.load(out / "signals.npy")


def _near(t: float, t0: float) -> bool:
    """A state event located right after t0 [s] (within the integrators' event tolerance)."""
    return t0 <= t <= t0 + 1e-9


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("solver, fields", SOLVERS)
def test_an_indicator_rising_from_zero_at_the_start_is_one_crossing_there(ramps, tmp_path, version, solver, fields):
    events, rows = _events(ramps[version], tmp_path / "out", solver, fields, s=1.0)
    assert [kind for _, kind in events] == ["state"] and _near(events[0][0], 0.0), events
    assert rows["r.crossings"].tolist() == [0.0, 1.0, 1.0, 1.0, 1.0]
    assert rows["r.x"][-1] == pytest.approx(0.2, abs=1e-9)


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("solver, fields", SOLVERS)
def test_an_indicator_falling_from_zero_at_the_start_is_no_crossing(ramps, tmp_path, version, solver, fields):
    events, rows = _events(ramps[version], tmp_path / "out", solver, fields, s=-1.0)
    assert events == []
    assert rows["r.crossings"].tolist() == [0.0] * 5
    assert rows["r.x"][-1] == pytest.approx(-0.2, abs=1e-9)


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("solver, fields", SOLVERS)
def test_an_indicator_set_to_zero_by_an_event_then_rising_is_one_crossing_there(ramps, tmp_path, version, solver,
                                                                                 fields):
    """Falling from the start (no event), set back to 0 at the time event at 0.1 s, then rising: one
    state event, right after 0.1 s."""
    events, rows = _events(ramps[version], tmp_path / "out", solver, fields, s=-1.0, T_reset=T_RESET, s_after=1.0)
    assert [kind for _, kind in events] == ["time", "state"], events
    assert events[0][0] == T_RESET and _near(events[1][0], T_RESET), events
    assert rows["r.crossings"].tolist() == [0.0, 0.0, 0.0, 1.0, 1.0]
    assert rows["r.x"][-1] == pytest.approx(0.1, abs=1e-9)


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("solver, fields", SOLVERS)
def test_an_indicator_set_to_zero_by_an_event_then_falling_is_no_crossing(ramps, tmp_path, version, solver, fields):
    """Rising from the start (a crossing there), set back to 0 at 0.1 s, then falling: no event after the
    time event."""
    events, rows = _events(ramps[version], tmp_path / "out", solver, fields, s=1.0, T_reset=T_RESET, s_after=-1.0)
    assert [kind for _, kind in events] == ["state", "time"] and _near(events[0][0], 0.0), events
    assert events[1][0] == T_RESET
    assert rows["r.crossings"].tolist() == [0.0, 1.0, 1.0, 1.0, 1.0]
    assert rows["r.x"][-1] == pytest.approx(-0.1, abs=1e-9)


def test_the_domains_of_crossed():
    """z > 0 against z <= 0: from 0 upwards is a crossing, from 0 downwards or staying at 0 is none, and
    reaching 0 from above is one."""
    assert integrators.crossed([0.0], [1e-300]) and integrators.crossed([1e-300], [0.0])
    assert not integrators.crossed([0.0], [-1e-300]) and not integrators.crossed([0.0], [0.0])
    assert not integrators.crossed([-1.0], [0.0]) and integrators.crossed([0.0, -1.0], [0.0, 2.0])
    assert integrators.ZERO_SIDE < 0.0 and integrators.ZERO_SIDE == -5e-324
