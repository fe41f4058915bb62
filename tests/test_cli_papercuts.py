"""Command-line papercuts: ``--set`` one item per use (a positional argument after it stays the scenario),
a key without an instance for a scenario of one FMU, "did you mean" for near names, readable ``--help``,
``direct --stop``, and built FMUs that ship only the platform that is built and tested (linux64)."""
from __future__ import annotations

import zipfile

import pytest

from wmr_cosim.fmus.build import SLAVES, SLAVES3, build_all


def test_a_built_fmu_ships_no_win64_binary(built_fmus):
    for model, fmu in built_fmus.items():
        with zipfile.ZipFile(fmu) as zf:
            platforms = {n.split("/")[1] for n in zf.namelist() if n.startswith("binaries/") and n.count("/") >= 2}
        assert platforms == {"linux64"}, (model, platforms)


def test_a_built_fmi3_fmu_ships_no_windows_binary(tmp_path):
    fmu = build_all(tmp_path, models=("WmrSensor3",))["WmrSensor3"]
    with zipfile.ZipFile(fmu) as zf:
        platforms = {n.split("/")[1] for n in zf.namelist() if n.startswith("binaries/") and n.count("/") >= 2}
    assert platforms == {"x86_64-linux"}
