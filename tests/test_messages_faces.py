"""The lazy faces (cosim/messages/faces.py): a face lists its exports once, as the imports of its
``if TYPE_CHECKING:`` block, and gives the same names at run time, each imported on first use."""
from __future__ import annotations

import sys

import pytest

from wmr_cosim.cosim.messages.faces import exports

FACE = ('"""A face."""\nfrom typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n'
        '    from .alpha import (B, a,\n                        c)\n    from .beta import d\n')


def test_the_exports_are_the_names_of_the_type_checking_block(tmp_path):
    face = tmp_path / "__init__.py"
    face.write_text(FACE + "X = 1\n")
    assert exports(str(face)) == {"alpha": ["B", "a", "c"], "beta": ["d"]}


@pytest.mark.parametrize("line", ["    from .alpha import a as b\n", "    from alpha import a\n",
                                  "    from . import alpha\n", "    from .alpha import *\n", "    import alpha\n"])
def test_an_import_a_lazy_face_cannot_give_is_refused(tmp_path, line):
    face = tmp_path / "__init__.py"
    face.write_text(FACE + line)
    with pytest.raises(ValueError, match="line 8: a face imports only names of its submodules"):
        exports(str(face))


def test_a_face_gives_its_names_on_first_use_and_all_of_them_in_all(tmp_path, monkeypatch):
    pkg = tmp_path / "facepkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(FACE.replace("\nif TYPE", "from wmr_cosim.cosim.messages.faces import attach\n"
                                                  "\nif TYPE") + "__getattr__, __dir__ = attach(__name__, __file__)\n")
    (pkg / "alpha.py").write_text("B, a, c = 'B', 'a', 'c'\n")
    (pkg / "beta.py").write_text("d = 'd'\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        import facepkg

        assert "facepkg.alpha" not in sys.modules
        assert facepkg.__all__ == ["B", "a", "c", "d"] == dir(facepkg)
        assert (facepkg.a, facepkg.d) == ("a", "d") and "facepkg.alpha" in sys.modules
        with pytest.raises(AttributeError):
            facepkg.e
    finally:
        for m in [m for m in sys.modules if m.split(".")[0] == "facepkg"]:
            del sys.modules[m]


def test_every_face_of_the_master_gives_what_its_block_imports():
    import importlib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "cosim"
    for init in [root / "__init__.py", *sorted(root.glob("*/__init__.py"))]:
        name = "wmr_cosim.cosim" + ("" if init.parent == root else f".{init.parent.name}")
        face = importlib.import_module(name)
        names = [n for ns in exports(str(init)).values() for n in ns]
        assert face.__all__ == sorted(names) and len(set(names)) == len(names), name
