"""The bug-kinds harness (benchmarks/bug_kinds.py) makes the bugs it says it makes, and only those."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import bug_kinds  # noqa: E402

SOURCE_VAR = '''\
def g(status: list[int], names: dict[str, int], i: int, key: str) -> int:
    return status[i] + names[key] + status[self.pos]
'''


def test_a_variable_index_of_a_position_is_off_by_one_and_a_key_is_left_alone(tmp_path):
    path = tmp_path / "v.py"
    path.write_text(SOURCE_VAR)
    bugs = {(b.kind, b.old, b.new) for b in bug_kinds.bugs_of(path, "cosim/v.py") if b.kind == "index"}
    assert bugs == {("index", "i", "i + 1"), ("index", "i", "i - 1"), ("index", "self.pos", "self.pos + 1"),
                    ("index", "self.pos", "self.pos - 1")}


SOURCE = '''\
def f(flags: dict[str, int], k: int, h: float, x: float, a: float, b: float) -> float:
    t = t0 + k * h
    y = a * b * x + 2.0 * x
    if x in (1, 2, 3) and k not in [4, 5]:
        return flags[1] + self.h * k
    return flags[-1]
'''


def _bugs(tmp_path):
    path = tmp_path / "m.py"
    path.write_text(SOURCE)
    return {(b.kind, b.old, b.new) for b in bug_kinds.bugs_of(path, "cosim/m.py")}, path


def test_each_kind_is_made(tmp_path):
    bugs, _ = _bugs(tmp_path)
    assert {("time", "k * h", "(k + 1) * h"), ("time", "k * h", "(k - 1) * h"),
            ("time", "self.h * k", "(k + 1) * self.h"),
            ("index", "1", "0"), ("index", "1", "2"), ("index", "-1", "-2"), ("index", "-1", "0"),
            ("factor", "a * b * x", "b * x"), ("factor", "a * b * x", "a * x"), ("factor", "a * b * x", "a * b"),
            ("factor", "2.0 * x", "x"), ("factor", "2.0 * x", "2.0"),
            ("contains", "x in (1, 2, 3)", "x == 1"), ("contains", "k not in [4, 5]", "k != 4")} <= bugs


def test_annotations_and_inner_products_make_no_bugs(tmp_path):
    bugs, _ = _bugs(tmp_path)
    assert not any(old in ("str, int", "str") for _, old, _ in bugs)        # dict[str, int] is no index
    assert not any(old == "a * b" for _, old, _ in bugs)                     # only the whole chain a * b * x
    assert {b for b in bugs if b[0] == "index"} == {("index", "1", "0"), ("index", "1", "2"), ("index", "-1", "-2"),
                                                 ("index", "-1", "0")}    # no variable index in SOURCE


def test_a_bug_applies_to_its_place_only(tmp_path):
    _, path = _bugs(tmp_path)
    bug = next(b for b in bug_kinds.bugs_of(path, "cosim/m.py") if b.kind == "contains" and b.new == "x == 1")
    mutated = bug.apply(SOURCE)
    assert mutated == SOURCE.replace("x in (1, 2, 3)", "x == 1")
    compile(mutated, "m.py", "exec")


@pytest.mark.filterwarnings("ignore::SyntaxWarning")
def test_every_bug_of_the_core_compiles():
    """Every planted bug of cosim/ and components/ is valid Python (a bug that does not compile would be
    'killed' for nothing)."""
    for bug in bug_kinds.all_bugs():
        text = (ROOT / bug.file).read_text(encoding="utf-8")
        compile(bug.apply(text), bug.file, "exec")


def test_the_tests_of_a_module_are_found_by_its_imports():
    tests = bug_kinds.tests_of("cosim/model/units.py")
    assert "tests/test_model_units.py" in tests and "tests/test_docs.py" not in tests


def test_every_bug_has_a_name_of_its_own():
    """Two bugs on one line (the same expression twice) are told apart by their column: the verdicts are
    kept by name."""
    names = [b.name for b in bug_kinds.all_bugs()]
    assert len(names) == len(set(names))
