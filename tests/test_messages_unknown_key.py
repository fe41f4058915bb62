"""The one refusal of an unknown key (cosim/messages/suggest.py ``unknown_key``): the allowed keys
sorted, the nearest one suggested, the same words in every table of a scenario that refuses a key."""
from __future__ import annotations

import pytest

from wmr_cosim.cosim import ScenarioError, load, unknown_key


def test_the_allowed_keys_are_sorted_and_the_nearest_suggested():
    assert unknown_key("colour", {"mat", "csv"}) == "unknown key (allowed: csv, mat)"
    assert unknown_key("tolerence", ("tolerance", "max_iterations")) == \
        "unknown key (allowed: max_iterations, tolerance) (did you mean 'tolerance'?)"
    assert unknown_key("stpo", {"stop", "step"}, "experiment field 'stpo'", ", iteration.KEY") == \
        "unknown experiment field 'stpo' (allowed: step, stop, iteration.KEY) (did you mean 'stop'?)"


@pytest.mark.parametrize("table, field", [
    ("[experiment.iteration]\ntolerence = 1e-6\n", "experiment.iteration.tolerence"),
    ("[experiment.adaptive]\nmax_stp = 0.1\n", "experiment.adaptive.max_stp"),
    ("[limits]\narchive_sise = 1\n", "limits.archive_sise"),
    ("[experiment.iterations]\n", "experiment.iterations"),
])
def test_every_table_of_a_scenario_refuses_a_key_in_the_same_words(tmp_path, table, field):
    path = tmp_path / "s.toml"
    path.write_text('[experiment]\nstop = 1.0\nstep = 0.1\n' + table, encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load(path)
    message = str(info.value)
    assert f"{field}: unknown key (allowed: " in message and "(did you mean '" in message, message
