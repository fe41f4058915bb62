"""Recording to disk as the run goes: a structured .npy file whose header is rewritten at every flush,
so that whatever was recorded up to a failure (or a kill) loads with one ``numpy.load`` call.

``numpy.load('signals.npy')`` gives a structured array with one named float64 field per column
('time', 'plant.alpha1', ...); ``pandas.DataFrame(numpy.load('signals.npy'))`` gives a table.
"""
from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np
from numpy.lib import format as npformat



class NpyRecorder:
    """Append rows of float64 to a structured .npy file, keeping the file loadable after every flush."""

    def __init__(self, path: str | os.PathLike, columns: list[str]) -> None:
        self.path = Path(path)
        self.columns = list(columns)
        self.dtype = np.dtype([(c, "<f8") for c in self.columns])
        self.rows = 0
        self._fh = open(self.path, "wb+")
        self._write_header(0)

    def _write_header(self, rows: int) -> None:
        """Write the .npy 1.0 header for ``rows`` rows; its length never changes (room for 10^15 rows)."""
        d = {"descr": npformat.dtype_to_descr(self.dtype), "fortran_order": False, "shape": (rows,)}
        width = len(repr({**d, "shape": (10 ** 15,)}))
        body = repr(d).ljust(width)
        total = 10 + len(body) + 1  # magic (6) + version (2) + length (2) + body + newline
        body += " " * ((64 - total % 64) % 64) + "\n"
        self._fh.seek(0)
        self._fh.write(b"\x93NUMPY\x01\x00" + len(body).to_bytes(2, "little") + body.encode("latin1"))
        self._fh.flush()

    def append(self, block: np.ndarray) -> None:
        """Append a (rows, len(columns)) float64 block and make the file consistent on disk."""
        block = np.ascontiguousarray(block, dtype="<f8")
        if block.ndim != 2 or block.shape[1] != len(self.columns):
            raise ValueError(f"block of shape {block.shape} for {len(self.columns)} columns")
        if not block.shape[0]:
            return
        self._fh.seek(0, os.SEEK_END)
        self._fh.write(block.tobytes())
        self.rows += block.shape[0]
        self._write_header(self.rows)
        self._fh.flush()

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.flush()
            self._fh.close()


def write_csv(npy_path: str | os.PathLike, csv_path: str | os.PathLike) -> None:
    """The recording as CSV (header row of column names, full float precision)."""
    data = np.load(npy_path)
    names = data.dtype.names or ()
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        if len(data):
            arr = data.view("<f8").reshape(len(data), len(names))
            fh.writelines(",".join(map(repr, row)) + "\n" for row in arr.tolist())
