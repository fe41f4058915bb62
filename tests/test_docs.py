"""The README fits on a few screens and starts with the two commands (the main job, then the tests, which
CI runs as written); every relative link of the README and of docs/ points at a file of the repository;
the documentation cites nothing outside the repository."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MAIN_JOB = "pip install -e . && wmr-cosim paper --out results/paper"
TESTS = 'pip install -e ".[test]" && pytest -q -n 2'


def test_readme_is_short_and_starts_with_the_main_job_then_the_tests():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text) < 15_000
    blocks = re.findall(r"^```[^\n]*\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    assert [b.strip() for b in blocks[:2]] == [MAIN_JOB, TESTS]
    ci = (ROOT / ".ci" / "run").read_text()
    assert TESTS in ci  # CI runs the README's test command exactly


def test_relative_links_point_at_files():
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = target.split("#")[0]
            assert (doc.parent / path).exists(), f"{doc.relative_to(ROOT)}: broken link {target}"


#: What a citation of something outside the repository looks like: a notes, paper or tools folder beside
#: the checkout, a numbered tracker
#: item or trap, an absolute path of the machine the code was written on (composed here, so that this file
#: does not match itself).
_OUTSIDE = [r"shared/" + "notes", r"shared/" + "paper", r"shared/" + "tools", r"\.\./" + "shared",
            r"\bno" + "tes/", r"\b" + "iss" + r"ue \d+", r"\b" + "tr" + r"ap \d+", "/" + "work/"]


def test_nothing_outside_the_repository_is_cited():
    files = DOCS + [p for d in ("wmr_cosim", "components", "fmus", "cosim", "tests", "benchmarks", "scenarios")
                    for p in (ROOT / d).rglob("*") if p.suffix in (".py", ".toml", ".md")]
    for f in files:
        text = f.read_text(encoding="utf-8")
        for pattern in _OUTSIDE:
            assert not re.search(pattern, text, flags=re.IGNORECASE), f"{f.relative_to(ROOT)}: {pattern}"
