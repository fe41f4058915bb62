"""The command line's exit codes are the application's (wmr_cosim.exit_codes): one per run status and one
per kind of error; the master defines none."""
from __future__ import annotations

import pytest

from wmr_cosim import exit_codes
from wmr_cosim.cli import UsageError
from wmr_cosim.components.validation import ParameterError
from wmr_cosim.cosim.messages import errors
from wmr_cosim.cosim.results.status import RunStatus


@pytest.mark.parametrize("status, code", [
    (RunStatus.OK, 0), (RunStatus.TERMINATED, 0), (RunStatus.STOPPED, 0), (RunStatus.FAILED, 1),
    (RunStatus.DIVERGED, 1), (RunStatus.INTERRUPTED, 130), ("ok", 0), ("diverged", 1)])
def test_each_run_status_has_its_exit_code(status, code):
    assert exit_codes.for_status(status) == code


def test_a_protocol_exits_with_the_worst_of_its_runs():
    assert exit_codes.for_statuses([]) == 0
    assert exit_codes.for_statuses(["ok", "stopped"]) == 0
    assert exit_codes.for_statuses(["ok", "diverged", "ok"]) == 1
    assert exit_codes.for_statuses(["failed", "interrupted"]) == 130


@pytest.mark.parametrize("exc, code", [
    (errors.ScenarioError("s.toml", "x", "bad"), 2), (errors.OtherFileError("s.toml", "a sweep file"), 2),
    (errors.FmuLoadError("bad"), 2), (errors.OutputError("held"), 2), (errors.CosimError("bad"), 2),
    (ParameterError("bad"), 2), (UsageError("bad"), 2), (errors.RunError("failed"), 1), (KeyboardInterrupt(), 130)])
def test_each_error_has_its_exit_code(exc, code):
    assert exit_codes.for_error(exc) == code


def test_the_errors_of_the_master_carry_no_exit_code():
    assert not any(hasattr(cls, "exit_code") for cls in (errors.CosimError, errors.ScenarioError,
                                                         errors.FmuLoadError, errors.RunError))
