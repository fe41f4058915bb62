"""The shape of the application layer (wmr_cosim/): its modules import each other along a DAG (no
cycle, imports inside functions included), none imports another's private name, and no function of
wmr_cosim/ or cosim/ is longer than 60 lines (a short, shrinking list of exceptions)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
APP = ROOT / "wmr_cosim"
MAX_LINES = 60

#: Functions still over MAX_LINES, being split, as "folder/file.py:qualified name".  The list may only
#: shrink: any other function over MAX_LINES fails, and an entry goes once its function is split
#: (cosim/isolation.py:_serve, cosim/system.py:resolve and wmr_cosim/cli.py:build_parser have been).
LONG_FUNCTIONS: set[str] = set()


def _app_modules() -> dict[str, Path]:
    """{module name within wmr_cosim: file} of the application folder (``__init__`` for the package)."""
    return {p.stem: p for p in sorted(APP.glob("*.py"))}


def _imports(path: Path, modules: set[str]) -> list[tuple[str, str, int]]:
    """(module of wmr_cosim/ imported, name imported from it or '', line) of every import in ``path``,
    at module level and inside functions alike.  ``from . import x`` is module x when x is one, else a
    name of the package (``__init__``); imports of the sub-packages (cosim, components, fmus) are left out."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level == 1:
                parts = node.module.split(".") if node.module else []
            elif node.level == 0 and node.module and node.module.split(".")[0] == "wmr_cosim":
                parts = node.module.split(".")[1:]
            else:
                continue
            if parts:
                if parts[0] in modules:
                    out += [(parts[0], a.name, node.lineno) for a in node.names]
            else:
                out += [(a.name, "", node.lineno) if a.name in modules else ("__init__", a.name, node.lineno)
                        for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] == "wmr_cosim":
                    out.append((parts[1] if len(parts) > 1 and parts[1] in modules else "__init__", "", node.lineno))
    return out


def import_graph() -> dict[str, set[str]]:
    """{module: the modules of wmr_cosim/ it imports}."""
    mods = _app_modules()
    return {m: {dep for dep, _, _ in _imports(p, set(mods)) if dep != m} for m, p in mods.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as [a, b, ..., a], or None when it is a DAG."""
    state: dict[str, int] = {}    # 1: on the current path, 2: done

    def visit(node: str, path: list[str]) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt, path)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node, [])
            if found:
                return found
    return None


def test_the_cycle_finder_finds_a_cycle_and_passes_a_dag():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_importer_sees_imports_inside_functions(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("from .x import a\n\ndef f():\n    from .y import b\n    from . import z, version\n"
                 "    import wmr_cosim.x\n    from .cosim.errors import CosimError\n")
    assert sorted(_imports(f, {"x", "y", "z"})) == [("__init__", "version", 5), ("x", "", 6), ("x", "a", 1),
                                                    ("y", "b", 4), ("z", "", 5)]


def test_the_modules_of_wmr_cosim_import_each_other_without_a_cycle():
    graph = import_graph()
    assert {"paper_job", "paper_report", "robustness", "sweep"} <= set(graph)   # the folder was read
    cycle = find_cycle(graph)
    assert cycle is None, f"an import cycle among the modules of wmr_cosim/: {' -> '.join(cycle)}"


def test_no_module_of_wmr_cosim_imports_a_private_name_of_another():
    mods = _app_modules()
    bad = [f"{p.relative_to(ROOT)}:{line}: {name} of {dep}" for m, p in mods.items()
           for dep, name, line in _imports(p, set(mods)) if dep != m and name.startswith("_")]
    assert not bad, "private names imported from another module: " + "; ".join(bad)


def _functions(path: Path) -> dict[str, int]:
    """{qualified name: lines (end_lineno - lineno + 1)} of every function of ``path``, methods and
    nested functions included."""
    out: dict[str, int] = {}

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out[prefix + child.name] = child.end_lineno - child.lineno + 1
                walk(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                walk(child, prefix + child.name + ".")
            else:
                walk(child, prefix)

    walk(ast.parse(path.read_text(), str(path)), "")
    return out


def _long_functions() -> dict[str, int]:
    """{"folder/file.py:function": lines} of the functions over MAX_LINES in the application folder (its
    own modules: the subpackages it links to are read as cosim/ or not at all) and in cosim/."""
    files = sorted(APP.glob("*.py")) + sorted((ROOT / "cosim").rglob("*.py"))
    return {f"{p.relative_to(ROOT).as_posix()}:{name}": n
            for p in files for name, n in _functions(p).items() if n > MAX_LINES}


def test_no_function_of_wmr_cosim_or_cosim_is_over_60_lines():
    new = {k: n for k, n in _long_functions().items() if k not in LONG_FUNCTIONS}
    assert not new, (f"functions over {MAX_LINES} lines (split them into named helpers): "
                     + ", ".join(f"{k} ({n})" for k, n in sorted(new.items())))

