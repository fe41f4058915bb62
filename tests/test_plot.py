"""``wmr-cosim plot RESULTS [VARIABLE ...]`` (wmr_cosim/runs/plot.py): a PNG of the recorded signals of a
results folder against time, one subplot per unit with the unit in its y label, the run's events as
vertical lines named by their kind and source where summary.json gives them; the default variables; bad
input (no folder, no signals.npy, a variable not recorded, an output it cannot write) in one line, exit 2;
``--show`` without a display writes the file and says so."""
from __future__ import annotations

import json
import shutil
import struct

import numpy as np
import pytest

from wmr_cosim import Simulation, cli, runner
from wmr_cosim.runs import plot

EVENT_T = 0.1   # [s]


@pytest.fixture(scope="module")
def results(built_fmus, tmp_path_factory):
    """A 0.2 s G1 run with one timed event at 0.1 s: its results folder (not to be changed: see ``folder``)."""
    out = tmp_path_factory.mktemp("plot") / "g1"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(runner, "resolve_model", lambda name: built_fmus.get(name))
        (Simulation.load("g1_learn.toml").experiment(stop=0.2)
         .event(time=EVENT_T, variable="plant.tau_d1", action="override", value=0.5).run(out=out))
    return out


@pytest.fixture
def folder(results, tmp_path):
    """A copy of the results folder, for a test to change."""
    return shutil.copytree(results, tmp_path / "g1")


def _png_size(path) -> tuple[int, int]:
    raw = path.read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n" and raw[12:16] == b"IHDR", raw[:16]
    return struct.unpack(">II", raw[16:24])


def _drawn(fig) -> list[list[str]]:
    """The signals drawn, subplot by subplot (the events are collections, not lines)."""
    return [[ln.get_label() for ln in ax.get_lines()] for ax in fig.axes]


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_plot_writes_a_png_of_the_first_recorded_variables(folder, monkeypatch, capsys):
    figures = []
    draw = plot.draw
    monkeypatch.setattr(plot, "draw", lambda *a, **k: figures.append(draw(*a, **k)) or figures[-1])
    assert cli.main(["plot", str(folder)]) == 0, capsys.readouterr().err
    columns = list(json.loads((folder / "summary.json").read_text())["columns"])
    assert columns[0] == "time"
    first = columns[1:5]                                   # plant.alpha1, alpha2 [rad], alpha_dot1, 2 [rad/s]
    assert capsys.readouterr().out.strip() == f"{folder}: {', '.join(first)} drawn in {folder / 'plot.png'}"
    (fig,) = figures
    assert _drawn(fig) == [first[:2], first[2:]]
    assert [ax.get_ylabel() for ax in fig.axes] == ["[rad]", "[rad/s]"]
    assert fig.axes[-1].get_xlabel() == "time [s]"
    sig = np.load(folder / "signals.npy")
    line = fig.axes[0].get_lines()[0]
    assert np.array_equal(line.get_xdata(), sig["time"]) and np.array_equal(line.get_ydata(), sig[first[0]])
    width, height = _png_size(folder / "plot.png")
    assert (width, height) == (900, 580) and (folder / "plot.png").stat().st_size > 10_000


def test_named_variables_and_patterns_one_subplot_per_unit(folder, tmp_path):
    done = plot.plot_results(folder, ["plant.x_A", "controller.u1", "plant.y_A", "controller.W*", "sensor.count1"],
                             out=tmp_path / "figs" / "mine.png")
    assert done.path == tmp_path / "figs" / "mine.png" and _png_size(done.path)[1] == 100 + 4 * 240
    assert done.variables == ["plant.x_A", "controller.u1", "plant.y_A", "controller.W1", "controller.W2",
                              "controller.W3", "sensor.count1"]
    assert _drawn(done.figure) == [["plant.x_A", "plant.y_A"], ["controller.u1"],
                                   ["controller.W1", "controller.W2", "controller.W3"], ["sensor.count1"]]
    assert [ax.get_ylabel() for ax in done.figure.axes] == ["[m]", "controller.u1 [N.m]", "[1]",
                                                             "sensor.count1 (no unit)"]
    assert not (folder / "plot.png").exists()


def _event_lines(ax) -> list[tuple[list[float], str]]:
    """The vertical lines of each label on a subplot: (their times [s], the label)."""
    return [([float(seg[0][0]) for seg in c.get_segments()], c.get_label()) for c in ax.collections]


