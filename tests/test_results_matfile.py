"""Results as MAT (Dymola's result layout, MAT v4, cosim/results/matfile.py): ``run --format mat`` writes
signals.mat beside signals.npy, which scipy.io.loadmat and DyMat read back as the recording, column for
column (float64 bit for bit), with each variable's name, description and unit; the constants in data_1;
``--format`` picks what the folder gets and refuses an unknown value in one line; the API writes the same
file (``[record] mat``, ``Result.write_mat``)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io

from wmr_cosim import Simulation, cli, runner
from wmr_cosim.cosim.results.matfile import MatLayout, MatVariable, write_mat


@pytest.fixture
def ours(built_fmus, monkeypatch):
    """Model names resolve to the session's FMUs (no build into the checkout)."""
    monkeypatch.setattr(runner, "resolve_model", lambda name: built_fmus.get(name))


def _run(tmp_path, capsys, *options: str, stop: str = "1") -> int:
    code = cli.main(["run", "g1_learn.toml", "--stop", stop, "--out", str(tmp_path / "out"), "--quiet", *options])
    assert code == 0, capsys.readouterr().err
    return code


def _texts(mat: dict, key: str) -> list[str]:
    """A char matrix stored transposed (one column per entry), as strings."""
    return ["".join(col).rstrip() for col in mat[key].T]


@pytest.fixture
def g1_mat(ours, tmp_path, capsys):
    """A 1 s G1 run with --format mat and gamma set: (the folder, signals.npy, signals.mat loaded)."""
    _run(tmp_path, capsys, "--format", "mat", "--set", "controller.gamma=8")
    out = tmp_path / "out"
    return out, np.load(out / "signals.npy"), scipy.io.loadmat(out / "signals.mat", chars_as_strings=False)


def test_the_mat_file_holds_the_recording_column_for_column(g1_mat):
    out, sig, mat = g1_mat
    assert ["".join(row).rstrip() for row in mat["Aclass"]] == ["Atrajectory", "1.1", "", "binTrans"]
    names = _texts(mat, "name")
    constants = [n for n in names if n not in sig.dtype.names]
    assert [n for n in names if n in sig.dtype.names] == list(sig.dtype.names)   # time first, then in order
    data_2 = mat["data_2"]
    assert data_2.shape == (len(sig.dtype.names), len(sig)) and data_2.dtype == np.float64
    info = mat["dataInfo"]
    for name in sig.dtype.names:
        block, row = info[0, names.index(name)], info[1, names.index(name)]
        assert (block, row) == ((0, 1) if name == "time" else (2, list(sig.dtype.names).index(name) + 1)), name
        col = sig[name]
        if col.dtype == np.float64:                                            # bit for bit
            assert data_2[row - 1].view(np.uint64).tolist() == col.view(np.uint64).tolist(), name
        else:                                                                  # integers, booleans: exactly
            assert np.array_equal(data_2[row - 1], col.astype(np.float64)), name
    assert set(sig.dtype.names) - {"time"} and constants   # signals and constants both present
    data_1 = mat["data_1"]
    assert data_1[0].tolist() == [sig["time"][0], sig["time"][-1]]
    gamma = names.index("controller.gamma")
    assert info[:, gamma].tolist() == [1, info[1, gamma], 0, 0] and data_1[info[1, gamma] - 1].tolist() == [8.0, 8.0]


def test_each_description_carries_the_unit_as_dymola_writes_it(g1_mat):
    out, sig, mat = g1_mat
    names, descriptions = _texts(mat, "name"), _texts(mat, "description")
    desc = dict(zip(names, descriptions))
    units = {n: c["unit"] for n, c in json.loads((out / "summary.json").read_text())["columns"].items()}
    assert desc["time"] == "Simulation time [s]"
    assert desc["plant.x_A"] == "x of point A [m]"
    assert desc["controller.u1"].endswith(" [N.m]") and desc["controller.gamma"].endswith(" [1]")
    for name in sig.dtype.names:
        if units[name]:
            assert desc[name].endswith(f"[{units[name]}]"), (name, desc[name])
    assert units["controller.adapting"] is None and "[" not in desc["controller.adapting"]


