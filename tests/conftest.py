"""Shared fixtures; the session's own temporary folder, which must be empty at the end (tempdir_guard)."""
from __future__ import annotations

import os

import pytest

from tempdir_guard import pytest_configure, pytest_sessionfinish  # noqa: F401 (hooks of this session)

#: Copies of test files that the mutation harness's --check runs in mutmut's tree (benchmarks/mutation.py)
#: belong to that check only: no other session (mutmut's own) collects them.
collect_ignore_glob = [] if os.environ.get("WMR_MUTATION_CHECK") else ["_check_*"]


def fmu_cache(tmp_path_factory, name: str):
    """Where a session builds its FMUs: the FMU cache's folder ``name`` if there is a cache
    (cosim_support.fmu_cache_dir; the build skips an FMU whose sources have not changed), else a
    temporary folder."""
    from cosim_support import fmu_cache_dir

    return fmu_cache_dir(name) or tmp_path_factory.mktemp(name)


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory):
    """The three FMUs built once per test session: {model name: path}."""
    from wmr_cosim.fmus.build import build_all

    return build_all(fmu_cache(tmp_path_factory, "fmus"))


@pytest.fixture(scope="module")
def studies_run_the_session_fmus(built_fmus):
    """For a module's tests of studies (``pytestmark = pytest.mark.usefixtures(...)``): their points run
    the session's FMUs (the robot system's model names, which the driver resolves and ships to the workers)."""
    from wmr_cosim import runner

    mp = pytest.MonkeyPatch()
    mp.setattr(runner, "resolve_model", lambda name: built_fmus.get(name))
    yield
    mp.undo()


#: Tests that start pools of worker processes (the paper job, Dask clusters).  Under mutation testing
#: they are skipped: mutmut ends a mutant that overruns its time by killing its worker process, which
#: leaves that worker's own children running and loading the machine, and what these tests check of the
#: master is checked by faster tests in process.
STARTS_WORKER_PROCESSES = (
    "tests/test_robustness.py::test_reduced_study_runs_on_dask",
    "tests/test_security.py::test_a_sweep_on_a_tls_scheduler",
    "tests/test_security.py::test_the_sweep_command_listens_on_the_loopback_address_only",
    "tests/test_security.py::test_a_local_cluster_listens_on_the_loopback_address_only",
    "tests/test_sweep.py",
    "tests/test_sweep_shipping.py::test_a_sweep_of_reference_fmus_on_workers_that_cannot_see_its_files",
    "tests/test_sweep_shipping.py::test_the_foam_sweep_on_workers_that_cannot_see_its_files",
    "tests/test_sweep_shipping.py::test_a_worker_killed_mid_sweep",
    "tests/test_sweep_shipping.py::test_a_point_that_kills_its_worker_each_time",
)


#: The fixture of tests/test_paper.py that runs the whole paper job in a pool of worker processes.
USES_THE_PAPER_JOB = "job"
#: Fixtures that start a pool of worker processes (the whole paper job; a shortened one, a few seconds).
STARTS_A_POOL = (USES_THE_PAPER_JOB, "short_job")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    import os
    import re

    slow = pytest.mark.slow
    for item in items:   # the paper job (a minute or more) and pools of worker processes (Dask): slow
        nodeid = re.sub(r"/_check_\d+_", "/", item.nodeid)
        if (USES_THE_PAPER_JOB in getattr(item, "fixturenames", ()) or nodeid.startswith(STARTS_WORKER_PROCESSES)) \
                and item.get_closest_marker("slow") is None:
            item.add_marker(slow)
    if "MUTANT_UNDER_TEST" not in os.environ:
        return
    skip = pytest.mark.skip(reason="starts worker processes: not run under mutation testing")
    for item in items:
        nodeid = re.sub(r"/_check_\d+_", "/", item.nodeid)   # (the copies benchmarks/mutation.py --check runs)
        if nodeid.startswith(STARTS_WORKER_PROCESSES) or set(STARTS_A_POOL) & set(getattr(item, "fixturenames", ())):
            item.add_marker(skip)

