"""The one table of result formats (cosim/results/formats.py): its flags are the scenario's [record]
flags, ``run --format`` sets them from it, and the results folder writes and clears the files it names."""
from __future__ import annotations

import dataclasses

from wmr_cosim.cosim import RECORDING, RESULT_FORMATS, Scenario, format_flags
from wmr_cosim.cosim.scenario.document import _RECORD_KEYS


def test_each_flag_of_the_table_is_a_boolean_of_the_scenario_and_a_key_of_record():
    fields = {f.name: f for f in dataclasses.fields(Scenario)}
    flags = [f.flag for f in RESULT_FORMATS.values() if f.flag is not None]
    assert flags == ["csv", "mat"]
    for flag in flags:
        assert flag in _RECORD_KEYS and fields[flag].type in (bool, "bool"), flag
    assert RESULT_FORMATS[RECORDING].file == "signals.npy" and RESULT_FORMATS[RECORDING].writer is None


def test_run_format_sets_every_flag_exactly_to_the_formats_named():
    assert format_flags(["mat"]) == {"record.csv": False, "record.mat": True}
    assert format_flags(["npy"]) == {"record.csv": False, "record.mat": False}
    assert format_flags(["csv", "mat"]) == {"record.csv": True, "record.mat": True}
