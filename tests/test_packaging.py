"""The project installs as one distribution whose import names are all under wmr_cosim; a wheel installed
into a fresh virtual environment runs the paper job, a shipped scenario and the FMU build from any folder,
reading its own scenario files and writing only under the working folder, --out or the user's cache."""
from __future__ import annotations

import ast
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
#: what a wheel is built from: the build configuration, the README (the long description) and the
#: folders that are packages through the links of wmr_cosim/ (pyproject.toml, [tool.setuptools.packages.find])
WHEEL_SOURCES = ("pyproject.toml", "README.md", "wmr_cosim", "components", "fmus", "cosim", "scenarios")


def _source_copy(dest: Path) -> Path:
    """A clean copy of what the wheel is built from (no build/ or *.egg-info of earlier builds, whose
    stale files setuptools would package, and nothing written into the checkout)."""
    dest.mkdir(parents=True)
    for name in WHEEL_SOURCES:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.fmu"))
        else:
            shutil.copy2(src, dest / name)
    return dest


def _pip(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    p = subprocess.run([sys.executable, "-m", "pip", *args], capture_output=True, text=True, cwd=cwd)
    if p.returncode != 0:
        pytest.fail(f"pip {' '.join(args[:2])} failed (exit {p.returncode}): {p.stderr.strip()[-2000:]}")
    return p


def test_components_import_no_fmi():
    """Nothing in components/ imports FMI (fmpy, pythonfmu)."""
    for f in (ROOT / "components").glob("*.py"):
        text = f.read_text()
        assert "fmpy" not in text and "pythonfmu" not in text, f
        # relative imports only, so the folder can be bundled under another package name
        assert "wmr_cosim" not in text.replace("wmr_cosim.components", ""), f


def test_non_editable_install_works(tmp_path):
    target = tmp_path / "site packages"
    _pip("install", "--quiet", "--no-deps", "--no-build-isolation", "--target", str(target),
         str(_source_copy(tmp_path / "src")))
    code = ("import wmr_cosim.components.plant as m, wmr_cosim.components.paper as p, wmr_cosim.cli;"
            "import wmr_cosim.scenario_files as s;"
            "print(m.__file__); print(p.table1()['gamma']); print(s.folder())")
    env = {**os.environ, "PYTHONPATH": str(target)}
    q = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert q.returncode == 0, q.stderr
    lines = q.stdout.split("\n")
    assert Path(lines[0]).is_relative_to(target), lines[0]
    assert lines[1] == "11.0"
    shipped = Path(lines[2])
    assert shipped.is_relative_to(target)
    for f in (ROOT / "scenarios").rglob("*.toml"):  # every scenario file ships, byte for byte
        assert (shipped / f.relative_to(ROOT / "scenarios")).read_bytes() == f.read_bytes(), f
    for f in (ROOT / "fmus" / "pyloader").iterdir():  # the loaders' sources and their header (the build needs them)
        assert (target / "wmr_cosim" / "fmus" / "pyloader" / f.name).read_bytes() == f.read_bytes(), f
    # every package of the tree (a folder with __init__.py, through the links) is installed with its modules
    tree = {Path(d).relative_to(ROOT) for d, _, files in os.walk(ROOT / "wmr_cosim", followlinks=True)
            if "__init__.py" in files}
    assert Path("wmr_cosim/cosim/linearisation") in tree
    for folder in tree:
        for f in (ROOT / folder).glob("*.py"):
            assert (target / folder / f.name).read_bytes() == f.read_bytes(), f"{folder / f.name} is not installed"


#: every third-party module the installed code imports -> the requirement that provides it, and where
#: pyproject.toml declares it (dependencies, or the extra of the only commands that import it)
IMPORTS = {
    "fmpy": ("fmpy", None), "pythonfmu": ("pythonfmu", None), "pythonfmu3": ("pythonfmu3", None),
    "numpy": ("numpy", None),
    "matplotlib": ("matplotlib", None), "tqdm": ("tqdm", None), "pyssp_standard": ("pyssp-standard", None),
    "lxml": ("lxml", None), "lazy_loader": ("lazy_loader", None),
    "pandas": ("pandas", "sweep"), "distributed": ("dask[distributed]", "sweep"),  # sweep, gamma-search
    "scipy": ("scipy", "sweep"),   # falsify (and linearize: in the linear extra too)
    "control": ("control", "linear"),   # linearize (python-control)
    "starlette": ("starlette", "live"), "uvicorn": ("uvicorn", "live"), "tomli_w": ("tomli-w", "live"),  # run --live
}


def _requirement_names(reqs: list[str]) -> set[str]:
    return {re.split(r"[<>=!~; ]", r, maxsplit=1)[0].strip().lower() for r in reqs}


def test_runtime_dependencies_are_what_the_code_imports():
    """The installed code's third-party imports are exactly the declared ones; scipy (falsify's, and the
    tests') is in the sweep and test extras, not a run-time dependency."""
    found: dict[str, set[str]] = {}
    for d in ("wmr_cosim", "components", "fmus", "cosim"):
        for f in (ROOT / d).rglob("*.py"):
            for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                for name in names:
                    top = name.split(".")[0]
                    if top not in sys.stdlib_module_names and top != "wmr_cosim":
                        found.setdefault(top, set()).add(str(f.relative_to(ROOT)))
    assert set(found) == set(IMPORTS), f"declare in pyproject.toml and in IMPORTS: {found}"
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    runtime = _requirement_names(meta["dependencies"])
    for module, (req, extra) in IMPORTS.items():
        declared = runtime if extra is None else _requirement_names(meta["optional-dependencies"][extra])
        assert req.lower() in declared, f"{module} (imported by {sorted(found[module])}): {req} not in {extra or 'dependencies'}"
    assert "scipy" not in runtime and "scipy" in _requirement_names(meta["optional-dependencies"]["test"])


#: The extras the commands need beyond the run-time dependencies (sweep, gamma-search, falsify; linearize).
EXTRAS = "sweep,linear"


@pytest.fixture(scope="module")
def venv(tmp_path_factory):
    """The wheel (built from a clean copy of the sources) installed with its declared dependencies and the
    extras of the commands (sweep, linear) into a fresh virtual environment without the system's
    site-packages; removed afterwards (about 500 MB)."""
    import pip

    base = tmp_path_factory.mktemp("wheel")
    src = _source_copy(base / "src")
    _pip("wheel", "--quiet", "--no-deps", "--no-build-isolation", "--wheel-dir", str(base / "dist"), str(src))
    wheels = list((base / "dist").glob("wmr_cosim-*.whl"))
    assert len(wheels) == 1, wheels
    env_dir = base / "venv"
    if tuple(int(x) for x in pip.__version__.split(".")[:2]) >= (22, 3):  # this pip installs into it
        subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env_dir)], check=True)
        _pip("--python", str(env_dir / "bin" / "python"), "install", "--quiet", f"{wheels[0]}[{EXTRAS}]")
    else:
        subprocess.run([sys.executable, "-m", "venv", str(env_dir)], check=True)
        p = subprocess.run([str(env_dir / "bin" / "python"), "-m", "pip", "install", "--quiet",
                            f"{wheels[0]}[{EXTRAS}]"],
                           capture_output=True, text=True)
        assert p.returncode == 0, p.stderr[-2000:]
    yield env_dir
    shutil.rmtree(env_dir, ignore_errors=True)


def _installed_files(env_dir: Path) -> set[Path]:
    pkg = next((env_dir / "lib").glob("python3*/site-packages/wmr_cosim"))
    return {p for p in pkg.rglob("*") if p.is_file() and "__pycache__" not in p.parts}


@pytest.mark.slow
def test_wheel_in_a_fresh_environment_runs_the_commands_from_any_folder(venv, tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(XDG_CACHE_HOME=str(tmp_path / "cache"), MPLCONFIGDIR=str(tmp_path / "mpl"))
    exe = venv / "bin" / "wmr-cosim"
    before = _installed_files(venv)

    def cli(*args: str) -> subprocess.CompletedProcess:
        p = subprocess.run([str(exe), *args], capture_output=True, text=True, cwd=work, env=env, timeout=900)
        assert p.returncode == 0, f"wmr-cosim {' '.join(args)}: exit {p.returncode}\n{p.stdout}\n{p.stderr}"
        return p

    # the installed code, not a checkout or an editable install
    q = subprocess.run([str(venv / "bin" / "python"), "-c", "import wmr_cosim; print(wmr_cosim.__file__)"],
                       capture_output=True, text=True, cwd=work, env=env)
    assert Path(q.stdout.strip()).is_relative_to(venv), q.stdout + q.stderr
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert cli("--version").stdout.strip() == f"wmr-cosim {version}"

    # a shipped scenario by name: its own copy; its FMUs, named by model name, built on demand into the
    # per-user cache (not into the package nor the working folder); results under --out
    fmus = tmp_path / "cache" / "wmr-cosim" / "fmus"
    assert not fmus.exists()
    cli("run", "example.toml", "--out", "example", "--quiet")
    sig = np.load(work / "example" / "signals.npy")
    summary = json.loads((work / "example" / "summary.json").read_text())
    assert summary["status"] == "ok" and sig["time"][-1] == pytest.approx(20.0)
    assert np.isfinite(sig["plant.x_A"]).all()
    if shutil.which("cc"):   # the compiled loop's source ships with the package, its build goes to the cache
        assert summary["stepping"]["loop"] == "compiled (C)"
        assert len(list((tmp_path / "cache" / "wmr-cosim").glob("native-loop-*.so"))) == 1
    assert sorted(f.name for f in fmus.glob("*.fmu")) == ["WmrController.fmu", "WmrPlant.fmu", "WmrSensor.fmu"]
    cli("check", "scenarios/g1_learn.toml")

    # build: the same cache, already current
    out = cli("build").stdout
    for model in ("WmrPlant", "WmrSensor", "WmrController"):
        assert f"{model}: {fmus / (model + '.fmu')} (up to date)" in out

    # the paper job with its shipped protocol (one variant)
    cli("paper", "--out", "paper", "--no-compare", "--quiet")
    metrics = json.loads((work / "paper" / "metrics.json").read_text())
    assert metrics["diverged_runs"] == [] and sorted(metrics["tasks"]) == ["G1", "G2", "G3", "LINE"]
    assert (work / "paper" / "report.html").is_file()

    assert sorted(p.name for p in work.iterdir()) == ["example", "paper"]  # nothing else in the folder
    assert _installed_files(venv) == before  # nothing written inside the installed package


def test_a_scenario_name_that_is_not_a_file_here_is_the_shipped_one(tmp_path, monkeypatch):
    from wmr_cosim.paper.tasks import DEFAULT_MANIFEST
    from wmr_cosim.scenario_files import folder, scenario_path

    shipped = folder()
    assert (shipped / "paper.toml").is_file() and (shipped / DEFAULT_MANIFEST).is_file()
    monkeypatch.chdir(tmp_path)
    assert scenario_path("example.toml") == shipped / "example.toml"
    assert scenario_path("paper/g1.toml") == shipped / "paper" / "g1.toml"
    assert scenario_path("scenarios/g1_learn.toml") == shipped / "g1_learn.toml"
    for name in ("missing.toml", "../example.toml", "paper", str(tmp_path / "example.toml")):
        assert scenario_path(name) == Path(name), name  # the command then reports it missing
    (tmp_path / "example.toml").write_text("# mine\n")
    assert scenario_path("example.toml") == Path("example.toml")  # a file here comes first


#: A sweep of one point over a shortened example, one metric of the generic kind.
_SWEEP = """base = "short.toml"
[grid]
"plant.foam_da1" = [0.4]
[metric.x_end]
of = "final"
variable = "plant.x_A"
"""
#: A falsification of the smallest budget over the G1 protocol cut to 11 s.
_FALSIFY = """base = "g1_short.toml"
requirement = "tracking"
seed = 3
budget = 10
[space]
"plant.foam_da1" = { low = 0.2, high = 1.2 }
"""


@pytest.mark.slow
def test_every_command_runs_its_smallest_case_from_the_installed_wheel(venv, tmp_path):
    """Each command of the table, once, from the wheel installed with its extras (the studies, the
    linearisation): what a package folder missing from the wheel, or an extra missing a module, breaks."""
    import test_falsify as falsify_tests
    from reference_fmus import REF
    from wmr_cosim.cli.commands import COMMANDS

    work = tmp_path / "work"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(XDG_CACHE_HOME=str(tmp_path / "cache"), MPLCONFIGDIR=str(tmp_path / "mpl"), MPLBACKEND="Agg")
    ran: set[str] = set()

    def cli(*args: str) -> str:
        p = subprocess.run([str(venv / "bin" / "wmr-cosim"), *args], capture_output=True, text=True, cwd=work,
                           env=env, timeout=900)
        assert p.returncode == 0, f"wmr-cosim {' '.join(args)}: exit {p.returncode}\n{p.stdout}\n{p.stderr}"
        ran.add(args[0])
        return p.stdout

    (work / "short.toml").write_text('base = "example.toml"\n[experiment]\nstop = 13.0\n')  # (events at 12 s)
    (work / "sweep.toml").write_text(_SWEEP)
    # the falsification tests' base, on the shipped scenario by its name
    short = falsify_tests.SHORT.replace(f'"{falsify_tests.SCENARIO}"', '"g1_requirements.toml"')
    (work / "g1_short.toml").write_text(short)
    (work / "falsify.toml").write_text(_FALSIFY)
    shutil.copy(ROOT / "tests" / "data" / "short_protocol.toml", work / "protocol.toml")
    (work / "protocol.toml").write_text((work / "protocol.toml").read_text().replace(
        '"../../scenarios/paper/g1.toml"', '"paper/g1.toml"'))

    assert "G1" in cli("direct", "G1", "--stop", "2")
    assert "WmrPlant" in cli("build")
    cli("run", "short.toml", "--out", "short", "--quiet")
    assert cli("check", "short.toml").startswith("short.toml: ok: 3 instances")
    cli("plot", "short", "plant.x_A", "--out", "short.png")
    cli("export-ssp", "g1_learn.toml", "--out", "short.ssp")   # (a scenario without events: SSP has none)
    (work / "vdp.toml").write_text(f'[instances.vdp]\nfmu = "{REF / "fmi2" / "VanDerPol.fmu"}"\n'
                                   '[experiment]\nstop = 1.0\nstep = 0.01\n[record]\nvariables = ["vdp.x0"]\n')
    cli("export-fmu", "vdp.toml", "--out", "vdp.fmu")   # (the container's C source shipped beside the loop's)
    cli("export-fmu", "vdp.toml", "--out", "vdp3.fmu", "--fmi", "3")   # (its FMI 3.0 face and the headers)
    plant = next((tmp_path / "cache" / "wmr-cosim" / "fmus").glob("WmrPlant.fmu"))
    assert "WmrPlant" in cli("info", str(plant))
    cli("sweep", "sweep.toml", "--out", "sweep", "--workers", "1", "--quiet")
    cli("gamma-search", "protocol.toml", "--grid", "11", "--out", "gamma", "--workers", "1", "--quiet")
    cli("falsify", "falsify.toml", "--out", "falsify", "--workers", "1", "--quiet")
    assert "eigenvalues" in cli("linearize", str(REF / "fmi2" / "VanDerPol.fmu"), "--at", "0", "--out", "lin")
    cli("paper", "--help")   # (the paper job itself: the test above)
    cli("view", "--help")    # (it serves until Ctrl-C: tests/test_live_page.py)
    assert ran == set(COMMANDS)
    assert (work / "short.png").is_file() and (work / "short.ssp").is_file() and (work / "vdp3.fmu").is_file()
    assert (work / "sweep" / "results.csv").is_file() and (work / "falsify" / "falsify.json").is_file()
    assert (work / "gamma" / "gamma_search.json").is_file() and (work / "lin" / "linear.npz").is_file()
