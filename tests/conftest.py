"""Shared fixtures; the session's own temporary folder, which must be empty at the end (tempdir_guard)."""
from __future__ import annotations

import pytest

from tempdir_guard import pytest_configure, pytest_sessionfinish  # noqa: F401 (hooks of this session)


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory):
    """The three FMUs built once per test session into a temporary folder: {model name: path}."""
    from wmr_cosim.fmus.build import build_all

    return build_all(tmp_path_factory.mktemp("fmus"))
