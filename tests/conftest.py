"""Shared fixtures."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory):
    """The three FMUs built once per test session into a temporary folder: {model name: path}."""
    from wmr_cosim.fmus.build import build_all

    return build_all(tmp_path_factory.mktemp("fmus"))
