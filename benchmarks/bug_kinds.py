"""Bugs of the kinds developers make and mutmut does not: are there any the tests let through?

mutmut's operators swap one token (an operator, a number, a string, a keyword).  The bugs that slip past
a suite that kills every mutmut mutant are of other kinds, and this harness makes them, with Python's
``ast``, in ``cosim/`` and ``components/``:

* ``index``: an index into a sequence off by one, a constant one (``flags[1]`` -> ``flags[0]`` /
  ``flags[2]``) or a variable one (``status[i]`` -> ``status[i + 1]`` / ``status[i - 1]``): a wrong entry of
  an array of FMI flags or statuses (a variable index into a mapping is a wrong key, which fails at once);
* ``time``: an off-by-one inside a time expression, a step count times a step (``k * h`` -> ``(k + 1) * h``
  / ``(k - 1) * h``, with ``h``, ``step``, ``dt`` or ``self.h`` as the step);
* ``factor``: one factor dropped from one term of a product (``a * b * c`` -> ``a * c``);
* ``contains``: a containment check weakened to its first element (``x in (a, b, c)`` -> ``x == a``, and
  ``not in`` -> ``!=``).

Each bug is planted, one at a time, in a copy of the project laid out as the installed package
(``build/bug_kinds/``, git-ignored; the same staging as benchmarks/mutation.py), and the fast tests that
import the module it sits in are run against it; a bug those let through is run against the whole fast
suite before it is called a survivor.  ``--sample N --seed S`` draws N bugs (default: all).  Bugs no test
can tell from the original are listed with a reason in ``benchmarks/bug-kinds-equivalents.toml``.

``python benchmarks/bench.py bugs`` (or this script) prints as its last line one JSON object:
``{"bugs", "killed", "kill_rate", "by_kind", "survivors", "equivalent", "minutes"}``.
"""
from __future__ import annotations

import argparse
import ast
import json
import os
import random
import re
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STAGE = ROOT / "build" / "bug_kinds"
EQUIVALENTS = ROOT / "benchmarks" / "bug-kinds-equivalents.toml"
#: The source files bugs are planted in (repository paths) and their import names.
SOURCES = {"cosim": "wmr_cosim.cosim", "components": "wmr_cosim.components"}
#: Names that stand for a communication or integration step in a time expression.
STEP_NAMES = {"h", "step", "dt", "step_size"}
#: Names of integer positions (an index named so is off by one in an ``index`` bug; other names are keys).
INDEX_NAME = re.compile(r"(i|j|k|n|m|ii|idx|index|pos|elem|offset|row|col|slot|first|last|start|end)"
                        r"|\w*_(i|j|k|idx|index|pos|elem|offset)")
#: The fast suite, as the mutation harness runs it (tests that read the repository itself left out).
FAST = ["-m", "not slow", "-p", "no:cacheprovider", "-q", "-x",
        "--ignore=tests/test_docs.py", "--ignore=tests/test_packaging.py", "--ignore=tests/test_mutation_harness.py",
        "--ignore=tests/test_bug_kinds.py"]


@dataclass(frozen=True)
class Bug:
    """One planted bug: the file (repository path), the kind, the line, the source text replaced (from
    ``start`` to ``end``, character offsets) and what replaces it."""

    file: str
    kind: str
    line: int
    col: int
    start: int
    end: int
    old: str
    new: str

    @property
    def name(self) -> str:
        return f"{self.file}:{self.line}:{self.col}:{self.kind}:{self.old} -> {self.new}"

    def apply(self, text: str) -> str:
        if text[self.start:self.end] != self.old:
            raise ValueError(f"{self.name}: the source has changed")
        return text[:self.start] + self.new + text[self.end:]


def _offsets(text: str) -> list[int]:
    """The character offset of the start of each line (1-based line numbers index it from 1)."""
    out = [0, 0]
    for line in text.splitlines(keepends=True):
        out.append(out[-1] + len(line))
    return out


def _is_step(node: ast.AST) -> bool:
    return (isinstance(node, ast.Name) and node.id in STEP_NAMES) or \
        (isinstance(node, ast.Attribute) and node.attr in STEP_NAMES)


def _factors(node: ast.AST) -> list[ast.AST]:
    """The factors of a chain of multiplications (``a * b * c`` -> [a, b, c])."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        return _factors(node.left) + _factors(node.right)
    return [node]


def _annotations(tree: ast.AST) -> set[int]:
    """The ids of the nodes inside annotations (``dict[str, int]`` is no index)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        anns = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            anns = [a.annotation for a in node.args.args + node.args.kwonlyargs + node.args.posonlyargs] + \
                [node.returns, node.args.vararg and node.args.vararg.annotation,
                 node.args.kwarg and node.args.kwarg.annotation]
        elif isinstance(node, ast.AnnAssign):
            anns = [node.annotation]
        for a in anns:
            if a is not None:
                out.update(id(n) for n in ast.walk(a))
    return out


