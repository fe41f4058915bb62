"""The shape of the application layer (wmr_cosim/): its modules import each other along a DAG (no
cycle, imports inside functions included); no module of the package (wmr_cosim/, cosim/, components/,
fmus/) imports another's private name or reads one from an imported module; and no function of
wmr_cosim/ or cosim/ is longer than 60 lines (a short, shrinking list of exceptions)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
APP = ROOT / "wmr_cosim"
MAX_LINES = 60

#: Functions still over MAX_LINES, being split, as "folder/file.py:qualified name".  The list may only
#: shrink: any other function over MAX_LINES fails, and an entry goes once its function is split
#: (cosim/instances/isolation.py:_serve, cosim/plan/resolution.py:resolve and the command line's build_parser have
#: been).
LONG_FUNCTIONS: set[str] = set()


def _app_modules() -> dict[str, Path]:
    """{module name within wmr_cosim: file} of the application folder (``__init__`` for the package)."""
    return {p.stem: p for p in sorted(APP.glob("*.py"))}


def _app_packages() -> dict[str, list[Path]]:
    """{package of the application folder's own (cli/; not a linked subpackage): its modules' files}."""
    return {p.name: sorted(p.rglob("*.py")) for p in sorted(APP.iterdir())
            if not p.is_symlink() and (p / "__init__.py").is_file()}


def _app_files() -> list[Path]:
    """Every module file of the application: the folder's own modules and those of its own packages."""
    return sorted(APP.glob("*.py")) + [f for files in _app_packages().values() for f in files]