def test_the_events_of_the_run_are_vertical_lines_on_every_subplot(folder):
    events = json.loads((folder / "summary.json").read_text())["events"]
    times = sorted(e["time"] for e in events)
    assert times and times[0] == pytest.approx(EVENT_T)       # the scenario's event at 0.1 s (and any other)
    fig = plot.plot_results(folder, ["plant.x_A", "controller.u1"]).figure
    for ax in fig.axes:
        assert sorted(t for at, _ in _event_lines(ax) for t in at) == times
        assert all(seg[0][0] == seg[1][0] for c in ax.collections for seg in c.get_segments())   # vertical


def _with_events(folder, events: list[dict]):
    summary = json.loads((folder / "summary.json").read_text())
    (folder / "summary.json").write_text(json.dumps({**summary, "events": events}))
    return plot.plot_results(folder, ["plant.x_A"]).figure


def test_events_are_named_by_kind_and_source_where_given(folder):
    fig = _with_events(folder, [{"time": 0.1, "kind": "scenario", "source": "events[0]", "action": "override"},
                                {"time": 99.0, "kind": "late"}, {"time": 0.15, "source": "script"},
                                {"time": 0.12, "kind": "state", "source": "plant"},
                                {"time": 0.18, "kind": "state", "source": "plant"}, {"kind": "no time"}])
    assert _event_lines(fig.axes[0]) == [([0.1], "scenario (events[0])"), ([0.15], "script"),
                                         ([0.12, 0.18], "state (plant)")]        # 99 s: outside the run
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend == ["plant.x_A", "scenario (events[0])", "script", "state (plant)"]


def test_events_without_kind_or_source_are_named_by_their_action(folder):
    fig = _with_events(folder, [{"time": 0.1, "event": 0, "action": "override"}, {"time": 0.2}])
    assert _event_lines(fig.axes[0]) == [([0.1], "event: override"), ([0.2], "event")]


def test_a_folder_without_summary_takes_the_units_from_scenario_json(folder):
    (folder / "summary.json").unlink()
    fig = plot.plot_results(folder, ["plant.x_A"]).figure
    assert fig.axes[0].get_ylabel() == "plant.x_A [m]" and len(fig.axes[0].collections) == 0


@pytest.mark.parametrize("case, words", [
    ("missing", "{folder}/nothing: no such folder"),
    ("empty", "{folder}/logs: no signals.npy (not a results folder of `wmr-cosim run`)"),
    ("typo", "{folder}: 'plant.xA' was not recorded (did you mean 'plant.x_A'?); recorded: plant.alpha1, "
             "plant.alpha2, plant.alpha_dot1, plant.alpha_dot2, plant.x_A, plant.y_A, plant.beta, plant.dF1, ... "),
    ("unknown", "{folder}: 'zzz' was not recorded; recorded: plant.alpha1"),
    ("pattern", "{folder}: 'nobody.*' was not recorded; recorded: "),
    ("suffix", "--out {folder}/plot.xyz: the file name must end in one of "),
    ("not writable", "--out {folder}/signals.npy/p.png: cannot write there"),
])
def test_bad_input_is_one_line_and_exit_2(case, words, folder, capsys):
    argv = {"missing": [f"{folder}/nothing"], "empty": [f"{folder}/logs"], "typo": [str(folder), "plant.xA"],
            "unknown": [str(folder), "plant.x_A", "zzz"], "pattern": [str(folder), "nobody.*"],
            "suffix": [str(folder), "--out", f"{folder}/plot.xyz"],
            "not writable": [str(folder), "--out", f"{folder}/signals.npy/p.png"]}[case]
    assert cli.main(["plot", *argv]) == 2
    err = _err(capsys)
    assert err.startswith("wmr-cosim: error: " + words.format(folder=folder)), err
    if case in ("typo", "unknown"):
        assert err.endswith(f"({len(np.load(folder / 'signals.npy').dtype.names) - 1} in all)"), err
    assert not (folder / "plot.png").exists()


