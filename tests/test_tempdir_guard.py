"""The session's temporary-folder check (tempdir_guard.py): a test session that leaves a folder in the
temporary folder fails and names it; one that cleans up passes; tmp_path is unaffected."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent

LEAKY = '''
import tempfile
from pathlib import Path

def test_leaks():
    Path(tempfile.mkdtemp(prefix="left_behind_"))

def test_child_process_leaks():
    import subprocess, sys
    subprocess.run([sys.executable, "-c", "import tempfile; tempfile.mkdtemp(prefix='child_left_')"], check=True)
'''

CLEAN = '''
import tempfile

def test_cleans_up(tmp_path):
    (tmp_path / "kept by pytest").write_text("x")
    with tempfile.TemporaryDirectory() as d:
        pass
'''


def _session(tmp_path: Path, body: str, *extra: str) -> subprocess.CompletedProcess:
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "test_it.py").write_text(body)
    env = {**os.environ, "PYTHONPATH": str(TESTS)}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "tempdir_guard", "-p", "no:cacheprovider",
                           "-c", str(tmp_path / "pytest.ini"), "--basetemp", str(tmp_path / "base"), *extra,
                           str(tmp_path / "test_it.py")], capture_output=True, text=True, cwd=tmp_path, env=env,
                          timeout=120)


def test_a_parallel_session_that_leaves_a_folder_fails_and_names_it(tmp_path):
    """With pytest-xdist (-n 2) the workers share the session's temporary folder and the session checks it
    once every worker is done: what a worker's test leaves fails the session as in a serial one."""
    import pytest
    pytest.importorskip("xdist")
    p = _session(tmp_path, LEAKY, "-n", "2")
    assert p.returncode == 1, p.stdout + p.stderr
    assert "2 passed" in p.stdout
    assert "left 2 entries in the temporary folder" in p.stdout
    assert "left_behind_" in p.stdout and "child_left_" in p.stdout


def test_a_session_that_leaves_a_folder_fails_and_names_it(tmp_path):
    p = _session(tmp_path, LEAKY)
    assert p.returncode == 1, p.stdout + p.stderr
    assert "2 passed" in p.stdout
    assert "left 2 entries in the temporary folder" in p.stdout
    assert "left_behind_" in p.stdout and "child_left_" in p.stdout


def test_a_session_that_cleans_up_passes(tmp_path):
    p = _session(tmp_path, CLEAN)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "temporary folder" not in p.stdout
    assert (tmp_path / "base").is_dir()  # pytest's tmp_path folders are where pytest keeps them
