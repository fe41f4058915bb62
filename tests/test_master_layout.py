"""The shape of the master (cosim/): its folders are its concepts, each with a face; no import cycle among
its modules (imports for type checking and inside functions included); no folder over 12 modules; the
algorithm names written in one module, the table of algorithms."""
from __future__ import annotations

import ast
import importlib
from pathlib import Path

import grimp

from test_layering_app import find_cycle

ROOT = Path(__file__).resolve().parent.parent
COSIM = ROOT / "cosim"
MAX_MODULES = 12
#: The one module that names the algorithms (``[experiment] algorithm``).
TABLE = COSIM / "stepping" / "table.py"


def folders() -> list[Path]:
    return sorted(p for p in COSIM.iterdir() if (p / "__init__.py").is_file())


def module_graph(exclude_type_checking: bool = False) -> dict[str, set[str]]:
    """{module of wmr_cosim.cosim: the modules of it that it imports}, as import-linter reads them."""
    g = grimp.build_graph("wmr_cosim", cache_dir=None, exclude_type_checking_imports=exclude_type_checking)
    mods = {m for m in g.modules if m.startswith("wmr_cosim.cosim.")}
    return {m: {d for d in g.find_modules_directly_imported_by(m) if d in mods} for m in mods}


def test_the_graph_is_read_with_the_imports_for_type_checking():
    """(so that the cycle test below sees them): the execution's views are imported only to type."""
    full, runtime_only = module_graph(), module_graph(exclude_type_checking=True)
    assert "wmr_cosim.cosim.runtime.execution" in full["wmr_cosim.cosim.runtime.protocol"]
    assert sum(map(len, full.values())) > sum(map(len, runtime_only.values())) > 100
    assert "wmr_cosim.cosim.instances.contract" in full["wmr_cosim.cosim.runtime.manipulators"]
    assert "wmr_cosim.cosim.instances.contract" not in runtime_only["wmr_cosim.cosim.runtime.manipulators"]


def test_no_import_cycle_among_the_modules_of_the_master():
    cycle = find_cycle(module_graph())
    assert cycle is None, f"an import cycle in cosim/: {' -> '.join(cycle)}"


def test_every_folder_has_a_face_and_at_most_twelve_modules():
    names = [p.name for p in folders()]
    assert names == sorted(["messages", "model", "instances", "stepping", "requirements", "scenario", "plan", "results",
                            "linearisation",
                            "runtime"])
    assert sorted(p.name for p in COSIM.glob("*.py")) == ["__init__.py"]   # no module outside the folders
    for folder in folders():
        modules = [p for p in folder.glob("*.py") if p.name != "__init__.py"]
        assert 1 <= len(modules) <= MAX_MODULES, (folder.name, len(modules))
        assert not [p for p in folder.iterdir() if p.is_dir() and p.name != "__pycache__"], folder
        face = importlib.import_module(f"wmr_cosim.cosim.{folder.name}")
        assert face.__doc__ and face.__all__, folder.name
        for name in face.__all__:
            assert getattr(face, name) is not None, (folder.name, name)


def test_every_folder_has_tests_named_after_it():
    """The tests of a concept are found from its folder's name: tests/test_<folder>_*.py."""
    tests = ROOT / "tests"
    for folder in folders():
        assert sorted(tests.glob(f"test_{folder.name}_*.py")), folder.name


def test_the_face_of_the_master_exports_what_it_names():
    from wmr_cosim import cosim

    assert len(set(cosim.__all__)) == len(cosim.__all__)
    for name in cosim.__all__:
        getattr(cosim, name)
    assert callable(cosim.run) and cosim.Execution.__module__ == "wmr_cosim.cosim.runtime.execution"


def _strings(path: Path) -> list[tuple[int, str]]:
    """(line, value) of every string constant of a module but its docstrings."""
    tree = ast.parse(path.read_text(), str(path))
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docs.add(id(first.value))
    return [(n.lineno, n.value) for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def _named(value: str, names: tuple[str, ...]) -> bool:
    """A string that is an algorithm's name, or quotes one as a scenario file writes it."""
    return value in names or any(f'"{n}"' in value for n in names)


def test_the_algorithm_names_are_written_in_the_table_alone():
    from wmr_cosim.cosim.stepping import table

    assert [n for _, n in _strings(TABLE) if n in table.NAMES] == list(table.NAMES)
    found = [f"{p.relative_to(ROOT)}:{line}: {value!r}" for p in sorted(COSIM.rglob("*.py")) if p != TABLE
             for line, value in _strings(p) if _named(value, table.NAMES)
             and not (p.name == "__init__.py" and (p.parent / f"{value}.py").is_file())]   # (a face names modules)
    assert not found, "algorithm names outside the table of algorithms: " + "; ".join(found)


def test_the_name_finder_sees_names_and_quoted_names(tmp_path):
    f = tmp_path / "m.py"
    f.write_text('"""Doc: "jacobi" is allowed here."""\nA = "jacobi"\nB = f"run under \\"iterated\\" {A}"\n'
                 'def g():\n    """"adaptive" in a docstring."""\n    return "iteration"\n')
    assert [v for _, v in _strings(f) if _named(v, ("jacobi", "iterated", "adaptive"))] == \
        ["jacobi", 'run under "iterated" ']


def test_every_algorithm_of_the_table_runs_as_its_row_says():
    """Each row's class is what ``make`` gives for its name, and the checks read the rows."""
    from wmr_cosim.cosim.stepping import table
    from wmr_cosim.cosim.stepping.multirate import MultiRate
    from wmr_cosim.cosim.stepping.parallel import ParallelJacobi

    for r in table.ROWS:
        alg = table.make(r.name)
        assert type(alg) is r.cls and table.name_of(alg) == r.name
        assert table.name_of(r.cls() if not r.varies_step else alg) == r.name
    assert table.adaptive_couplings() == [n for n in table.NAMES if not table.row(n).varies_step]
    rated = table.make(table.JACOBI, own_rates=True)
    assert isinstance(rated, MultiRate) and rated.jacobi and table.name_of(rated) == table.JACOBI
    parallel = table.make(table.JACOBI, workers=2)
    assert isinstance(parallel, ParallelJacobi) and table.name_of(parallel) == table.JACOBI
    assert table.iterates(table.ADAPTIVE, table.ITERATED) and not table.iterates(table.ADAPTIVE, None)
    assert table.readers(table.ITERATION_TABLE) == '"iterated", and by "adaptive" with coupling = "iterated"'


def test_the_master_draws_nothing():
    """Plots are the application's (a loop's: wmr_cosim/runs/loop_plot.py): no module of cosim/ imports
    matplotlib, so none chooses a backend for the process."""
    found = []
    for p in sorted(COSIM.rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text(), str(p))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            found += [f"{p.relative_to(ROOT)}:{node.lineno}" for n in names if n.split(".")[0] == "matplotlib"]
    assert not found, found
