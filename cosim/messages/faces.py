"""The faces of the master's packages: each lists its exports once, as the imports of its
``if TYPE_CHECKING:`` block (what the type checker reads), and :func:`attach` makes the same list its
lazy ``__getattr__``, ``__dir__`` and ``__all__`` at run time, each name imported where it is first used.
The list is read from the face's source when first needed (its first name looked up, ``dir()`` or
``__all__``), so that importing a face costs no parse."""
from __future__ import annotations

from typing import Any, Callable

import lazy_loader


def exports(file: str) -> dict[str, list[str]]:
    """The exports of the face in ``file`` (its ``__init__.py``): submodule -> the names imported from it
    in its ``if TYPE_CHECKING:`` block, in their order.  ValueError for an import there that a lazy face
    cannot give (absolute, from the package itself, a star, a name imported under another)."""
    import ast

    with open(file, encoding="utf-8") as f:
        tree = ast.parse(f.read(), filename=file)
    found: dict[str, list[str]] = {}
    for node in tree.body:
        if not (isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"):
            continue
        for imp in node.body:
            if not (isinstance(imp, ast.ImportFrom) and imp.level == 1 and imp.module
                    and all(a.asname is None and a.name != "*" for a in imp.names)):
                raise ValueError(f"{file}, line {imp.lineno}: a face imports only names of its submodules, "
                                 "as `from .module import name`")
            found.setdefault(imp.module, []).extend(a.name for a in imp.names)
    return found


def attach(package: str, file: str) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of the face ``package`` (``__name__``) whose ``__init__.py`` is
    ``file`` (``__file__``): the names of :func:`exports`, each imported on first use; ``__all__`` (the
    names, sorted) is one of them."""
    lazy: list[tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]] = []

    def face() -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
        if not lazy:
            lazy.append(lazy_loader.attach(package, submod_attrs=exports(file)))
        return lazy[0]

    def __getattr__(name: str) -> Any:
        if name == "__all__":
            return list(face()[2])
        return face()[0](name)

    def __dir__() -> list[str]:
        return face()[1]()

    return __getattr__, __dir__