def bugs_of(path: Path, rel: str) -> list[Bug]:
    """Every bug of the four kinds that can be planted in one source file."""
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    lines = _offsets(text)
    skip = _annotations(tree)
    inner = {id(n) for p in ast.walk(tree) if isinstance(p, ast.BinOp) and isinstance(p.op, ast.Mult)
             for n in (p.left, p.right) if isinstance(n, ast.BinOp) and isinstance(n.op, ast.Mult)}
    out: list[Bug] = []

    def span(node: ast.AST) -> tuple[int, int, str]:
        a = lines[node.lineno] + node.col_offset
        b = lines[node.end_lineno] + node.end_col_offset
        return a, b, text[a:b]

    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Load):
            sl = node.slice
            value = None
            if isinstance(sl, ast.Constant) and type(sl.value) is int:
                value = sl.value
            elif isinstance(sl, ast.UnaryOp) and isinstance(sl.op, ast.USub) and isinstance(sl.operand, ast.Constant) \
                    and type(sl.operand.value) is int:
                value = -sl.operand.value
            if value is not None:
                a, b, old = span(sl)
                for new in (value - 1, value + 1):
                    if (new >= 0) == (value >= 0) or new == 0:     # an index stays from its end or its start
                        out.append(Bug(rel, "index", node.lineno, a - lines[node.lineno], a, b, old, str(new)))
            elif isinstance(sl, (ast.Name, ast.Attribute)) and INDEX_NAME.fullmatch(
                    sl.id if isinstance(sl, ast.Name) else sl.attr):
                a, b, old = span(sl)          # a variable index, off by one (names of positions, not of keys)
                for sign in ("+", "-"):
                    out.append(Bug(rel, "index", node.lineno, a - lines[node.lineno], a, b, old, f"{old} {sign} 1"))
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult) and id(node) not in inner:
            fs = _factors(node)          # (the outermost product of a chain makes the bugs of the whole chain)
            a, b, old = span(node)
            src = [ast.get_source_segment(text, f) for f in fs]
            if any(t is None for t in src):
                continue
            if len(fs) == 2 and sum(map(_is_step, fs)) == 1:
                i = 0 if _is_step(fs[1]) else 1
                if not isinstance(fs[i], ast.Constant):
                    for sign in ("+", "-"):
                        out.append(Bug(rel, "time", node.lineno, a - lines[node.lineno], a, b, old,
                                       f"({src[i]} {sign} 1) * {src[1 - i]}"))
            for i, f in enumerate(fs):
                if isinstance(f, ast.Constant) and f.value in (1, -1):
                    continue             # dropping a factor of one changes nothing (or only the sign: mutmut's)
                rest = [t if " " not in t or t.startswith("(") else f"({t})" for j, t in enumerate(src) if j != i]
                out.append(Bug(rel, "factor", node.lineno, a - lines[node.lineno], a, b, old, " * ".join(rest)))  # type: ignore[arg-type]
        elif isinstance(node, ast.Compare) and len(node.ops) == 1 and isinstance(node.ops[0], (ast.In, ast.NotIn)):
            seq = node.comparators[0]
            if isinstance(seq, (ast.Tuple, ast.List, ast.Set)) and len(seq.elts) >= 2:
                a, b, old = span(node)
                left = ast.get_source_segment(text, node.left)
                first = ast.get_source_segment(text, seq.elts[0])
                if left is not None and first is not None:
                    op = "==" if isinstance(node.ops[0], ast.In) else "!="
                    out.append(Bug(rel, "contains", node.lineno, a - lines[node.lineno], a, b, old,
                                       f"{left} {op} {first}"))
    return sorted(set(out), key=lambda bug: (bug.file, bug.start, bug.kind, bug.new))


def all_bugs() -> list[Bug]:
    out: list[Bug] = []
    for folder in SOURCES:
        for path in sorted((ROOT / folder).glob("*.py")):
            out += bugs_of(path, f"{folder}/{path.name}")
    return out


def load_equivalents() -> dict[str, str]:
    """{bug name: why no test can tell it from the original}."""
    if not EQUIVALENTS.is_file():
        return {}
    doc = tomllib.loads(EQUIVALENTS.read_text(encoding="utf-8"))
    return {e["bug"]: e["reason"] for e in doc.get("equivalent", [])}


