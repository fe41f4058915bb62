"""A pytest plugin (loaded by conftest.py; not a test module): the test session gets a temporary folder
of its own, and the session fails if anything is left in it at the end.

At the start the plugin creates ``wmr-tests-tmp-*`` in the system's temporary folder and points ``TMPDIR``
and :mod:`tempfile`'s default at it, so every temporary file or folder made by the tests, by the code they
run and by every child process (FMU extraction, the FMU build, Dask workers, the ecos program) lands there.
At the end it lists what is left, removes the folder and, if it was not empty, reports the entries and
sets the exit status to "tests failed".  Under pytest-xdist the workers inherit the folder (``TMPDIR``) and
the session checks it once every worker has finished.  A test's ``tmp_path`` is unaffected: pytest keeps those in its
own folder (``PYTEST_DEBUG_TEMPROOT`` is set to the system's temporary folder for that).
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

_state: dict[str, object] = {}


def pytest_configure(config: pytest.Config) -> None:
    if hasattr(config, "workerinput"):
        return   # a pytest-xdist worker: it inherits the session's folder (TMPDIR), which the session checks
    system_tmp = tempfile.gettempdir()
    _state["env"] = {k: os.environ.get(k) for k in ("TMPDIR", "PYTEST_DEBUG_TEMPROOT")}
    _state["tempdir"] = tempfile.tempdir
    os.environ.setdefault("PYTEST_DEBUG_TEMPROOT", system_tmp)  # tmp_path folders stay where pytest keeps them
    private = Path(tempfile.mkdtemp(prefix="wmr-tests-tmp-", dir=system_tmp))
    _state["private"] = private
    os.environ["TMPDIR"] = str(private)
    tempfile.tempdir = str(private)


def leftovers(folder: Path) -> list[str]:
    """What the session left in its temporary folder (pytest's own basetemp, if an old pytest put it
    there, excepted)."""
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith("pytest-of-"))


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    private = _state.pop("private", None)
    if not isinstance(private, Path):
        return
    left = leftovers(private) if private.is_dir() else []
    for k, v in _state.pop("env").items():  # type: ignore[union-attr]
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
    tempfile.tempdir = _state.pop("tempdir")  # type: ignore[assignment]
    shutil.rmtree(private, ignore_errors=True)
    if left:
        shown = ", ".join(left[:10]) + (f" and {len(left) - 10} more" if len(left) > 10 else "")
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        message = f"the tests left {len(left)} {'entry' if len(left) == 1 else 'entries'} in the temporary folder: {shown}"
        if reporter is not None:
            reporter.line("")  # end the progress line
            reporter.write_sep("=", "temporary folder", red=True)
            reporter.write_line(f"FAILED: {message}", red=True, bold=True)
        else:
            print(message)
        if session.exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED
