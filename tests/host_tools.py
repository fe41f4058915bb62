"""The prebuilt third-party FMI hosts the tests compare against (fmusim, OMSimulator): C/C++ programs that
no package index provides.  They are looked for in the folder ``WMR_HOST_TOOLS`` names, else in the
folder ``tools`` of a folder ``shared`` beside the checkout (fmusim in ``fmusim/fmusim``, OMSimulator in
``omsimulator/bin/OMSimulator``); a test that needs one skips, saying why, where it is absent or cannot
start (fmusim needs Debian's libxml2, libminizip1 and libsundials-cvode6; OMSimulator libcurl4 and
libicu72)."""
from __future__ import annotations

import os
import subprocess
from functools import lru_cache
from pathlib import Path

import pytest

TOOLS = Path(os.environ.get("WMR_HOST_TOOLS") or Path(__file__).resolve().parents[2] / "shared" / "tools")
FMUSIM = "fmusim/fmusim"
OMSIMULATOR = "omsimulator/bin/OMSimulator"


@lru_cache(maxsize=None)
def problem(relative: str) -> str | None:
    """Why the tool at ``relative`` (below TOOLS) cannot be used here, or None when ``--version`` runs."""
    exe = TOOLS / relative
    if not exe.is_file():
        return f"{exe} not found (the prebuilt third-party hosts are not beside this checkout)"
    try:
        p = subprocess.run([str(exe), "--version"], capture_output=True, text=True, env={}, timeout=60)
    except OSError as exc:
        return f"{exe.name} cannot start here: {exc}"
    if p.returncode != 0 or "error while loading shared libraries" in p.stderr:
        return f"{exe.name} cannot start here (exit {p.returncode}): {(p.stderr or p.stdout).strip()[-300:]}"
    return None


def tool(relative: str) -> Path:
    """The tool's executable, or a skip with the reason."""
    why = problem(relative)
    if why is not None:
        pytest.skip(why)
    return TOOLS / relative
