"""C of the master's own built at run time with the system's C compiler and kept in a cache folder under the
hash of its source, the compiler and the flags: the compiled stepping loop (:mod:`..stepping.native`) and
the step slot of an isolated C FMU (:mod:`.slot_c`).  No build step at install: a machine without a
compiler runs without them, and the run says why.

``CC`` names the compiler (default ``cc``); ``WMR_COSIM_CACHE`` the cache folder (default
``$XDG_CACHE_HOME/wmr-cosim``, else ``~/.cache/wmr-cosim``).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


class NoBuild(Exception):
    """The library cannot be built here; the message says why (a phrase)."""


def cache() -> Path:
    """The cache folder of the built libraries."""
    base = os.environ.get("WMR_COSIM_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "wmr-cosim")
    return Path(base)


def build(source: Path, stem: str, flags: list[str], what: str) -> Path:
    """The shared library of ``source``, compiled once per source, compiler and ``flags`` into the cache
    folder as ``<stem>-<hash>.so``; ``what`` names it in the reasons of :class:`NoBuild` ("the compiled
    loop")."""
    if sys.platform == "win32":
        raise NoBuild(f"no {what.removeprefix('the ')} on Windows yet")
    cc = os.environ.get("CC") or "cc"
    path = shutil.which(cc)
    if path is None:
        raise NoBuild(f"no C compiler ({cc}) on PATH")
    # the compiler known by the file it is (its links followed), its size and its time of change: no
    # process started where the library is in the cache (``cc --version`` costs milliseconds every run)
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
    except OSError as exc:
        raise NoBuild(f"the C compiler {path} does not run: {exc}") from None
    compiler = f"{real}\0{st.st_size}\0{st.st_mtime_ns}"
    key = hashlib.sha256("\0".join([source.read_text(), path, compiler, *flags]).encode()).hexdigest()[:20]
    lib = cache() / f"{stem}-{key}.so"
    if lib.is_file():
        return lib
    try:
        lib.parent.mkdir(parents=True, exist_ok=True)
        _compile(path, source, flags, lib)
    except OSError as exc:
        raise NoBuild(f"{what} cannot be built in {lib.parent}: {exc}") from None
    return lib


def _compile(cc: str, source: Path, flags: list[str], lib: Path) -> None:
    """``source`` compiled by ``cc`` into ``lib``, through a temporary file beside it (NoBuild if the
    compiler fails)."""
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=lib.parent)
    os.close(fd)
    try:
        p = subprocess.run([cc, *flags, str(source), "-o", tmp], capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.SubprocessError) as exc:
        os.unlink(tmp)
        raise NoBuild(f"the C compiler {cc} does not run: {exc}") from None
    if p.returncode:
        os.unlink(tmp)
        raise NoBuild(f"the C compiler {cc} failed on {source.name}: {p.stderr.strip()[:300]}")
    os.replace(tmp, lib)   # (atomic: a process that builds it at the same time writes the same file)
