"""Recording (the observers): the row buffer flushed to a structured .npy file as the run goes, the
CSV written from it in bounded chunks, and result files that exist only when whole.

``numpy.load('signals.npy')`` gives a structured array with one named field per column: 'time' and every
Real as float64, Integer and Enumeration as int32, Boolean as bool ('plant.alpha1', ...);
``pandas.DataFrame(numpy.load('signals.npy'))`` gives a table.  The header is rewritten at every flush,
so whatever was recorded up to a failure (or a kill) loads with one call.
"""
from __future__ import annotations

import json
import os
from decimal import Decimal
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.lib import format as npformat

from ..messages.errors import OutputError, RunError

#: FMI type -> column dtype in signals.npy (FMI 2.0 Real, Integer, Enumeration, Boolean; FMI 3.0 types).
DTYPES: dict[str, str] = {"Real": "<f8", "Integer": "<i4", "Enumeration": "<i4", "Boolean": "?",
                          "Float64": "<f8", "Float32": "<f4", "Int8": "<i1", "UInt8": "<u1", "Int16": "<i2",
                          "UInt16": "<u2", "Int32": "<i4", "UInt32": "<u4", "Int64": "<i8", "UInt64": "<u8"}
#: Rows of the CSV converted at a time (bounds the memory the CSV writer needs).
CSV_CHUNK = 20000


LOCK_NAME = ".wmr-cosim.lock"


class OutputLock:
    """An exclusive lock on a results folder (``.wmr-cosim.lock`` inside it, held with flock): a second
    run into the same folder is refused at once, naming the holder's process id.  The kernel releases the
    lock when its process ends, so a lock left by a killed run is simply taken over."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self._fh: IO[str] | None = None

    def acquire(self) -> "OutputLock":
        import fcntl

        fh = open(self.path, "a+")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            holder = fh.read().strip() or "?"
            fh.close()
            raise OutputError(f"{self.folder}: in use by another run (process {holder}): choose another --out "
                              "or wait for it to finish") from None
        fh.seek(0)
        fh.truncate()
        fh.write(f"{os.getpid()}\n")
        fh.flush()
        self._fh = fh
        return self

    def release(self) -> None:
        if self._fh is not None:
            try:
                self.path.unlink(missing_ok=True)
            finally:
                self._fh.close()  # closing releases the flock
                self._fh = None

    def __enter__(self) -> "OutputLock":
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def make_folder(folder: Path, what: str = "--out") -> Path:
    """Create ``folder`` (and its parents) and make sure files can be written in it; OutputError (one line)
    if not: under a regular file, on an existing file, read-only, in /proc, ..."""
    folder = Path(folder)
    try:
        if folder.exists() and not folder.is_dir():
            raise OutputError(f"{what} {folder}: exists and is not a folder")
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".wmr-cosim-probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OutputError:
        raise
    except OSError as exc:
        raise OutputError(f"{what} {folder}: cannot write there ({exc.strerror or exc})") from None
    return folder


def atomic_write(path: Path, data: str | bytes) -> None:
    """Write ``path`` through a temporary name and rename it: a file that exists is whole."""
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as fh:
        fh.write(data.encode() if isinstance(data, str) else data)
    os.replace(tmp, path)


def write_json(path: Path, obj: Any) -> None:
    atomic_write(path, json.dumps(obj, indent=2, default=str) + "\n")


class RecordedRows:
    """The recorded rows, in the structured dtype of signals.npy (one field per column: Real as float64,
    integers and enumerations as their FMI type, Boolean as bool), appended as the run goes."""

    def __init__(self, columns: list[str], types: list[str] | None = None) -> None:
        self.columns = list(columns)
        types = types or ["Real"] * len(columns)
        self.dtype = np.dtype([(c, DTYPES[t]) for c, t in zip(self.columns, types)])
        self.rows = 0

    def append(self, cols: list[np.ndarray]) -> None:
        """Append rows given as one array per column (float64 or int64), each converted to its type
        (an int64 column of an unsigned type is reinterpreted bit for bit)."""
        if len(cols) != len(self.columns):
            raise ValueError(f"{len(cols)} columns for {len(self.columns)}")
        n = len(cols[0]) if cols else 0
        if not n:
            return
        rec = np.empty(n, self.dtype)
        for name, col in zip(self.columns, cols):
            kind = self.dtype[name].kind
            rec[name] = col.view(np.uint64) if kind == "u" and col.dtype == np.int64 else col
        self.append_records(rec)

    def append_records(self, rec: np.ndarray) -> None:
        """Append rows given as records of this dtype (contiguous; copied or written out at once: ``rec``
        may be a view of a buffer written again)."""
        if len(rec):
            self._write(rec.view(np.uint8))
            self.rows += len(rec)

    def _write(self, data: np.ndarray) -> None:
        """The records' bytes kept."""
        raise NotImplementedError

    def array(self) -> np.ndarray:
        """Every row written so far."""
        raise NotImplementedError

    def close(self) -> None:
        pass