def _imports(path: Path, modules: set[str], package: tuple[str, ...] = ()) -> list[tuple[str, str, int]]:
    """(module of wmr_cosim/ imported, name imported from it or '', line) of every import in ``path``,
    at module level and inside functions alike.  ``from . import x`` is module x when x is one, else a
    name of the package (``__init__``); imports of the sub-packages (cosim, components, fmus) are left out.
    ``package``: the folders below wmr_cosim/ that hold ``path`` (("cli",) for cli/run.py), against which its
    relative imports are read (``from ..runner import x`` there is module runner, ``from . import options``
    module cli)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if 1 <= node.level <= len(package) + 1:
                parts = [*package[:len(package) - node.level + 1], *(node.module.split(".") if node.module else [])]
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
    """{module: the modules of wmr_cosim/ it imports}; a package of its own (cli/) is one module, whose
    imports are those of all its files."""
    mods, packages = _app_modules(), _app_packages()
    names = set(mods) | set(packages)
    graph = {m: {dep for dep, _, _ in _imports(p, names) if dep != m} for m, p in mods.items()}
    for pkg, files in packages.items():
        graph[pkg] = {dep for f in files for dep, _, _ in _imports(f, names, (pkg, *f.relative_to(APP / pkg).parent.parts))
                      if dep != pkg}
    return graph


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
    assert {"api", "runner", "cli", "paper", "runs", "studies"} <= set(graph)   # the folder was read
    assert {"runner", "paper", "runs", "studies"} <= graph["cli"]   # and its packages' modules
    assert "paper" not in graph["studies"] and "runner" not in graph["studies"]
    cycle = find_cycle(graph)
    assert cycle is None, f"an import cycle among the modules of wmr_cosim/: {' -> '.join(cycle)}"


#: The folders of the package's modules and the package each one is: wmr_cosim/ (its own files; its
#: links to the others are read as those), and the subpackages it links to.
PACKAGE_FOLDERS = {"wmr_cosim": APP, "wmr_cosim.cosim": ROOT / "cosim", "wmr_cosim.components": ROOT / "components",
                   "wmr_cosim.fmus": ROOT / "fmus"}

#: Private names one module still imports from another, as "folder/file.py: name of module", each with
#: its reason.  The list may only shrink: an entry goes once its name is made public where it is defined.
ALLOWED_PRIVATE: dict[str, str] = {}


def package_modules() -> dict[str, Path]:
    """{dotted module name: file} of every module of the package (``wmr_cosim.cosim.scenario.document``, the
    package itself as ``wmr_cosim``, a subpackage as ``wmr_cosim.cosim`` or ``wmr_cosim.cosim.scenario``)."""
    out: dict[str, Path] = {}
    for pkg, folder in PACKAGE_FOLDERS.items():
        files = _app_files() if pkg == "wmr_cosim" else folder.rglob("*.py")
        for p in sorted(files):
            parts = [pkg, *p.relative_to(folder).with_suffix("").parts]
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    return out


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


class _PrivateUse(ast.NodeVisitor):
    """The private names a module takes from other modules of the package: ``from .x import _y`` (any
    level, or absolute from ``wmr_cosim``), and ``x._y`` where ``x`` is bound by an import to a module of
    the package (``x.y._z`` too) and not rebound in the function that reads it.  Attributes of anything
    else (a library's handle, a shared memory's ``_name``) are not a module's private names."""

    def __init__(self, module: str, is_package: bool, modules: set[str]) -> None:
        self.module, self.modules = module, modules
        self.package = module if is_package else module.rpartition(".")[0]
        self.scopes: list[dict[str, str | None]] = [{}]   # name -> the module it is bound to (None: rebound)
        self.found: list[tuple[str, str, int]] = []       # (module, private name, line)

    def _base(self, node: ast.ImportFrom) -> str | None:
        if node.level == 0:
            return node.module if node.module and node.module.split(".")[0] == "wmr_cosim" else None
        parts = self.package.split(".")
        if node.level > 1:
            parts = parts[:len(parts) - node.level + 1]
        return ".".join(parts + ([node.module] if node.module else []))

    def _take(self, dep: str, name: str, line: int) -> None:
        if dep != self.module and _private(name):
            self.found.append((dep, name, line))

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        base = self._base(node)
        if base is None:
            return
        for a in node.names:
            full = f"{base}.{a.name}"
            if full in self.modules:          # a module: ``from . import x``, ``from .cosim import scenario``
                self._take(base, a.name, node.lineno)
                self.scopes[-1][a.asname or a.name] = full
            else:
                self._take(base, a.name, node.lineno)
                self.scopes[-1][a.asname or a.name] = None

    def visit_Import(self, node: ast.Import) -> None:
        for a in node.names:
            if a.name.split(".")[0] != "wmr_cosim":
                self.scopes[-1][(a.asname or a.name).split(".")[0]] = None
            elif a.asname:
                self.scopes[-1][a.asname] = a.name if a.name in self.modules else None
            else:
                self.scopes[-1]["wmr_cosim"] = "wmr_cosim"

    def _bound(self, name: str) -> str | None:
        for scope in reversed(self.scopes):
            if name in scope:
                return scope[name]
        return None

    def _resolve(self, node: ast.AST) -> str | None:
        """The module of the package an expression names (``scenario``, ``wmr_cosim.cosim.scenario``), or None."""
        if isinstance(node, ast.Name):
            return self._bound(node.id)
        if isinstance(node, ast.Attribute):
            base = self._resolve(node.value)
            if base is not None and f"{base}.{node.attr}" in self.modules:
                return f"{base}.{node.attr}"
        return None

    def visit_Attribute(self, node: ast.Attribute) -> None:
        owner = self._resolve(node.value)
        if owner is not None:
            self._take(owner, node.attr, node.lineno)
        self.generic_visit(node)

    def _function(self, node: ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) -> None:
        for d in getattr(node, "decorator_list", []):
            self.visit(d)
        args = node.args
        for default in [*args.defaults, *args.kw_defaults]:
            if default is not None:
                self.visit(default)
        local: dict[str, str | None] = {a.arg: None for a in [*args.posonlyargs, *args.args, *args.kwonlyargs,
                                                                *filter(None, [args.vararg, args.kwarg])]}
        body = node.body if isinstance(node.body, list) else [node.body]
        for stmt in body:   # names assigned in the function are its own, wherever the assignment is
            for sub in ast.walk(stmt):
                if isinstance(sub, ast.Name) and isinstance(sub.ctx, ast.Store):
                    local[sub.id] = None
        self.scopes.append(local)
        for stmt in body:
            self.visit(stmt)
        self.scopes.pop()

    visit_FunctionDef = visit_AsyncFunctionDef = visit_Lambda = _function


def private_uses(path: Path, module: str, modules: set[str]) -> list[tuple[str, str, int]]:
    """(module of the package, private name of it, line) of every private name ``path`` (module ``module``)
    imports from another module of the package or reads from one it imported."""
    v = _PrivateUse(module, path.stem == "__init__", modules)
    v.visit(ast.parse(path.read_text(), str(path)))
    return v.found


