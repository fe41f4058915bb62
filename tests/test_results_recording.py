"""The recording's files as a user reads them: signals.csv (header, quoting, full precision, integer and
boolean columns, chunking, written whole under a temporary name), the results folder's one-line errors,
and the row buffer's last recorded time."""
from __future__ import annotations

import csv
import math
import io
import os
from pathlib import Path

import numpy as np
import pytest

from wmr_cosim.cosim.results import recording
from wmr_cosim.cosim.messages.errors import OutputError
from wmr_cosim.cosim.results.recording import NpyRecorder, RowBuffer, make_folder, write_csv

COLUMNS = ["time", "a,b", 'say "hi"', "two\nlines", "plant.X", "n", "flag"]
TYPES = ["Real", "Real", "Real", "Real", "Real", "Integer", "Boolean"]


def _recording(path: Path, rows: int = 2) -> Path:
    """A recording of ``rows`` rows (1, 2 or 5) with every kind of column and name."""
    rec = NpyRecorder(path, COLUMNS, TYPES)
    cols = [np.array([0.0, 0.1, 0.2, 0.3, 0.4]), np.array([1 / 3, -2.5, 1e300, 0.0, 7.0]),
            np.array([1e-300, 2.0, -0.0, 3.0, 4.0]), np.array([7.0, 8.0, 9.0, 10.0, 11.0]),
            np.array([0.5, 1.5, 2.5, 3.5, 4.5]), np.array([3, -4, 5, 2 ** 31 - 1, -2 ** 31], dtype=np.int64),
            np.array([1, 0, 1, 1, 0], dtype=np.int64)]
    rec.append([c[:rows] for c in cols])
    rec.close()
    return path


HEADER = 'time,"a,b","say ""hi""","two\nlines",plant.X,n,flag\n'
ROWS = ["0.0,0.3333333333333333,1e-300,7.0,0.5,3,1\n",
        "0.1,-2.5,2.0,8.0,1.5,-4,0\n",
        "0.2,1e+300,-0.0,9.0,2.5,5,1\n",
        "0.3,0.0,3.0,10.0,3.5,2147483647,1\n",
        "0.4,7.0,4.0,11.0,4.5,-2147483648,0\n"]


def test_csv_header_quoting_full_precision_integers_and_booleans(tmp_path):
    """Names with a comma, a quote or a newline are quoted (quotes doubled), others are not; floats are
    written at full precision (repr), integers as integers, booleans as 0/1; the csv module reads back
    the names and values."""
    npy = _recording(tmp_path / "signals.npy")
    write_csv(npy, tmp_path / "signals.csv")
    text = (tmp_path / "signals.csv").read_text()
    assert text == HEADER + "".join(ROWS[:2])
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0] == COLUMNS
    assert float(rows[1][1]) == 1 / 3 and int(rows[2][5]) == -4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["signals.csv", "signals.npy"]


def test_csv_writes_64_bit_integers_in_full(tmp_path):
    """FMI 3.0 UInt64 and Int64 columns: every value exactly as numpy.load gives it (2^64 - 1 is not -1)."""
    rec = NpyRecorder(tmp_path / "signals.npy", ["time", "u", "i", "f"], ["Real", "UInt64", "Int64", "Float32"])
    rec.append([np.array([0.0, 1.0]), np.array([-1, 2 ** 62 + 1], dtype=np.int64),
                np.array([-2 ** 63, 2 ** 63 - 1], dtype=np.int64), np.array([0.1, 2.0])])
    rec.close()
    write_csv(tmp_path / "signals.npy", tmp_path / "signals.csv")
    data = np.load(tmp_path / "signals.npy")
    assert data["u"].tolist() == [2 ** 64 - 1, 2 ** 62 + 1]
    assert (tmp_path / "signals.csv").read_text() == (
        f"time,u,i,f\n0.0,{2 ** 64 - 1},{-2 ** 63},{float(np.float32(0.1))!r}\n"
        f"1.0,{2 ** 62 + 1},{2 ** 63 - 1},2.0\n")


@pytest.mark.parametrize("chunk", [1, 2, 3, 5, 20000])
def test_csv_written_in_chunks_has_every_row_once(tmp_path, chunk):
    npy = _recording(tmp_path / "signals.npy", rows=5)
    write_csv(npy, tmp_path / "signals.csv", chunk=chunk)
    assert (tmp_path / "signals.csv").read_text() == HEADER + "".join(ROWS)


def test_csv_of_one_row_with_the_default_chunk(tmp_path):
    npy = _recording(tmp_path / "signals.npy", rows=1)
    write_csv(npy, tmp_path / "signals.csv")
    assert (tmp_path / "signals.csv").read_text() == HEADER + ROWS[0]