class NpyRecorder(RecordedRows):
    """Rows appended to a structured .npy file, its header rewritten after every append so that the file
    loads whole at any time (what a process that dies leaves is in the file)."""

    def __init__(self, path: str | os.PathLike, columns: list[str], types: list[str] | None = None) -> None:
        super().__init__(columns, types)
        self.path = Path(path)
        d = {"descr": npformat.dtype_to_descr(self.dtype), "fortran_order": False, "shape": (10 ** 15,)}
        self._descr = repr(d).rsplit("'shape'", 1)[0]
        self._width = len(repr(d))
        self._fd: int | None = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o666)
        head = self._header(0)
        self._end = len(head)    # where the next row goes [bytes]
        os.pwrite(self._fd, head, 0)

    def _header(self, rows: int) -> bytes:
        """The .npy 1.0 header for ``rows`` rows; its length never changes (room for 10^15 rows).  Column
        names outside Latin-1 need the .npy 3.0 header (UTF-8)."""
        body = (self._descr + f"'shape': ({rows},)}}").ljust(self._width)
        try:
            body.encode("latin1")
            version, enc, nlen = b"\x01\x00", "latin1", 2
        except UnicodeEncodeError:
            version, enc, nlen = b"\x03\x00", "utf8", 4
        encoded = body.encode(enc)
        total = 8 + nlen + len(encoded) + 1
        encoded += b" " * ((64 - total % 64) % 64) + b"\n"
        return b"\x93NUMPY" + version + len(encoded).to_bytes(nlen, "little") + encoded

    def _write(self, data: np.ndarray) -> None:
        """The rows' bytes written after the last (straight from ``data``: no copy), then the header."""
        assert self._fd is not None
        view = data.data   # (bytes, not copied)
        while len(view):
            n = os.pwrite(self._fd, view, self._end)
            self._end += n
            view = view[n:]
        os.pwrite(self._fd, self._header(self.rows + len(data) // self.dtype.itemsize), 0)

    def array(self) -> np.ndarray:
        """The rows, read back from the file (mapped, not loaded)."""
        return np.load(self.path, mmap_mode="r")

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


class MemoryRecorder(RecordedRows):
    """The rows kept in memory (a run without a results folder: the Python API's in-memory run), in one
    store grown by doubling."""

    def __init__(self, columns: list[str], types: list[str] | None = None) -> None:
        super().__init__(columns, types)
        self._store = np.empty(0, self.dtype)

    def _write(self, data: np.ndarray) -> None:
        n = len(data) // self.dtype.itemsize
        if self.rows + n > len(self._store):
            grown = np.empty(max(self.rows + n, 2 * len(self._store), 1024), self.dtype)
            grown.view(np.uint8)[:self.rows * self.dtype.itemsize] = self._store[:self.rows].view(np.uint8)
            self._store = grown
        self._store[self.rows:self.rows + n].view(np.uint8)[:] = data

    def array(self) -> np.ndarray:
        """Every row so far."""
        return self._store[:self.rows]


#: A recorded column's conversion in a native loop (native_loop.c's REC_*): from a double (the type in
#: signals.npy) and from a 64-bit integer.
_REC_FROM_DOUBLE = {"<f8": 0, "<f4": 1}
_REC_FROM_INT = {"|i1": 2, "<i2": 3, "<i4": 4, "<i8": 5, "|u1": 6, "<u2": 7, "<u4": 8, "<u8": 9, "|b1": 10}


class _Records:
    """A run of ``n`` records written by a native loop at ``start`` of the buffer, the first non-finite real
    in record ``bad_row`` of them (-1: none), column ``bad_col``."""

    __slots__ = ("start", "n", "bad_row", "bad_col")

    def __init__(self, start: int, n: int, bad_row: int, bad_col: int) -> None:
        self.start, self.n, self.bad_row, self.bad_col = start, n, bad_row, bad_col


class RowBuffer:
    """The rows of the current segment (``bytes`` of the master's row buffer: ``n_double`` float64 slots,
    then ``n_int`` int64 slots), flushed to the recorder with a check that every recorded real is finite.
    A native loop may instead write the rows as the recorder's records straight into this buffer's
    records (:meth:`reserve`, :meth:`took`: ``stepping.algorithm.RecordSink``; :attr:`takes_records` False
    where a column's conversion is not one it makes), checking the reals as it writes them; the flush
    hands them to the recorder as they are (one write of their bytes to signals.npy)."""

    def __init__(self, recorder: RecordedRows, cols: list[int], n_double: int, n_int: int = 0) -> None:
        self.recorder = recorder
        self.cols = list(cols)
        self.n_double = n_double
        self.dtype = np.dtype([("d", "<f8", (n_double,)), ("i", "<i8", (n_int,))])
        self.chunk: list[Any] = []     # each a row, or several (:meth:`extend`), or a run of records
        self.more = 0                  # the rows beyond one per element of chunk
        self.record_bytes = recorder.dtype.itemsize
        layout = self._layout()
        self.columns: list[tuple[int, int, int]] = layout or []
        self.takes_records = layout is not None   # False: a column's conversion is not one the loop makes
        self.records = np.empty(0, recorder.dtype)   # the records written by a native loop, not yet flushed
        self.fill = 0

    def _layout(self) -> list[tuple[int, int, int]] | None:
        """Per recorded column: (its value's byte offset in the row, its conversion, its byte offset in the
        record); None where one is not a conversion the native loop makes."""
        out = []
        fields = self.recorder.dtype.fields
        assert fields is not None
        for name, c in zip(self.recorder.columns, self.cols):
            dt, dst = fields[name][:2]
            kind = (_REC_FROM_DOUBLE if c < self.n_double else _REC_FROM_INT).get(dt.str)
            if kind is None:
                return None
            out.append((8 * c, kind, dst))
        return out

    def __len__(self) -> int:
        return len(self.chunk) + self.more

    def extend(self, rows: bytes, n: int) -> None:
        """Take ``n`` whole rows at once (a compiled loop's segment)."""
        self.chunk.append(rows)
        self.more += n - 1

    def reserve(self, n: int) -> int:
        """The address where up to ``n`` records may be written next (the buffer grown if need be: it is
        used again after each flush, so it stays in the cache)."""
        if self.fill + n > len(self.records):
            grown = np.empty(max(2 * len(self.records), self.fill + n), self.recorder.dtype)
            grown.view(np.uint8)[:self.fill * self.record_bytes] = self.records[:self.fill].view(np.uint8)
            self.records = grown
        return int(self.records.ctypes.data) + self.fill * self.record_bytes

    def took(self, n: int, bad_row: int, bad_col: int) -> None:
        """``n`` records were written where :meth:`reserve` said (the first non-finite real: record
        ``bad_row`` of them, -1: none, column ``bad_col``)."""
        self.chunk.append(_Records(self.fill, n, bad_row, bad_col))
        self.more += n - 1
        self.fill += n

    def last_time(self) -> float | None:
        if not self.chunk:
            return None
        last = self.chunk[-1]
        if isinstance(last, _Records):
            rec = self.records[last.start + last.n - 1]
            return float(rec[self.recorder.columns[self.cols.index(0)]])
        return float(np.frombuffer(last, "<f8", 1, len(last) - self.dtype.itemsize)[0])

    def flush(self) -> None:
        """Write the rows; RunError at the first non-finite value (rows up to it are written)."""
        if not self.chunk:
            return
        chunk = self.chunk[:]
        self.chunk.clear()   # (the same list: the recording's take appends to it)
        self.more = 0
        try:
            rows: list[bytes] = []
            for item in chunk:
                if not isinstance(item, _Records):
                    rows.append(item)
                    continue
                if rows:
                    self._rows(rows)
                    rows = []
                self._records(item)
            if rows:
                self._rows(rows)
        finally:
            self.fill = 0

    def _records(self, r: _Records) -> None:
        """A native loop's records handed to the recorder (up to the first non-finite real)."""
        block = self.records[r.start:r.start + r.n]
        self.recorder.append_records(block[:r.n if r.bad_row < 0 else r.bad_row + 1])
        if r.bad_row < 0:
            return
        columns = self.recorder.columns
        reals = [j for j, c in enumerate(self.cols) if c < self.n_double]
        name = columns[r.bad_col]
        row = block[r.bad_row]
        value, t = float(row[name]), float(row[columns[reals[0]]])
        raise RunError(f"{name} is {value!r} at t = {t:.6g} s (a non-finite output)", name.split(".", 1)[0], t)

    def _rows(self, chunk: list[bytes]) -> None:
        raw = np.frombuffer(b"".join(chunk), dtype=self.dtype)
        d, i = raw["d"], raw["i"]
        cols = [d[:, c] if c < self.n_double else i[:, c - self.n_double] for c in self.cols]
        reals = [j for j, c in enumerate(self.cols) if c < self.n_double]
        block = np.column_stack([cols[j] for j in reals])
        finite = np.isfinite(block)
        if not finite.all():
            r, c = np.argwhere(~finite)[0]
            self.recorder.append([col[: r + 1] for col in cols])
            name = self.recorder.columns[reals[c]]
            raise RunError(f"{name} is {float(block[r, c])!r} at t = {block[r, 0]:.6g} s (a non-finite output)",
                           name.split(".", 1)[0], float(block[r, 0]))
        self.recorder.append(cols)


def _decimals(x: float) -> int:
    """The digits after the decimal point of ``x`` as Python writes it (0.002 -> 3, 1e-05 -> 5, 2.0 -> 0)."""
    exponent = Decimal(repr(float(x))).as_tuple().exponent
    return -exponent if isinstance(exponent, int) and exponent < 0 else 0


def grid_times(times: np.ndarray, start: float, step: float) -> np.ndarray:
    """The recorded times as the grid's: a time within rounding of a point ``start + k * step`` becomes
    that point written with the decimals of ``start`` and ``step`` (0.30000000000000004 -> 0.3 for a step
    of 0.002); a time off the grid (an FMU that ended the run between two points), and every time when
    those decimals are more than a float64 holds, stays as recorded."""
    d = max(_decimals(start), _decimals(step))
    if d > 15:
        return times
    rounded = np.round(times, d)
    near = np.abs(rounded - times) <= np.maximum(1e-9 * step, 64 * np.spacing(np.abs(times)))
    return np.where(near, rounded, times)


def write_csv(npy_path: str | os.PathLike, csv_path: str | os.PathLike, chunk: int = CSV_CHUNK, *,
              start: float = 0.0, step: float | None = None) -> None:
    """The recording as CSV (header row of column names; floats at full precision, integers as integers,
    booleans as 0/1), converted ``chunk`` rows at a time and renamed into place when complete.  With the
    grid's ``step`` (and ``start``) [s], the time column is written as the grid's times
    (:func:`grid_times`: 0.3, not 0.30000000000000004); the .npy file keeps the values as computed."""
    data = np.load(npy_path, mmap_mode="r")
    names = data.dtype.names or ()
    csv_path = Path(csv_path)
    tmp = csv_path.with_name(csv_path.name + ".part")
    line = ",".join(["%r"] * len(names))   # Python floats and ints: repr is full precision
    try:
        with open(tmp, "w", newline="") as fh:
            fh.write(",".join(_csv_name(n) for n in names) + "\n")
            for i in range(0, len(data), chunk):
                part = data[i:i + chunk]
                # booleans as 0/1; integers as Python ints (an unsigned 64-bit value in full)
                cols = [part[n].astype(np.int64).tolist() if data.dtype[n].kind == "b" else part[n].tolist()
                        for n in names]
                if step is not None and "time" in names:
                    cols[names.index("time")] = grid_times(np.asarray(part["time"]), start, step).tolist()
                fh.writelines(line % row + "\n" for row in zip(*cols))
        os.replace(tmp, csv_path)
    except BaseException:  # interrupted or failed: no partial file left behind
        tmp.unlink(missing_ok=True)
        raise


def _csv_name(name: str) -> str:
    return '"' + name.replace('"', '""') + '"' if any(ch in name for ch in ',"\n') else name
