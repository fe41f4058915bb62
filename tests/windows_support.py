"""Windows for the tests, on Linux: MinGW-w64 (Debian's ``gcc-mingw-w64-x86-64``) builds win64 binaries,
Wine (Debian's ``wine64``) runs them.  One Wine prefix and one persistent ``wineserver`` serve a whole
test session (creating a prefix takes seconds; a program run in it then a fraction of one); a test that
needs either tool skips, saying which package is missing."""
from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path
from typing import Iterator

import pytest

#: Where Debian's wine64 puts its programs (its /usr/bin/wine is a wrapper that wants the 32-bit part).
WINE_DIR = Path("/usr/lib/wine")
MINGW_CC = "x86_64-w64-mingw32-gcc"
MINGW_OBJDUMP = "x86_64-w64-mingw32-objdump"


def mingw_cc() -> str:
    """The MinGW-w64 C compiler, or a skip with the package to install."""
    cc = shutil.which(MINGW_CC)
    if cc is None:
        pytest.skip(f"{MINGW_CC} not on PATH (Debian: apt-get install gcc-mingw-w64-x86-64)")
    return cc


def _headers(dll: Path) -> str:
    """A PE file's headers as MinGW-w64's objdump prints them (``-p``)."""
    objdump = shutil.which(MINGW_OBJDUMP) or pytest.skip(f"{MINGW_OBJDUMP} not on PATH")
    return subprocess.run([objdump, "-p", str(dll)], capture_output=True, text=True, check=True).stdout


def pe_imports(dll: Path) -> list[str]:
    """The DLLs a PE file imports."""
    return [ln.split(":", 1)[1].strip() for ln in _headers(dll).splitlines() if ln.strip().startswith("DLL Name:")]


def pe_exports(dll: Path) -> set[str]:
    """The names a PE file exports."""
    names, table = set(), False
    for ln in _headers(dll).splitlines():
        if "[Ordinal/Name Pointer] Table" in ln:
            table = True
        elif table and ln.strip().startswith("["):
            names.add(ln.split()[-1])
        elif table and not ln.strip():
            break
    return names


class Wine:
    """A Wine prefix of its own with a persistent wineserver: :meth:`run` a Windows program in it."""

    def __init__(self, prefix: Path) -> None:
        self.wine64, self.wineserver = WINE_DIR / "wine64", WINE_DIR / "wineserver"
        self.prefix = prefix
        (prefix.parent / "tmp").mkdir(exist_ok=True)   # (Wine's own temporary files: not in the system's)
        self.env = {**os.environ, "WINEPREFIX": str(prefix), "WINEDEBUG": "-all", "TMPDIR": str(prefix.parent / "tmp"),
                    "WINEDLLOVERRIDES": "mscoree,mshtml="}   # (no Mono or Gecko installer asked for)

        prefix.mkdir(parents=True)   # (a wineserver started first needs the folder; the first run fills it)
        subprocess.run([str(self.wineserver), "-p"], env=self.env, check=True, timeout=60)

    def run(self, *argv: str | Path, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
        """``argv`` (a .exe first) under Wine; its output as text.  The output goes through files: the
        wineserver inherits a pipe's end and keeps it open, so that a reader of a pipe would wait for it."""
        out, err = self.prefix.parent / "stdout", self.prefix.parent / "stderr"
        with open(out, "w") as o, open(err, "w") as e:
            p = subprocess.run([str(self.wine64), *map(str, argv)], env=self.env, stdout=o, stderr=e,
                               timeout=timeout, stdin=subprocess.DEVNULL)
        return subprocess.CompletedProcess(p.args, p.returncode, out.read_text(), err.read_text())

    def stop(self) -> None:
        subprocess.run([str(self.wineserver), "-k"], env=self.env, timeout=60)
        subprocess.run([str(self.wineserver), "-w"], env=self.env, timeout=60)


def wine_session(tmp: Path) -> Iterator[Wine]:
    """A :class:`Wine` for the session (a skip where Wine is not installed), stopped at its end."""
    if not (WINE_DIR / "wine64").is_file() or not (WINE_DIR / "wineserver").is_file():
        pytest.skip(f"{WINE_DIR}/wine64 not found (Debian: apt-get install wine64)")
    wine = Wine(tmp / "prefix")
    try:
        first = wine.run("cmd", "/c", "echo", "ready", timeout=180)   # (the prefix is made here: seconds)
        if "ready" not in first.stdout:
            pytest.skip(f"Wine does not run programs here: {(first.stderr or first.stdout).strip()[-300:]}")
        yield wine
    finally:
        wine.stop()
        for d in ("prefix", "tmp"):
            shutil.rmtree(tmp / d, ignore_errors=True)
