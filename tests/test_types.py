"""The whole package type-checks: mypy with [tool.mypy] of pyproject.toml on the package wmr_cosim, read
from this checkout's tree (the generic master cosim/, the components/, the fmus/ and the scenarios/ through
their links wmr_cosim/cosim -> ../cosim, ...; the application in wmr_cosim's own folders), reports no error."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _modules() -> int:
    """The .py files of the package in this tree: wmr_cosim's own and those of every folder it links to."""
    package = ROOT / "wmr_cosim"
    linked = [d for d in package.iterdir() if d.is_symlink() and d.is_dir()]
    assert {"cosim", "components", "fmus"} <= {d.name for d in linked}, linked
    own = [p for p in package.rglob("*.py") if not any(p.is_relative_to(d) for d in linked)]
    return len(own) + sum(len(list(d.resolve().rglob("*.py"))) for d in linked)


@pytest.mark.slow   # about half a minute (mypy without a cache)
def test_the_package_type_checks(tmp_path):
    p = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
                        "--cache-dir", str(tmp_path / "mypy-cache"), "-p", "wmr_cosim"],
                       capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert p.returncode == 0, p.stdout + p.stderr
    checked = re.search(r"no issues found in (\d+) source files", p.stdout)
    assert checked, p.stdout
    # every module of the package, the linked folders' too: the package was found in this tree, whole
    assert int(checked.group(1)) >= _modules(), p.stdout
