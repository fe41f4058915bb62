"""The layering of the packages, as import-linter contracts ([tool.importlinter] in pyproject.toml): the
generic master (cosim/) imports nothing of the components, the FMUs or the application; the components
import no FMI package and nothing of wmr_cosim outside themselves; the master's folders are layers, each
importing only those below it; the application reaches the master through its face alone.  import-linter reads the
source tree of this checkout (wmr_cosim/ with its links to the top-level folders), imports inside
functions and chains through other modules included; a copy of the tree with forbidden imports added
shows that the contracts see them."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "pyproject.toml"
#: the folders linked into wmr_cosim/ as its subpackages
SUBPACKAGES = ("cosim", "components", "fmus", "scenarios")
CONTRACTS = {"master": "the generic master (cosim/)", "components": "the components (components/)",
             "master-layers": "the master's folders are layers", "master-face": "the application imports the master",
             "studies": "the studies (studies/) run any system", "cli-faces": "the command line reaches the studies"}


def lint_imports(tree: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` with the contracts of pyproject.toml on the package wmr_cosim found in ``tree``
    (first on the path, so neither an installed copy nor another checkout's editable install is read)."""
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONDONTWRITEBYTECODE": "1"}
    code = "from importlinter.cli import lint_imports_command; lint_imports_command()"
    return subprocess.run([sys.executable, "-c", code, "--no-cache", "--no-logo", str(CONFIG)],
                          capture_output=True, text=True, cwd=tree, env=env, timeout=300)


def test_the_subpackages_are_links_in_the_package_folder():
    """The layout the contracts (and any tool that reads the tree) depend on."""
    for name in SUBPACKAGES:
        link = ROOT / "wmr_cosim" / name
        assert link.is_symlink() and os.readlink(link) == f"../{name}", link
        assert (link / "__init__.py").is_file(), link


def test_the_layering_contracts_hold():
    p = lint_imports(ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "Contracts: 6 kept, 0 broken." in p.stdout, p.stdout


def test_the_face_contract_names_every_module_of_the_application():
    """A module added to wmr_cosim/ later is held to the master's face too: the contract lists them all."""
    import tomllib

    contracts = tomllib.loads(CONFIG.read_text())["tool"]["importlinter"]["contracts"]
    face = next(c for c in contracts if c["id"] == "master-face")
    app = {"wmr_cosim"} | {f"wmr_cosim.{p.stem}" for p in (ROOT / "wmr_cosim").glob("*.py") if p.stem != "__init__"} | {
        f"wmr_cosim.{p.name}" for p in (ROOT / "wmr_cosim").iterdir()   # its packages (cli/), not the linked ones
        if not p.is_symlink() and (p / "__init__.py").is_file()}
    assert set(face["source_modules"]) == app
    layers = next(c for c in contracts if c["id"] == "master-layers")
    folders = {p.name for p in (ROOT / "cosim").iterdir() if (p / "__init__.py").is_file()}
    assert set(layers["layers"]) == folders == {m.rpartition(".")[2] for m in face["forbidden_modules"]}


def _tree_copy(dest: Path) -> Path:
    """The package's sources, with wmr_cosim/ and its links as in the checkout."""
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.fmu")
    shutil.copytree(ROOT / "wmr_cosim", dest / "wmr_cosim", symlinks=True, ignore=ignore)
    for name in SUBPACKAGES:
        shutil.copytree(ROOT / name, dest / name, ignore=ignore)
    return dest


def test_a_forbidden_import_breaks_the_contracts(tmp_path):
    tree = _tree_copy(tmp_path / "tree")
    (tree / "cosim" / "_forbidden.py").write_text(
        "def f():\n    from ..components import paper  # inside a function\n    return paper\n")
    (tree / "components" / "_forbidden.py").write_text(
        "def f():\n    import fmpy\n    from ..cosim.messages import errors\n    return fmpy, errors\n")
    p = lint_imports(tree)
    assert p.returncode == 1, p.stdout + p.stderr
    assert "Contracts: 4 kept, 2 broken." in p.stdout, p.stdout
    for line in ("wmr_cosim.cosim._forbidden -> wmr_cosim.components.paper (l.2)",
                 "wmr_cosim.components._forbidden -> fmpy (l.2)",
                 "wmr_cosim.components._forbidden -> wmr_cosim.cosim.messages.errors (l.3)"):
        assert line in p.stdout, p.stdout


def test_an_application_module_imported_by_the_master_breaks_its_contract(tmp_path):
    """Any module directly in wmr_cosim/ counts as the application, one added later too, and importing
    the package wmr_cosim itself reaches the application through its __init__."""
    tree = _tree_copy(tmp_path / "tree")
    (tree / "wmr_cosim" / "_new_module.py").write_text("X = 1\n")
    (tree / "cosim" / "_forbidden.py").write_text("from .. import _new_module\nimport wmr_cosim\n")
    p = lint_imports(tree)
    assert p.returncode == 1 and "Contracts: 5 kept, 1 broken." in p.stdout, p.stdout + p.stderr
    assert "wmr_cosim.cosim._forbidden -> wmr_cosim._new_module (l.1)" in p.stdout, p.stdout
    assert "wmr_cosim.cosim is not allowed to import wmr_cosim.api:" in p.stdout, p.stdout


def test_a_lower_folder_importing_a_higher_one_breaks_the_layers(tmp_path):
    """A type-only import counts: the stepping importing the plan's records (to type an argument, say)."""
    tree = _tree_copy(tmp_path / "tree")
    (tree / "cosim" / "stepping" / "_forbidden.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..plan.records import Plan\n")
    p = lint_imports(tree)
    assert p.returncode == 1 and "Contracts: 5 kept, 1 broken." in p.stdout, p.stdout + p.stderr
    assert "wmr_cosim.cosim.stepping._forbidden -> wmr_cosim.cosim.plan.records (l.3)" in p.stdout, p.stdout


def test_the_application_importing_a_folder_of_the_master_breaks_the_face_contract(tmp_path):
    tree = _tree_copy(tmp_path / "tree")
    api = tree / "wmr_cosim" / "api.py"
    api.write_text(api.read_text() + "\n\ndef _f():\n    from .cosim.runtime.execution import Execution\n"
                   "    return Execution\n")
    p = lint_imports(tree)
    assert p.returncode == 1 and "Contracts: 5 kept, 1 broken." in p.stdout, p.stdout + p.stderr
    assert "wmr_cosim.api -> wmr_cosim.cosim.runtime.execution" in p.stdout, p.stdout


def test_the_studies_reaching_the_robot_break_their_contract(tmp_path):
    """Directly (the robot's measures, inside a function) or through a module that knows the robot (the
    runner, which builds its FMUs): either breaks the studies' contract."""
    tree = _tree_copy(tmp_path / "tree")
    (tree / "wmr_cosim" / "studies" / "_forbidden.py").write_text(
        "def f():\n    from ..paper import robot_measures\n    return robot_measures\n")
    (tree / "wmr_cosim" / "studies" / "_indirect.py").write_text("from ..runner import resolve_model\n")
    p = lint_imports(tree)
    assert p.returncode == 1 and "Contracts: 5 kept, 1 broken." in p.stdout, p.stdout + p.stderr
    assert "wmr_cosim.studies._forbidden -> wmr_cosim.paper.robot_measures (l.2)" in p.stdout, p.stdout
    assert "wmr_cosim.studies._indirect -> wmr_cosim.runner (l.1)" in p.stdout, p.stdout


def test_the_command_line_importing_a_module_behind_a_face_breaks_its_contract(tmp_path):
    tree = _tree_copy(tmp_path / "tree")
    sweep = tree / "wmr_cosim" / "cli" / "sweep.py"
    sweep.write_text(sweep.read_text() + "\n\ndef _f():\n    from ..studies.shipment import pack\n    return pack\n")
    p = lint_imports(tree)
    assert p.returncode == 1 and "Contracts: 5 kept, 1 broken." in p.stdout, p.stdout + p.stderr
    assert "wmr_cosim.cli.sweep -> wmr_cosim.studies.shipment" in p.stdout, p.stdout
