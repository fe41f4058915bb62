"""Reading a results folder back (``plot``, the analyses, the sweeps' metrics): signals.npy and the JSON
files, whatever a killed run, a copy cut short or a stranger left there.  A file that cannot be read is one
line naming it and what is wrong (:class:`ResultsError`); the rows of a recording cut short are data: a
run killed at 10 s of 40 has 10 s of signals, and they are read (with a note saying how many rows the
header promised)."""
from __future__ import annotations

import ast
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..messages.errors import CosimError

#: The longest .npy header read [bytes] (the recorder's header is a few kilobytes for a thousand columns).
MAX_HEADER = 1 << 24
_MAGIC = b"\x93NUMPY"


class ResultsError(CosimError):
    """A file of a results folder cannot be read: the message (one line) names the file and why."""


@dataclass
class Recording:
    """signals.npy read back: its rows (a structured array with a ``time`` field [s]) and, when the file
    holds fewer rows than its header says (a run killed between writing rows and its header, a copy cut
    short), a note saying so."""

    signals: np.ndarray
    note: str | None = None


def read_signals(path: str | os.PathLike) -> Recording:
    """signals.npy (or any recording the recorder writes) at ``path``: every whole row it holds.
    ResultsError when it is empty, not a .npy file, its header is cut or malformed, or it is not a
    recording (a one-dimensional structured array with a ``time`` field and no Python objects)."""
    path = Path(path)
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(12)
            if not head:
                raise ResultsError(f"{path}: empty (0 bytes): the run wrote nothing (it was killed before its "
                                   "first row, or the file was cut)")
            if head[:6] != _MAGIC[:len(head)] or (len(head) > 6 and head[6] not in (1, 2, 3)):
                raise ResultsError(f"{path}: not a .npy file (it begins {head[:8]!r})")
            if len(head) < 8:
                raise ResultsError(f"{path}: cut inside its header ({size} bytes)")
            major = head[6]
            width = 2 if major == 1 else 4
            if len(head) < 8 + width:
                raise ResultsError(f"{path}: cut inside its header ({size} bytes)")
            hlen = int.from_bytes(head[8:8 + width], "little")
            start = 8 + width + hlen
            if hlen > MAX_HEADER:
                raise ResultsError(f"{path}: not a recording (a header of {hlen} bytes)")
            if start > size:
                raise ResultsError(f"{path}: cut inside its header ({size} bytes of {start})")
            fh.seek(8 + width)
            text = fh.read(hlen)
            dtype, rows = _header(path, text.decode("utf-8" if major == 3 else "latin-1", errors="replace"))
            whole = (size - start) // dtype.itemsize if dtype.itemsize else rows
            fh.seek(start)
            signals = np.fromfile(fh, dtype=dtype, count=min(rows, whole))
    except OSError as exc:
        raise ResultsError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    note = None
    if whole < rows:
        note = (f"{path}: {whole} of the {rows} rows its header gives are in the file (it was cut short): "
                f"the {whole} are read")
    return Recording(signals, note)


def _header(path: Path, text: str) -> tuple[np.dtype, int]:
    """The dtype and row count a .npy header gives, when it is a recording's."""
    try:
        d = ast.literal_eval(text.strip())
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        raise ResultsError(f"{path}: not a .npy file (its header is not a Python literal)") from None
    if not isinstance(d, dict) or not {"descr", "shape", "fortran_order"} <= set(d):
        raise ResultsError(f"{path}: not a .npy file (its header lacks descr, shape or fortran_order)")
    try:
        dtype = np.lib.format.descr_to_dtype(d["descr"])
    except (ValueError, TypeError, KeyError, IndexError):
        raise ResultsError(f"{path}: not a .npy file (its header's descr is not a dtype)") from None
    shape = d["shape"]
    if dtype.names is None or "time" not in dtype.names:
        raise ResultsError(f"{path}: not a recording (no time column)")
    if dtype.hasobject:
        raise ResultsError(f"{path}: not a recording (it holds Python objects)")
    if not (isinstance(shape, tuple) and len(shape) == 1 and isinstance(shape[0], int) and shape[0] >= 0):
        raise ResultsError(f"{path}: not a recording (shape {shape!r}, not a list of rows)")
    return dtype, shape[0]


def read_json(path: str | os.PathLike, fields: dict[str, type | tuple[type, ...]] | None = None) -> dict[str, Any]:
    """A JSON file of a results folder (summary.json, scenario.json; {} when it is absent): ResultsError
    when it is empty, not UTF-8 JSON, not an object, or one of ``fields`` (name -> the type it must have,
    where present and not null) has another type."""
    path = Path(path)
    if not path.is_file():
        return {}
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ResultsError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not raw.strip():
        raise ResultsError(f"{path}: empty: the run wrote nothing there (it was killed, or the file was cut)")
    try:
        doc = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ResultsError(f"{path}: not UTF-8 (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise ResultsError(f"{path}: not valid JSON (line {exc.lineno} column {exc.colno}: {exc.msg})") from None
    except RecursionError:
        raise ResultsError(f"{path}: not valid JSON (nested too deeply)") from None
    if not isinstance(doc, dict):
        raise ResultsError(f"{path}: not a JSON object ({_json_type(doc)})")
    for name, kind in (fields or {}).items():
        value = doc.get(name)
        if value is not None and not isinstance(value, kind):
            want = " or ".join(_json_type(k()) for k in (kind if isinstance(kind, tuple) else (kind,)))
            raise ResultsError(f"{path}: {name}: {want} expected, not {_json_type(value)}")
    return doc


def _json_type(value: Any) -> str:
    """What JSON calls the type of ``value``, with its article ("an array")."""
    for kind, name in ((bool, "a boolean"), ((int, float), "a number"), (str, "a string"), (list, "an array"),
                       (dict, "an object")):
        if isinstance(value, kind):
            return name
    return "null"
