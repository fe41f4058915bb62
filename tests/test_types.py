"""The generic master (cosim/) type-checks: mypy with [tool.mypy] of pyproject.toml on the package
wmr_cosim.cosim, read from this checkout's tree (wmr_cosim/cosim links to cosim/), reports no error."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow   # about ten seconds (mypy without a cache)
def test_the_master_type_checks(tmp_path):
    p = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
                        "--cache-dir", str(tmp_path / "mypy-cache"), "-p", "wmr_cosim.cosim"],
                       capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    checked = re.search(r"no issues found in (\d+) source files", p.stdout)
    assert checked, p.stdout
    # every module of cosim/: the package was found in this tree
    assert int(checked.group(1)) >= len(list((ROOT / "cosim").glob("*.py"))), p.stdout