def test_dymat_reads_the_file(g1_mat):
    import DyMat

    out, sig, _ = g1_mat
    d = DyMat.DyMatFile(str(out / "signals.mat"))
    assert set(sig.dtype.names) - {"time"} <= set(d.names())
    for name in sig.dtype.names[1:]:
        assert np.array_equal(d.data(name), sig[name].astype(np.float64)), name
        assert d.block(name) == 2
    assert np.array_equal(d.abscissa(2, valuesOnly=True), sig["time"])
    assert d.description("plant.y_A") == "y of point A [m]"
    assert d.data("controller.gamma").tolist() == [8.0, 8.0]


def test_format_picks_what_the_folder_gets(ours, tmp_path, capsys):
    out = tmp_path / "out"
    for options, files in ((["--format", "mat"], {"signals.mat"}), ([], {"signals.csv"}),
                           (["--format", "npy"], set()), (["--format", "csv,mat"], {"signals.csv", "signals.mat"}),
                           (["--format", "csv", "--format", "MAT"], {"signals.csv", "signals.mat"}),
                           (["--set", "record.mat=true"], {"signals.csv", "signals.mat"})):
        _run(tmp_path, capsys, *options, stop="0.1")
        assert {p.name for p in out.glob("signals.*")} == {"signals.npy", *files}, options  # stale ones gone


