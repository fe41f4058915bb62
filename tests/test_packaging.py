"""The project installs as one distribution whose import names are all under wmr_cosim, and a
non-editable install works (package data included) from any working directory."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_components_import_no_fmi():
    """Nothing in components/ imports FMI (fmpy, pythonfmu)."""
    for f in (ROOT / "components").glob("*.py"):
        text = f.read_text()
        assert "fmpy" not in text and "pythonfmu" not in text, f
        # relative imports only, so the folder can be bundled under another package name
        assert "wmr_cosim" not in text.replace("wmr_cosim.components", ""), f


def test_non_editable_install_works(tmp_path):
    target = tmp_path / "site packages"
    p = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                        "--target", str(target), str(ROOT)], capture_output=True, text=True)
    if p.returncode != 0:
        pytest.fail(f"pip install --target failed: {p.stderr[-2000:]}")
    code = ("import wmr_cosim.components.plant as m, wmr_cosim.components.paper as p, wmr_cosim.cli;"
            "print(m.__file__); print(p.table1()['gamma'])")
    env = {**os.environ, "PYTHONPATH": str(target)}
    q = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert q.returncode == 0, q.stderr
    lines = q.stdout.split("\n")
    assert Path(lines[0]).is_relative_to(target), lines[0]
    assert lines[1] == "11.0"
