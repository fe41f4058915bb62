"""How a run ended is one of a closed set of statuses; the command line maps each to its exit code, once."""
from __future__ import annotations

import json

import pytest

from wmr_cosim import RunStatus
from wmr_cosim.exit_codes import INTERRUPTED as EXIT_INTERRUPTED, OK as EXIT_OK, RUN_FAILED as EXIT_RUN_FAILED, for_status


@pytest.mark.parametrize("status, code, well", [
    (RunStatus.OK, EXIT_OK, True), (RunStatus.TERMINATED, EXIT_OK, True), (RunStatus.STOPPED, EXIT_OK, True),
    (RunStatus.FAILED, EXIT_RUN_FAILED, False), (RunStatus.DIVERGED, EXIT_RUN_FAILED, False),
    (RunStatus.INTERRUPTED, EXIT_INTERRUPTED, False)])
def test_each_status_has_its_exit_code(status, code, well):
    assert (for_status(status), status.ended_well) == (code, well)


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
