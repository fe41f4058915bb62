"""What the benchmarks import is declared: every third-party module that ``benchmarks/*.py`` imports (at
module level or inside a function), or that a test helper or a module of the package they import does in
turn, is a run-time dependency or in the ``bench`` extra (the mutation harness's mutmut: in the mutation
extra), and the test extra includes the bench extra; a benchmark started without its extra says so in
one line."""
from __future__ import annotations

import ast
import importlib.metadata
import importlib.util
import re
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Folders whose modules the benchmarks import by their bare names (bench.py puts tests/ on sys.path).
LOCAL = (ROOT / "benchmarks", ROOT / "tests")
#: The files of the mutation harness, which may import what the mutation extra declares.
MUTATION_HARNESS = {"benchmarks/mutation.py"}


def _module_file(name: str) -> Path | None:
    """The file of a module of the checkout (the package by its import name, a benchmark or test helper
    by its bare name), or None for any other module."""
    parts = name.split(".")
    if parts[0] == "wmr_cosim":
        base = ROOT.joinpath("wmr_cosim", *parts[1:])
        return next((f for f in (base.with_suffix(".py"), base / "__init__.py") if f.is_file()), None)
    if len(parts) == 1:
        return next((d / f"{name}.py" for d in LOCAL if (d / f"{name}.py").is_file()), None)
    return None


def _imports(path: Path, module: str) -> set[str]:
    """Every module name ``path`` (the module ``module``) imports, anywhere in it, relative ones made
    absolute; a name imported from a module counts as its possible submodule too."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package.split(".")[:len(package.split(".")) - node.level + 1])
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
    return out


def third_party_imports() -> dict[str, set[str]]:
    """{top-level third-party module: the files (relative to the checkout) that import it}, over the
    benchmarks and everything of the checkout they import, transitively."""
    todo = [(p, p.stem) for p in sorted((ROOT / "benchmarks").glob("*.py"))]
    seen: set[Path] = set()
    found: dict[str, set[str]] = {}
    while todo:
        path, module = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        for name in _imports(path, module):
            parts = name.split(".")
            local = [(f, ".".join(parts[:i])) for i in range(1, len(parts) + 1)
                     if (f := _module_file(".".join(parts[:i]))) is not None]
            todo += local
            top = parts[0]
            if not local and top not in sys.stdlib_module_names and top not in ("__future__", "wmr_cosim"):
                found.setdefault(top, set()).add(path.resolve().relative_to(ROOT.resolve()).as_posix())
    return found


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _provided(reqs: list[str]) -> set[str]:
    """The distributions a list of requirements installs by name, an extra's name included
    ("dask[distributed]" provides dask and distributed)."""
    out: set[str] = set()
    for r in reqs:
        m = re.match(r"\s*([A-Za-z0-9._-]+)\s*(?:\[([^\]]*)\])?", r)
        assert m, r
        out.add(_norm(m.group(1)))
        out.update(_norm(e) for e in (m.group(2) or "").split(",") if e.strip())
    return out


def test_every_import_of_the_benchmarks_is_declared_in_the_bench_extra():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras = meta["optional-dependencies"]
    allowed = _provided(meta["dependencies"]) | _provided(extras.get("bench", []))
    dists = importlib.metadata.packages_distributions()
    found = third_party_imports()
    assert {"scipy", "pytest", "numpy", "fmpy"} <= set(found), found   # (the walk reaches the helpers)
    missing = {}
    for top, files in found.items():
        names = {_norm(d) for d in dists.get(top, [])} | {_norm(top)}
        ok = allowed | (_provided(extras["mutation"]) if files <= MUTATION_HARNESS else set())
        if not names & ok:
            missing[top] = sorted(files)
    assert missing == {}, f"declare these in pyproject.toml's bench extra: {missing}"


def test_the_test_extra_includes_the_bench_extra():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["optional-dependencies"]
    assert "bench" in extras
    assert _provided(extras["bench"]) <= _provided(extras["test"])


def test_a_benchmark_without_its_extra_says_which_in_one_line(monkeypatch, capsys):
    spec = importlib.util.spec_from_file_location("bench_under_test", ROOT / "benchmarks" / "bench.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)

    def needs_scipy(repeats: int) -> dict:
        raise ModuleNotFoundError("No module named 'scipy'", name="scipy")

    monkeypatch.setitem(bench.BENCHES, "adaptive", needs_scipy)
    assert bench.main(["adaptive"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == 'bench.py adaptive: needs scipy: pip install -e ".[bench]" (docs/benchmarks.md)'

    def needs_a_helper(repeats: int) -> dict:    # a module of the checkout that is missing: a real error
        raise ModuleNotFoundError("No module named 'coupling_fmus'", name="coupling_fmus")

    monkeypatch.setitem(bench.BENCHES, "adaptive", needs_a_helper)
    with pytest.raises(ModuleNotFoundError):
        bench.main(["adaptive"])