def test_csv_is_written_under_a_part_name_and_renamed_when_whole(tmp_path, monkeypatch):
    """While it is written the file is ``signals.csv.part`` (a kill leaves no truncated signals.csv);
    the rename moves the complete file into place."""
    npy = _recording(tmp_path / "signals.npy", rows=5)
    real = os.replace
    seen = []

    def replace(src, dst):
        seen.append((Path(src).name, Path(dst).name, Path(src).read_text()))
        real(src, dst)
    monkeypatch.setattr(recording.os, "replace", replace)
    write_csv(npy, tmp_path / "signals.csv", chunk=2)
    assert seen == [("signals.csv.part", "signals.csv", HEADER + "".join(ROWS))]


def test_an_interrupted_csv_leaves_no_file_behind(tmp_path, monkeypatch):
    npy = _recording(tmp_path / "signals.npy")

    def replace(src, dst):
        raise KeyboardInterrupt
    monkeypatch.setattr(recording.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        write_csv(npy, tmp_path / "signals.csv")
    assert [p.name for p in tmp_path.iterdir()] == ["signals.npy"]


def test_a_csv_that_cannot_be_created_raises_that_error_alone(tmp_path):
    """The clean-up of the partial file adds nothing when there is none: the error is the one from
    creating the file (no second error chained to it)."""
    npy = _recording(tmp_path / "signals.npy")
    with pytest.raises(FileNotFoundError) as err:
        write_csv(npy, tmp_path / "missing" / "signals.csv")
    assert err.value.filename == str(tmp_path / "missing" / "signals.csv.part")
    assert err.value.__context__ is None


# ---------------------------------------------------------------------- the results folder
def test_make_folder_on_a_file_names_the_option_and_the_folder(tmp_path):
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(OutputError) as err:
        make_folder(f)
    assert str(err.value) == f"--out {f}: exists and is not a folder"
    with pytest.raises(OutputError) as err:
        make_folder(f, "[runs] out")
    assert str(err.value) == f"[runs] out {f}: exists and is not a folder"


def test_make_folder_under_a_file_says_why_in_words(tmp_path):
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(OutputError) as err:
        make_folder(f / "sub")
    assert str(err.value) == f"--out {f / 'sub'}: cannot write there (Not a directory)"


def test_make_folder_creates_parents_and_leaves_no_probe(tmp_path):
    got = make_folder(tmp_path / "a" / "b")
    assert got == tmp_path / "a" / "b" and got.is_dir()
    assert list(got.iterdir()) == []


# ---------------------------------------------------------------------- the row buffer
def _row(t: float, *more: float) -> bytes:
    return np.array([t, *more], dtype="<f8").tobytes()


@pytest.mark.parametrize("extra", [(), (2.5, 3.5)])
def test_last_time_is_the_time_of_the_last_buffered_row(tmp_path, extra):
    rec = NpyRecorder(tmp_path / "s.npy", ["time"] + [f"x{i}" for i in range(len(extra))])
    rows = RowBuffer(rec, list(range(1 + len(extra))), 1 + len(extra))
    assert rows.last_time() is None
    for t in (0.25, 0.5, 0.75):
        rows.chunk.append(_row(t, *extra))
        assert rows.last_time() == t
    rows.flush()
    assert rows.last_time() is None
    rec.close()
    assert np.load(tmp_path / "s.npy")["time"].tolist() == [0.25, 0.5, 0.75]


def test_the_csv_writer_reads_the_recording_a_chunk_at_a_time(tmp_path):
    """Memory for the CSV is bounded by the chunk, not by the recording: 10,000 rows of 4 columns
    (320 kB of data) are written 100 rows at a time with less than 200 kB allocated at the peak
    (numpy's allocations are traced by tracemalloc)."""
    import tracemalloc

    rec = NpyRecorder(tmp_path / "signals.npy", ["time", "a", "b", "c"])
    t = np.arange(10_000) * 1e-3
    rec.append([t, np.sin(t), np.cos(t), t * t])
    rec.close()
    del rec, t
    tracemalloc.start()
    try:
        write_csv(tmp_path / "signals.npy", tmp_path / "signals.csv", chunk=100)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 200_000, peak
    assert (tmp_path / "signals.csv").read_text().count("\n") == 10_001


# ---------------------------------------------------------------------- the output lock
def test_the_output_lock_refuses_a_second_run_naming_the_holder(tmp_path):
    from wmr_cosim.cosim.results.recording import OutputLock

    with OutputLock(tmp_path) as lock:
        assert (tmp_path / ".wmr-cosim.lock").read_text() == f"{os.getpid()}\n"
        with pytest.raises(OutputError) as err:
            OutputLock(tmp_path).acquire()
        assert str(err.value) == (f"{tmp_path}: in use by another run (process {os.getpid()}): choose another --out "
                                  "or wait for it to finish")
        assert lock.path == tmp_path / ".wmr-cosim.lock"
    assert not (tmp_path / ".wmr-cosim.lock").exists()        # released: removed, and free again
    second = OutputLock(tmp_path).acquire()
    second.release()
    second.release()                                           # a second release does nothing
    assert list(tmp_path.iterdir()) == []


def test_a_lock_file_left_by_a_killed_run_is_taken_over(tmp_path):
    from wmr_cosim.cosim.results.recording import OutputLock

    (tmp_path / ".wmr-cosim.lock").write_text("999999999\nstale\n")   # no process holds its flock
    with OutputLock(tmp_path):
        assert (tmp_path / ".wmr-cosim.lock").read_text() == f"{os.getpid()}\n"


# ---------------------------------------------------------------------- the .npy recording
def test_the_npy_file_loads_after_every_append_with_a_header_of_fixed_length(tmp_path):
    path = tmp_path / "s.npy"
    rec = NpyRecorder(path, ["time", "x"])
    assert np.load(path).dtype == np.dtype([("time", "<f8"), ("x", "<f8")]) and len(np.load(path)) == 0
    header = path.stat().st_size
    assert header % 64 == 0
    rec.append([np.array([]), np.array([])])                  # nothing to add
    assert rec.rows == 0 and path.stat().st_size == header
    for n in (1, 3, 1000, 5000):
        rec.append([np.arange(n, dtype=float), np.full(n, 0.5)])
        assert path.stat().st_size == header + 16 * rec.rows
        assert len(np.load(path)) == rec.rows and np.load(path)["time"][-1] == n - 1
    rec.close()
    rec.close()
    assert path.stat().st_size == header + 16 * 6004
    d = np.load(path)
    assert rec.rows == 6004 and d["time"][-1] == 4999.0 and np.all(d["x"] == 0.5)


@pytest.mark.parametrize("memory", [False, True])
def test_a_native_loops_records_come_out_after_the_rows_taken_before_them(tmp_path, memory):
    """A native loop's records, written where ``reserve`` says (the buffer grown past its first size),
    are kept after the row taken in Python before them (the start row), in the order taken, as they were
    written (the buffer is used again after the flush: the recorder keeps its own copy)."""
    import ctypes

    from wmr_cosim.cosim.results.recording import MemoryRecorder

    rec = MemoryRecorder(["time", "x"]) if memory else NpyRecorder(tmp_path / "s.npy", ["time", "x"])
    rows = RowBuffer(rec, [0, 1], 2)
    rows.chunk.append(_row(0.0, 10.0))                        # the start row, taken in Python
    n = 3000                                                  # (more than the first store holds)
    addr = rows.reserve(n)
    block = np.array([(1.0 + i, 20.0 + i) for i in range(n)], rec.dtype)
    ctypes.memmove(addr, block.ctypes.data, block.nbytes)
    rows.took(n, -1, 0)
    assert rec.rows == 0 and rows.last_time() == float(n)
    rows.flush()
    assert rec.rows == n + 1 and rows.last_time() is None
    ctypes.memset(rows.reserve(n), 0, block.nbytes)          # (the buffer written again)
    data = np.array(rec.array())
    assert data["time"].tolist() == [float(i) for i in range(n + 1)] and data["x"][0] == 10.0
    rec.close()
    if not memory:
        assert np.array_equal(np.load(tmp_path / "s.npy"), data)
        assert (tmp_path / "s.npy").stat().st_size == 128 + 16 * (n + 1)


def test_a_process_killed_mid_recording_leaves_the_rows_committed(tmp_path):
    """The file is mapped into memory: a process killed (SIGKILL) after committing rows leaves them in
    the file, loadable, as many as its header says."""
    import subprocess
    import sys

    path = tmp_path / "s.npy"
    code = ("import os, signal, numpy as np\n"
            "from wmr_cosim.cosim.results.recording import NpyRecorder\n"
            f"rec = NpyRecorder({str(path)!r}, ['time', 'x'])\n"
            "rec.append([np.arange(2500.0), np.arange(2500.0) * 2])\n"
            "os.kill(os.getpid(), signal.SIGKILL)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True)
    assert p.returncode == -9, p.stderr
    d = np.load(path)
    assert len(d) == 2500 and d["x"][-1] == 4998.0


def test_column_names_outside_latin1_use_the_utf8_header(tmp_path):
    path = tmp_path / "s.npy"
    rec = NpyRecorder(path, ["time", "plant.α₁"], ["Real", "Real"])
    rec.append([np.array([0.0, 0.1]), np.array([1.0, 2.0])])
    rec.close()
    assert path.read_bytes()[6:8] == b"\x03\x00"
    assert np.load(path)["plant.α₁"].tolist() == [1.0, 2.0]
    latin = NpyRecorder(tmp_path / "l.npy", ["time", "é"])
    latin.close()
    assert (tmp_path / "l.npy").read_bytes()[6:8] == b"\x01\x00" and np.load(tmp_path / "l.npy").dtype.names == ("time", "é")


def test_append_converts_each_column_to_its_type(tmp_path):
    rec = NpyRecorder(tmp_path / "s.npy", ["time", "i", "b", "u8", "f4", "u64"],
                      ["Real", "Integer", "Boolean", "UInt8", "Float32", "UInt64"])
    rec.append([np.array([0.0, 1.0]), np.array([-3, 7], dtype=np.int64), np.array([0, 1], dtype=np.int64),
                np.array([255, 1], dtype=np.int64), np.array([0.5, 1.5]), np.array([-1, 3], dtype=np.int64)])
    with pytest.raises(ValueError) as err:
        rec.append([np.array([0.0])])
    assert str(err.value) == "1 columns for 6"
    rec.close()
    d = np.load(tmp_path / "s.npy")
    assert [d.dtype[n].str for n in d.dtype.names] == ["<f8", "<i4", "|b1", "|u1", "<f4", "<u8"]
    assert d["i"].tolist() == [-3, 7] and d["b"].tolist() == [False, True] and d["u8"].tolist() == [255, 1]
    assert d["u64"].tolist() == [2 ** 64 - 1, 3]          # an int64 column of UInt64 bits: reinterpreted


def test_a_float64_column_of_an_unsigned_type_is_converted_by_value(tmp_path):
    rec = NpyRecorder(tmp_path / "s.npy", ["time", "u64", "u8"], ["Real", "UInt64", "UInt8"])
    rec.append([np.array([0.0, 1.0]), np.array([5.0, 2.0 ** 40]), np.array([7.0, 200.0])])
    rec.close()
    d = np.load(tmp_path / "s.npy")
    assert d["u64"].tolist() == [5, 2 ** 40] and d["u8"].tolist() == [7, 200]


# ---------------------------------------------------------------------- the row buffer's check
def test_a_non_finite_recorded_real_stops_at_its_row(tmp_path):
    """Rows are [time, x, y] as float64 then [n] as int64; the recording takes time, y, n, x (slots 0, 2, 3
    and 1): the first non-finite real (in time order, then column order) names its column, value and time,
    and the rows up to it are written."""
    from wmr_cosim.cosim.messages.errors import RunError

    rec = NpyRecorder(tmp_path / "s.npy", ["time", "plant.y", "count", "ctrl.x"], ["Real", "Real", "Integer", "Real"])
    rows = RowBuffer(rec, [0, 2, 3, 1], 3, 1)
    for t, x, y, n in ((0.0, 1.0, 2.0, 7), (0.5, 1.5, 2.5, 8), (1.0, math.inf, math.nan, 9), (1.5, 0.0, 0.0, 10)):
        rows.chunk.append(np.array([t, x, y], "<f8").tobytes() + np.array([n], "<i8").tobytes())
    assert len(rows) == 4
    with pytest.raises(RunError) as err:
        rows.flush()
    assert str(err.value) == "plant.y is nan at t = 1 s (a non-finite output)"
    assert (err.value.instance, err.value.time) == ("plant", 1.0)
    assert len(rows) == 0
    rec.close()
    d = np.load(tmp_path / "s.npy")
    assert d["time"].tolist() == [0.0, 0.5, 1.0] and d["count"].tolist() == [7, 8, 9]
    assert d["ctrl.x"][:2].tolist() == [1.0, 1.5] and math.isinf(d["ctrl.x"][2])


def test_a_flush_of_finite_rows_writes_them_all(tmp_path):
    rec = NpyRecorder(tmp_path / "s.npy", ["time", "n"], ["Real", "Integer"])
    rows = RowBuffer(rec, [0, 1], 1, 1)
    rows.flush()                                              # nothing buffered: nothing written
    assert rec.rows == 0
    for t in range(3):
        rows.chunk.append(np.array([t / 2], "<f8").tobytes() + np.array([-t], "<i8").tobytes())
    rows.flush()
    rec.close()
    d = np.load(tmp_path / "s.npy")
    assert d["time"].tolist() == [0.0, 0.5, 1.0] and d["n"].tolist() == [0, -1, -2]


# ---------------------------------------------------------------------- whole files
def test_atomic_write_and_write_json_leave_whole_files_only(tmp_path):
    from wmr_cosim.cosim.results.recording import atomic_write, write_json

    atomic_write(tmp_path / "a.txt", "text")
    atomic_write(tmp_path / "b.bin", b"\x00\x01")
    write_json(tmp_path / "c.json", {"path": tmp_path, "x": [1, 2]})
    assert (tmp_path / "a.txt").read_text() == "text" and (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert (tmp_path / "c.json").read_text() == '{\n  "path": "%s",\n  "x": [\n    1,\n    2\n  ]\n}\n' % tmp_path
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.bin", "c.json"]
