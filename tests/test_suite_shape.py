"""The quick loop (pytest -m "not slow") leaves out every test that runs the whole paper job or starts a
pool of worker processes."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_no_test_of_the_paper_job_is_in_the_quick_loop():
    p = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", "not slow", "-p",
                        "no:cacheprovider", "tests/test_paper.py"], cwd=ROOT, capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr
    collected = [line.split("::")[1] for line in p.stdout.splitlines() if "::" in line]
    tree = ast.parse((ROOT / "tests" / "test_paper.py").read_text(encoding="utf-8"))
    using_the_job = [f.name for f in tree.body if isinstance(f, ast.FunctionDef) and f.name.startswith("test_")
                     and "job" in [a.arg for a in f.args.args]]
    assert "test_every_statement_of_the_report_agrees_with_its_number" in using_the_job
    assert collected and not set(collected) & set(using_the_job)


def test_no_test_that_starts_worker_processes_is_in_the_quick_loop():
    from conftest import STARTS_WORKER_PROCESSES

    p = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", "not slow", "-p",
                        "no:cacheprovider", "tests/test_sweep.py", "tests/test_security.py", "tests/test_robustness.py"],
                       cwd=ROOT, capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr
    collected = [line for line in p.stdout.splitlines() if "::" in line]
    assert collected and not [c for c in collected if c.startswith(STARTS_WORKER_PROCESSES)]
