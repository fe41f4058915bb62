"""``base`` finds what run and check find: a file beside the one that names it, else a shipped scenario, so
that a copy of a shipped file (example.toml) edited in another folder still loads."""
from __future__ import annotations

import shutil

import pytest

from wmr_cosim import scenario_files
from wmr_cosim.cli import main
from wmr_cosim import cosim
from wmr_cosim.cosim.messages.errors import ScenarioError

SHIPPED = scenario_files.folder()   # what the command line passes: the master knows no folder of its own


def test_a_copy_of_a_shipped_scenario_finds_its_base(tmp_path):
    copy = tmp_path / "example.toml"
    shutil.copy(scenario_files.folder() / "example.toml", copy)
    sc = cosim.load(copy, lambda name: tmp_path / f"{name}.fmu", shipped=SHIPPED)
    assert sc.file == str(copy)
    assert sorted(sc.instances) == ["controller", "plant", "sensor"]     # from g1_learn.toml, shipped


@pytest.mark.parametrize("base", ["paper/protocol.toml", "scenarios/paper/protocol.toml"])
def test_a_base_names_a_shipped_file_as_the_command_line_does(tmp_path, base):
    path = tmp_path / "mine.toml"
    path.write_text(f'base = "{base}"\n[instances.controller.parameters]\ngoal_x = 1.0\n')
    sc = cosim.load(path, lambda name: tmp_path / f"{name}.fmu", shipped=SHIPPED)
    assert [r.name for r in sc.runs] == ["learn", "frozen", "foam"]
    assert sc.instances["controller"].parameters["goal_x"] == 1.0


def test_a_file_beside_wins_over_a_shipped_one(tmp_path):
    (tmp_path / "g1_learn.toml").write_text('[experiment]\nstop = 1.0\nstep = 0.5\n[instances.a]\nfmu = "A"\n')
    path = tmp_path / "mine.toml"
    path.write_text('base = "g1_learn.toml"\n')
    assert list(cosim.load(path, lambda name: tmp_path / f"{name}.fmu", shipped=SHIPPED).instances) == ["a"]


def test_a_base_found_nowhere_says_so_in_one_line(tmp_path, capsys):
    path = tmp_path / "mine.toml"
    path.write_text('base = "nope.toml"\n')
    with pytest.raises(ScenarioError) as exc:
        cosim.load(path, shipped=SHIPPED)
    assert exc.value.field == "base" and "'nope.toml': file not found" in exc.value.reason
    assert "nor a shipped scenario" in exc.value.reason
    assert main(["check", str(path)]) == 2


def test_a_copy_of_a_shipped_protocol_task_is_told_where_its_base_is(tmp_path):
    copy = tmp_path / "g1.toml"
    shutil.copy(scenario_files.folder() / "paper" / "g1.toml", copy)     # base = "protocol.toml"
    with pytest.raises(ScenarioError, match=r"did you mean 'paper/protocol.toml'\?"):
        cosim.load(copy, shipped=SHIPPED)


def test_the_folder_of_shipped_files_is_the_callers(tmp_path):
    """The master looks for a base in the folder its caller gives (another application's), named with or
    without that folder's own name; the hint of a base found nowhere names that folder's files."""
    ours = tmp_path / "library"
    (ours / "tasks").mkdir(parents=True)
    (ours / "tasks" / "common.toml").write_text('[experiment]\nstop = 1.0\nstep = 0.5\n[instances.a]\nfmu = "A"\n')
    work = tmp_path / "work"
    work.mkdir()
    for i, base in enumerate(("tasks/common.toml", "library/tasks/common.toml")):
        (work / f"m{i}.toml").write_text(f'base = "{base}"\n')
        sc = cosim.load(work / f"m{i}.toml", lambda name: tmp_path / f"{name}.fmu", shipped=ours)
        assert list(sc.instances) == ["a"]
    (work / "lost.toml").write_text('base = "common.toml"\n')
    with pytest.raises(ScenarioError, match=r"did you mean 'tasks/common.toml'\?"):
        cosim.load(work / "lost.toml", shipped=ours)