def test_the_private_name_finder_sees_imports_and_attributes_of_imported_modules(tmp_path):
    mods = {"wmr_cosim", "wmr_cosim.cosim", "wmr_cosim.cosim.scenario", "wmr_cosim.cosim.system",
            "wmr_cosim.cosim.errors", "wmr_cosim.studies.sweep"}
    f = tmp_path / "system.py"
    f.write_text("import ctypes\nimport wmr_cosim.cosim.errors\nfrom . import scenario\n"
                 "from .errors import _one, CosimError\nfrom ..studies.sweep import _two\n"
                 "from wmr_cosim.cosim.scenario import _three as three\nimport wmr_cosim.cosim.errors as errs\n"
                 "def _own(): pass\n"
                 "def f(dll, shm):\n    scenario._read()\n    dll._handle, shm._name, _own()\n"
                 "    wmr_cosim.cosim.errors._four\n    errs._five\n    return ctypes._six\n"
                 "def g(scenario):\n    return scenario._field\n"
                 "def h():\n    scenario = object()\n    return scenario._field\n"
                 "def k():\n    from .scenario import __all__\n    from . import system\n    return system._x\n")
    found = sorted(private_uses(f, "wmr_cosim.cosim.system", mods))
    assert found == [("wmr_cosim.cosim.errors", "_five", 13), ("wmr_cosim.cosim.errors", "_four", 12),
                     ("wmr_cosim.cosim.errors", "_one", 4), ("wmr_cosim.cosim.scenario", "_read", 10),
                     ("wmr_cosim.cosim.scenario", "_three", 6), ("wmr_cosim.studies.sweep", "_two", 5)]


def test_no_module_of_the_package_takes_a_private_name_of_another():
    mods = package_modules()
    assert {"wmr_cosim.studies.sweep", "wmr_cosim.cosim.scenario.document", "wmr_cosim.cosim.stepping",
            "wmr_cosim.components.paper", "wmr_cosim.fmus.fmi_decl", "wmr_cosim.cli.run"} <= set(mods)   # every folder was read
    uses = {f"{p.relative_to(ROOT).as_posix()}: {name} of {dep}": line for m, p in mods.items()
            for dep, name, line in private_uses(p, m, set(mods))}
    bad = [f"{k.split(':')[0]}:{line}:{k.split(':', 1)[1]}" for k, line in sorted(uses.items())
           if k not in ALLOWED_PRIVATE]
    assert not bad, "private names taken from another module: " + "; ".join(bad)


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
    files = _app_files() + sorted((ROOT / "cosim").rglob("*.py"))
    return {f"{p.relative_to(ROOT).as_posix()}:{name}": n
            for p in files for name, n in _functions(p).items() if n > MAX_LINES}


def test_no_function_of_wmr_cosim_or_cosim_is_over_60_lines():
    new = {k: n for k, n in _long_functions().items() if k not in LONG_FUNCTIONS}
    assert not new, (f"functions over {MAX_LINES} lines (split them into named helpers): "
                     + ", ".join(f"{k} ({n})" for k, n in sorted(new.items())))



#: The most modules wmr_cosim/ holds beside its folders (its face, the Python API, the exit codes, the runner,
#: the shipped scenario files): what is not one of these belongs in a folder that is a concept.
MAX_TOP_MODULES = 6
#: The most lines of one command's module of the command line.
MAX_COMMAND_LINES = 250


def test_the_package_folder_holds_few_modules_beside_its_folders():
    assert len(_app_modules()) <= MAX_TOP_MODULES, sorted(_app_modules())
    assert {"cli", "paper", "runs", "studies"} <= set(_app_packages())


def test_the_command_line_is_one_module_per_command_none_long():
    """Each command of the table is a module of cli/ of its name, holding its options and its run; no
    module of cli/ is over MAX_COMMAND_LINES lines."""
    from wmr_cosim.cli import build_parser
    from wmr_cosim.cli.commands import COMMANDS

    files = {p.stem: p for p in (APP / "cli").glob("*.py")}
    for name, module in COMMANDS.items():
        assert module.__name__ == f"wmr_cosim.cli.{name.replace('-', '_')}", (name, module.__name__)
        assert name.replace("-", "_") in files
    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    assert set(sub.choices) == set(COMMANDS)
    long = {p.name: n for p in files.values() if (n := len(p.read_text().splitlines())) > MAX_COMMAND_LINES}
    assert not long, long


def test_the_fmus_modules_import_each_other_without_a_cycle():
    """fmus/ (the slaves and their builds): the builds take the win64 toolchain from the master (where the
    container's build reads it too), so that the C plant's build may read the Python FMUs' (not the other
    way round too)."""
    folder = ROOT / "fmus"
    names = {p.stem for p in folder.glob("*.py")}
    graph: dict[str, set[str]] = {}
    for p in folder.glob("*.py"):
        deps: set[str] = set()
        for node in ast.walk(ast.parse(p.read_text(), str(p))):
            if isinstance(node, ast.ImportFrom) and node.module:
                parts = node.module.split(".")
                if node.level == 1:
                    deps.add(parts[0])
                elif node.level == 0 and parts[:2] == ["wmr_cosim", "fmus"] and len(parts) > 2:
                    deps.add(parts[2])
        graph[p.stem] = {d for d in deps if d in names and d != p.stem}
    assert "cplant_build" not in graph["build"]
    cycle = find_cycle(graph)
    assert cycle is None, f"an import cycle among the modules of fmus/: {' -> '.join(cycle)}"
