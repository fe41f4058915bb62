"""One benchmark of this checkout against another commit's code, interleaved (``bench.py NAME --against
REV``): HEAD and the commit are checked out into temporary git worktrees (alike but for their code), and
``bench.py NAME --repeats R`` runs in a fresh process in each in turn, ``rounds`` times, each first in every
other round, so that the machine's drifting load falls on both alike.  Each numeric figure's median over
the rounds is given for both trees with their ratio (this / that); a ratio above 1 for a time is this
checkout slower.  ``--against HEAD`` measures the method's own noise (the same code on both sides)."""
from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: The import names that older checkouts map onto the top-level folders through setuptools' package-dir
#: (newer ones hold relative links in wmr_cosim/): made as links in the worktree so PYTHONPATH finds them.
LINKED = ("cosim", "components", "fmus", "scenarios")


def _worktree(rev: str, where: Path, name: str) -> Path:
    tree = where / name
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(tree), rev], check=True)
    for name in LINKED:
        link = tree / "wmr_cosim" / name
        if not link.exists():
            link.symlink_to(Path("..") / name)
    return tree


def _one(tree: Path, name: str, repeats: int) -> dict[str, Any]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, str(tree / "benchmarks" / "bench.py"), name, "--repeats", str(repeats)],
                         cwd=tree,
                         env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"bench.py {name} in {tree} failed (exit {out.returncode}): {out.stderr.strip()[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def against(name: str, rev: str, rounds: int, repeats: int = 1) -> dict[str, Any]:
    """``this`` is a worktree of the checkout's HEAD (so that both trees are alike but for their code: same
    kind of folder, FMUs built the same way; commit what is to be measured), ``that`` one of ``rev``."""
    where = Path(tempfile.mkdtemp(prefix="wmr-cosim-against-"))
    try:
        this, that = _worktree("HEAD", where, "this"), _worktree(rev, where, "that")
        runs: dict[str, list[dict[str, Any]]] = {"this": [], "that": []}
        for tree in (this, that):   # each tree's FMUs built, and the caches warm, before the rounds
            _one(tree, name, 1)
        for r in range(max(1, rounds)):   # each tree first in every other round
            for side, tree in (("this", this), ("that", that))[::1 if r % 2 == 0 else -1]:
                runs[side].append(_one(tree, name, repeats))
    finally:
        for tree in ("this", "that"):
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(where / tree)],
                           capture_output=True)
        shutil.rmtree(where, ignore_errors=True)
    this, that = [_flat(r) for r in runs["this"]], [_flat(r) for r in runs["that"]]
    figures: dict[str, Any] = {}
    for key in this[0]:
        if key not in that[0]:
            continue
        a = statistics.median(r[key] for r in this)
        b = statistics.median(r[key] for r in that)
        figures[key] = {"this": a, "that": b, "ratio": round(a / b, 4) if b else None}
    return {"against": rev, "rounds": rounds, "repeats": repeats, "figures": figures}


def _flat(figures: dict[str, Any], prefix: str = "") -> dict[str, float]:
    """The numeric figures, nested ones named ``outer.inner`` (booleans and text left out)."""
    out: dict[str, float] = {}
    for key, value in figures.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}."))
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            out[prefix + key] = value
    return out