def test_show_without_a_display_writes_the_file_and_says_so(folder, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(plot.sys, "platform", "linux")
    assert not plot.has_display()
    assert cli.main(["plot", str(folder), "plant.x_A", "--show"]) == 0
    assert _err(capsys) == "wmr-cosim: note: no display: --show opens no window; the figure is only written"
    assert _png_size(folder / "plot.png")[0] == 900


# --- a results folder a killed run, a cut copy or a stranger left: one line, or the rows that are there -----------

def _cut(path, size: int) -> None:
    path.write_bytes(path.read_bytes()[:size])


def _header_end(path) -> int:
    raw = path.read_bytes()
    assert raw[6] == 1
    return 10 + int.from_bytes(raw[8:10], "little")


@pytest.mark.parametrize("case, words", [
    ("0 bytes", "signals.npy: empty (0 bytes): the run wrote nothing"),
    ("magic only", "signals.npy: cut inside its header"),
    ("header cut", "signals.npy: cut inside its header"),
    ("garbage", "signals.npy: not a .npy file (it begins b'time,pla')"),
    ("no rows", "{folder}: signals.npy has no rows: nothing to draw"),
    ("no time", "signals.npy: not a recording (no time column)"),
    ("summary empty", "summary.json: empty"),
    ("summary not JSON", "summary.json: not valid JSON (line 1 column 12: "),
    ("summary a list", "summary.json: not a JSON object (an array)"),
    ("summary columns", "summary.json: columns: an object expected, not a number"),
    ("summary events", "summary.json: events: an array expected, not a string"),
    ("scenario not UTF-8", "scenario.json: not UTF-8 (byte 0)"),
    ("requirements.npy", "requirements.npy: empty (0 bytes)"),
])
def test_a_broken_file_of_the_folder_is_one_line_naming_it(case, words, folder, capsys):
    npy = folder / "signals.npy"
    if case == "0 bytes":
        npy.write_bytes(b"")
    elif case == "magic only":
        _cut(npy, 9)
    elif case == "header cut":
        _cut(npy, _header_end(npy) - 20)
    elif case == "garbage":
        npy.write_text("time,plant.x_A\n0,1\n")
    elif case == "no rows":
        raw, shape = npy.read_bytes()[:_header_end(npy)], b"'shape': (%d,)" % len(np.load(npy))
        npy.write_bytes(raw.replace(shape, b"'shape': (0,)".ljust(len(shape))))   # the header of a run killed at once
    elif case == "no time":
        np.save(npy, np.zeros(3, dtype=[("t", "<f8")]))
    elif case.startswith("summary"):
        summary = json.loads((folder / "summary.json").read_text())
        (folder / "summary.json").write_text({"summary empty": "  \n", "summary not JSON": '{"status": ok}',
                                              "summary a list": "[1, 2]",
                                              "summary columns": json.dumps({**summary, "columns": 5}),
                                              "summary events": json.dumps({**summary, "events": "none"})}[case])
    elif case == "scenario not UTF-8":
        (folder / "summary.json").unlink()
        (folder / "scenario.json").write_bytes(b"\xff\xfe{}")
    elif case == "requirements.npy":
        (folder / "requirements.npy").write_bytes(b"")
    assert cli.main(["plot", str(folder), "plant.x_A"]) == 2
    err = _err(capsys)
    lead = f"wmr-cosim: error: {folder}/" if not words.startswith("{folder}") else "wmr-cosim: error: "
    assert err.startswith(lead + words.format(folder=folder)), err
    assert not (folder / "plot.png").exists()


def test_a_recording_cut_short_is_drawn_up_to_its_last_whole_row(folder, monkeypatch, capsys):
    """A run killed between writing rows and rewriting the header, or a copy cut mid-row: the header
    promises more rows than the file holds; the whole rows are data and are drawn, and a note says how many
    of how many."""
    npy = folder / "signals.npy"
    full = np.load(npy)
    keep = len(full) // 2
    _cut(npy, _header_end(npy) + keep * full.dtype.itemsize + full.dtype.itemsize // 2)
    figures = []
    draw = plot.draw
    monkeypatch.setattr(plot, "draw", lambda *a, **k: figures.append(draw(*a, **k)) or figures[-1])
    assert cli.main(["plot", str(folder), "plant.x_A"]) == 0
    assert _err(capsys) == (f"wmr-cosim: note: {npy}: {keep} of the {len(full)} rows its header gives are in the "
                            f"file (it was cut short): the {keep} are read")
    line = figures[0].axes[0].get_lines()[0]
    assert np.array_equal(line.get_xdata(), full["time"][:keep])
    assert np.array_equal(line.get_ydata(), full["plant.x_A"][:keep])
    from wmr_cosim.paper.analysis import load_signals
    assert np.array_equal(load_signals(folder)["plant.x_A"], full["plant.x_A"][:keep])