@pytest.mark.parametrize("value, words", [
    ("xls", "--format 'xls': must be one of csv, npy, mat"),
    ("mta", "--format 'mta': must be one of csv, npy, mat (did you mean 'mat'?)"),
    ("csv,parquet", "--format 'parquet': must be one of csv, npy, mat"),
])
def test_an_unknown_format_is_refused_in_one_line(value, words, tmp_path, capsys):
    code = cli.main(["run", "g1_learn.toml", "--format", value, "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err == f"wmr-cosim: error: {words}", err
    assert not (tmp_path / "out").exists()


def test_record_mat_must_be_a_boolean(ours, tmp_path, capsys):
    assert cli.main(["check", "g1_learn.toml", "--set", "record.mat=yes"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.endswith("record.mat: 'yes': must be true or false"), err


def test_the_api_writes_the_same_file(ours, tmp_path):
    result = (Simulation.load("g1_learn.toml").experiment(stop=0.2).record("controller.goal_x", mat=True)
              .run(out=tmp_path / "run"))
    assert (tmp_path / "run" / "signals.mat").is_file()
    written = result.write_mat(tmp_path / "again.mat")
    assert written.read_bytes() == (tmp_path / "run" / "signals.mat").read_bytes()
    mat = scipy.io.loadmat(written, chars_as_strings=False)
    names = _texts(mat, "name")       # a parameter the scenario sets and records: a signal, not a constant
    assert names.count("controller.goal_x") == 1 and mat["dataInfo"][0, names.index("controller.goal_x")] == 2
    assert "controller.goal_y" in names and mat["dataInfo"][0, names.index("controller.goal_y")] == 1
    result = (Simulation.load("g1_learn.toml").experiment(stop=0.2)      # a temporary folder, no MAT
              .event(time=0.1, variable="controller.goal_y", action="set", value=4.0).run())
    mat = scipy.io.loadmat(result.write_mat(tmp_path / "temp.mat"), chars_as_strings=False)
    names = _texts(mat, "name")
    assert names[0] == "time" and "controller.goal_x" in names   # a parameter the scenario sets ...
    assert "controller.goal_y" not in names                      # ... and one an event changes: no constant
    row = mat["dataInfo"][1, names.index("plant.alpha1")]
    assert np.array_equal(mat["data_2"][row - 1], result["plant.alpha1"])


def test_the_writer_converts_every_type_and_writes_a_mat_v4_file(tmp_path):
    sig = np.zeros(3, dtype=[("time", "<f8"), ("a.f32", "<f4"), ("a.i64", "<i8"), ("a.u64", "<u8"),
                             ("a.on", "?"), ("a.größe", "<f8")])
    sig["time"] = [0.0, 0.5, 1.0]
    sig["a.f32"] = [0.1, -2.5, 3e38]
    sig["a.i64"] = [-(2 ** 53), 0, 2 ** 53]
    sig["a.u64"] = [0, 1, 2 ** 53]
    sig["a.on"] = [True, False, True]
    sig["a.größe"] = [1.0, 2.0, 3.0]
    spec = MatLayout({"time": MatVariable("time", "Simulation time", "s"), "a.f32": MatVariable("a.f32", "", "m")},
                     [MatVariable("a.k", "gain", "1", 2.5)])
    path = write_mat(tmp_path / "x.mat", sig, spec, chunk=2)
    raw = path.read_bytes()
    assert np.frombuffer(raw[:20], "<i4").tolist() == [51, 4, 11, 0, 7] and raw[20:27] == b"Aclass\0"
    mat = scipy.io.loadmat(path, chars_as_strings=False)
    names = _texts(mat, "name")
    assert names == ["time", "a.k", "a.f32", "a.i64", "a.u64", "a.on", "a.größe".encode().decode("latin-1")]
    assert _texts(mat, "description")[:3] == ["Simulation time [s]", "gain [1]", "[m]"]
    assert mat["data_1"].tolist() == [[0.0, 1.0], [2.5, 2.5]]
    for j, name in enumerate(sig.dtype.names):
        assert mat["data_2"][j].tolist() == sig[name].astype(np.float64).tolist(), name
    assert [p.name for p in tmp_path.iterdir()] == ["x.mat"]


def test_the_writer_refuses_what_it_cannot_write_and_leaves_nothing(tmp_path):
    with pytest.raises(ValueError, match="no rows"):
        write_mat(tmp_path / "x.mat", np.zeros(0, dtype=[("time", "<f8")]))
    with pytest.raises(ValueError, match="no 'time' column"):
        write_mat(tmp_path / "x.mat", np.zeros(2, dtype=[("t", "<f8")]))
    text = np.array([(0.0, "abc")], dtype=[("time", "<f8"), ("a.s", "<U3")])
    with pytest.raises(ValueError):      # fails while writing the data: the partial file is removed
        write_mat(tmp_path / "x.mat", text)
    assert list(tmp_path.iterdir()) == []


def test_the_docs_snippets_read_a_real_signals_mat(tmp_path, monkeypatch, capsys):
    """The snippets of docs/scenarios.md ("Reading signals.mat"), run as written against the run they name
    (BouncingBall, --format mat): each gives the recorded time and height, bit for bit."""
    import re
    from pathlib import Path

    from reference_fmus import REF

    doc = (Path(__file__).resolve().parents[1] / "docs" / "scenarios.md").read_text(encoding="utf-8")
    section = doc[doc.index("**Reading `signals.mat`.**"):]
    command = re.search(r"`(wmr-cosim run [^`]+)`", section).group(1).split()
    blocks = re.findall(r"^```python\n(.*?)^```", section, flags=re.MULTILINE | re.DOTALL)[:2]
    assert command[2] == "BouncingBall.fmu" and "loadmat" in blocks[0] and "DyMat" in blocks[1]
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", str(REF / "fmi2" / "BouncingBall.fmu"), *command[3:], "--quiet"]) == 0, \
        capsys.readouterr().err
    sig = np.load(tmp_path / "results" / "ball" / "signals.npy")
    assert len(sig) > 100 and sig["BouncingBall.h"].min() < 0.1   # the ball has bounced
    for code in blocks:
        scope: dict = {}
        exec(compile(code, "docs/scenarios.md", "exec"), scope)
        assert np.array_equal(scope["t"], sig["time"]) and np.array_equal(scope["h"], sig["BouncingBall.h"]), code