def stage() -> None:
    """The project in STAGE, laid out as the installed package (benchmarks/mutation.py's staging)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import mutation

    inner = frozenset(place.split("/", 1)[1] for place in mutation.PACKAGE_DIRS.values() if "/" in place)
    for folder, place in mutation.PACKAGE_DIRS.items():
        mutation._sync(ROOT / folder, STAGE / place, keep=inner if place == "wmr_cosim" else frozenset())
    for name in mutation.ALSO:
        mutation._sync(ROOT / name, STAGE / name)
    (STAGE / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text(encoding="utf-8"), encoding="utf-8")


def staged(rel: str) -> Path:
    folder, name = rel.split("/", 1)
    return STAGE / SOURCES[folder].replace(".", "/") / name


def tests_of(rel: str) -> list[str]:
    """The test files that import the module ``rel`` sits in (by its name), fastest files are not known: all."""
    folder, name = rel.split("/", 1)
    parts = name[:-3].split("/")        # (a module in a folder of the package: cosim/model/units.py)
    dotted, package = re.escape(".".join(parts)), "".join(rf"\.{p}" for p in parts[:-1])
    pat = re.compile(rf"\b{folder}\b[\w.]*(\.{dotted}\b|{package} import [^\n]*\b{parts[-1]}\b)")
    return sorted(f"tests/{p.name}" for p in (ROOT / "tests").glob("test_*.py")
                  if pat.search(p.read_text(encoding="utf-8")) and f"--ignore=tests/{p.name}" not in FAST)


def _pytest(args: list[str], limit_s: float) -> str:
    env = {**os.environ, "PYTHONPATH": str(STAGE), "PYTHONDONTWRITEBYTECODE": "1",
           "WMR_TEST_FMU_CACHE": str(STAGE.parent / "bug_kinds-fmu-cache")}
    try:
        p = subprocess.run([sys.executable, "-m", "pytest", *FAST, *args], cwd=STAGE, env=env,
                           capture_output=True, text=True, timeout=limit_s)
    except subprocess.TimeoutExpired:
        return "timeout"
    if p.returncode == 5:
        return "no tests"
    return "survived" if p.returncode == 0 else "killed"


def judge(bug: Bug, limit_s: float) -> str:
    """Plant the bug in the staged copy, run the tests of its module, then (if it survived) the whole fast
    suite; restore the file.  "killed", "timeout" (counts as killed) or "survived"."""
    path = staged(bug.file)
    original = path.read_text(encoding="utf-8")
    try:
        path.write_text(bug.apply(original), encoding="utf-8")
        verdict = _pytest(tests_of(bug.file), limit_s) if tests_of(bug.file) else "no tests"
        if verdict in ("survived", "no tests"):
            verdict = _pytest(["tests"], limit_s * 4)
    finally:
        path.write_text(original, encoding="utf-8")
    return verdict


def select(only: str | None = None, kinds: list[str] | None = None, match: str | None = None) -> list[Bug]:
    """The bugs in files matching the regular expression ``only``, of the ``kinds`` (default: all), whose
    names match ``match``."""
    return [b for b in all_bugs() if (only is None or re.search(only, b.file)) and (not kinds or b.kind in kinds)
            and (match is None or re.search(match, b.name))]


def run(sample: int | None = None, seed: int = 1, only: str | None = None, limit_s: float = 600.0,
        out: Path | None = None, kinds: list[str] | None = None, match: str | None = None) -> dict:
    t0 = time.time()
    bugs = select(only, kinds, match)
    equivalents = load_equivalents()
    stale = sorted(set(equivalents) - {b.name for b in bugs})
    candidates = [b for b in bugs if b.name not in equivalents]
    drawn = sorted(random.Random(seed).sample(candidates, sample), key=lambda b: (b.file, b.start)) \
        if sample is not None and sample < len(candidates) else candidates
    stage()
    verdicts: dict[str, str] = {}
    for i, bug in enumerate(drawn, 1):
        verdicts[bug.name] = judge(bug, limit_s)
        print(f"[{i}/{len(drawn)}] {verdicts[bug.name]}: {bug.name}", file=sys.stderr, flush=True)
    killed = sum(v in ("killed", "timeout") for v in verdicts.values())
    by_kind: dict[str, dict[str, int]] = {}
    for bug in drawn:
        k = by_kind.setdefault(bug.kind, {"bugs": 0, "killed": 0})
        k["bugs"] += 1
        k["killed"] += verdicts[bug.name] in ("killed", "timeout")
    result = {"population": len(bugs), "kinds": kinds or "all", "only": only, "match": match, "bugs": len(drawn), "killed": killed,
              "kill_rate": round(killed / len(drawn), 4) if drawn else None, "by_kind": by_kind,
              "seed": seed, "equivalent": len(equivalents), "stale_equivalents": stale,
              "minutes": round((time.time() - t0) / 60, 1),
              "survivors": [n for n, v in verdicts.items() if v not in ("killed", "timeout")]}
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"result": result, "verdicts": verdicts}, indent=1), encoding="utf-8")
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sample", type=int, default=None, metavar="N", help="plant only N bugs drawn at random")
    ap.add_argument("--seed", type=int, default=1, help="the seed of the draw")
    ap.add_argument("--only", default=None, metavar="REGEX", help="only bugs in files matching REGEX")
    ap.add_argument("--kind", action="append", choices=("index", "time", "factor", "contains"),
                    help="only bugs of this kind (repeatable)")
    ap.add_argument("--match", default=None, metavar="REGEX", help="only bugs whose names match REGEX")
    ap.add_argument("--out", type=Path, default=STAGE.parent / "bug_kinds.json", help="where the verdicts go")
    ap.add_argument("--list", action="store_true", help="list the bugs that would be planted, run nothing")
    ap.add_argument("--limit", type=float, default=600.0, help="seconds a test session may take (default 600)")
    args = ap.parse_args(argv)
    if args.list:
        bugs = select(args.only, args.kind, args.match)
        for b in bugs:
            print(b.name)
        print(json.dumps({"population": len(bugs)}))
        return 0
    print(json.dumps(run(args.sample, args.seed, args.only, args.limit, args.out, args.kind, args.match)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
