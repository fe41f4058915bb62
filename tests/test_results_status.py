"""How a run ended is one of a closed set of statuses; the command line maps each to its exit code, once."""
from __future__ import annotations

import json

import pytest

from wmr_cosim import RunStatus
from wmr_cosim.exit_codes import (INTERRUPTED as EXIT_INTERRUPTED, OK as EXIT_OK, REQUIREMENT_VIOLATED as EXIT_VIOLATED,
                                  RUN_FAILED as EXIT_RUN_FAILED, for_runs, for_status)


@pytest.mark.parametrize("status, code, well", [
    (RunStatus.OK, EXIT_OK, True), (RunStatus.TERMINATED, EXIT_OK, True), (RunStatus.STOPPED, EXIT_OK, True),
    (RunStatus.VIOLATED, EXIT_VIOLATED, True), (RunStatus.FAILED, EXIT_RUN_FAILED, False), (RunStatus.DIVERGED, EXIT_RUN_FAILED, False),
    (RunStatus.INTERRUPTED, EXIT_INTERRUPTED, False)])
def test_each_status_has_its_exit_code(status, code, well):
    assert (for_status(status), status.ended_well) == (code, well)


def test_a_violated_requirement_makes_runs_that_ended_well_exit_3_and_nothing_else():
    held, broke = {"verdict": "holds"}, {"verdict": "violated"}
    assert for_runs(["ok", "ok"], [held, broke]) == EXIT_VIOLATED and for_runs(["ok"], [held]) == EXIT_OK
    assert for_runs(["ok", "failed"], [broke]) == EXIT_RUN_FAILED and for_runs(["stopped"], [broke]) == EXIT_VIOLATED
    assert for_runs(["ok"], [{"verdict": "undecided"}]) == EXIT_OK


def test_a_status_is_its_value_in_json_and_in_text():
    assert json.dumps({"status": RunStatus.DIVERGED}) == '{"status": "diverged"}'
    assert f"{RunStatus.OK}" == "ok" and RunStatus("failed") is RunStatus.FAILED
    assert [s.value for s in RunStatus] == ["ok", "terminated", "stopped", "violated", "failed", "interrupted", "diverged"]


def test_a_run_result_carries_a_status_and_its_exit_code(tmp_path):
    from reference_fmus import REF
    from wmr_cosim.runner import run_scenario

    res = run_scenario(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "out", progress=False)
    assert res.status is RunStatus.OK and for_status(res.status) == EXIT_OK
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["status"] == "ok"
