"""Mutation testing of the core with mutmut: are there bugs the tests would let through?

``python benchmarks/bench.py mutation`` (or ``python benchmarks/mutation.py [--only GLOB ...]``) plants
every mutant mutmut makes in ``components/``, ``cosim/`` and the analysis code (``wmr_cosim/paper/analysis.py``,
``wmr_cosim/paper/claims.py``), one at a time, and runs against each the fast tests that cover the function it
sits in (mutmut records which tests call which function in one instrumented run of the fast suite, then
forks a worker per mutant).  The last line printed is one JSON object:
``{"mutants", "killed", "kill_rate", "survivors", ...}``, with the kill rate per area.

How it is laid out: mutmut names a mutant after its file's path and finds it again through the module's
import name, so the project is staged in ``build/mutation/`` (git-ignored) as the installed package is laid
out (``wmr_cosim/components``, ``wmr_cosim/cosim``, ...), with the tests, the scenarios and the examples
beside it.  mutmut keeps its results in ``build/mutation/mutants/``: a second run tests the mutants of
changed functions and, again, those that survived (``--keep-survivors`` skips those, ``--fresh`` starts
over).  The FMUs the tests build are kept in ``build/mutation/fmu-cache/`` between mutmut's many short
test sessions.

Equivalent mutants (those no test can tell from the original) are listed, each with its one-line reason,
in ``benchmarks/mutation-equivalents.toml``.  An entry names the mutant and the mutated line as mutmut
shows it; if the code has moved so that the named mutant no longer changes that line, the entry is
reported as stale and the mutant counts as a survivor again.  Equivalent mutants are left out of the
kill rate and counted apart.

Timeouts count as killed (a mutant that makes a test hang is caught by the step watchdogs' absence of
progress); "no tests" (code no fast test runs) counts as a survivor.
"""
from __future__ import annotations

import argparse
import fnmatch
import json
import math
import os
import random
import shutil
import subprocess
import sys
import time
import tomllib
from collections import Counter
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
STAGE = ROOT / "build" / "mutation"
EQUIVALENTS = ROOT / "benchmarks" / "mutation-equivalents.toml"

#: Folders of the repository and where the installed package has them.
PACKAGE_DIRS = {"wmr_cosim": "wmr_cosim", "components": "wmr_cosim/components", "cosim": "wmr_cosim/cosim",
                "fmus": "wmr_cosim/fmus", "scenarios": "wmr_cosim/scenarios"}
#: Copied beside the package: what the tests read by path.
ALSO = ("tests", "scenarios", "examples", "docs")
#: What is mutated (globs on the staged paths) and the area each belongs to.
AREAS = {"components": "wmr_cosim/components/*.py", "cosim": "wmr_cosim/cosim/*.py",
         "analysis": "wmr_cosim/paper/analysis.py", "claims": "wmr_cosim/paper/claims.py"}
#: The tests the mutants run against: the fast suite, without the tests of the repository's own files
#: (documentation, packaging, the FMU build from the source folders) and the ones that run other programs
#: (C hosts, interop peers).
TEST_SELECTION = ["tests", "-m", "not slow",
                  "--ignore=tests/test_docs.py", "--ignore=tests/test_packaging.py",
                  "--ignore=tests/test_interop.py", "--ignore=tests/test_hosts.py",
                  "--ignore=tests/test_tempdir_guard.py", "--ignore=tests/test_fmu_build.py",
                  # (the harness's own tests read benchmarks/, which is not staged)
                  "--ignore=tests/test_mutation_harness.py",
                  # Dask's dashboard, once started, stays registered in the process, and mutmut runs
                  # the tests more than once in its process: the "no dashboard" case would fail
                  "--deselect=tests/test_security.py::test_a_local_cluster_listens_on_the_loopback_address_only"]
KILLED = {"killed", "timeout", "segfault"}


def _sync(src: Path, dst: Path, keep: frozenset[str] = frozenset()) -> None:
    """Make ``dst`` a copy of ``src`` (files compared by size and mtime, so mutmut sees unchanged files as
    unchanged); build products and caches are left out, entries of ``dst`` named in ``keep`` are kept."""
    skip = {"__pycache__", ".pytest_cache", "build", "mutants", ".ipynb_checkpoints"}
    dst.mkdir(parents=True, exist_ok=True)
    wanted = set()
    for entry in src.iterdir():
        if entry.name in skip or entry.suffix in (".fmu", ".pyc"):
            continue
        wanted.add(entry.name)
        target = dst / entry.name
        if entry.is_dir():
            _sync(entry, target)
        else:
            st = entry.stat()
            if not target.exists() or target.stat().st_size != st.st_size or target.stat().st_mtime != st.st_mtime:
                shutil.copy2(entry, target)
    for stale in dst.iterdir():
        if stale.name not in wanted and stale.name not in skip and stale.name not in keep:
            shutil.rmtree(stale) if stale.is_dir() else stale.unlink()


def stage(only: list[str]) -> None:
    """Lay the project out in STAGE as the installed package is, with mutmut's configuration."""
    STAGE.mkdir(parents=True, exist_ok=True)
    inner = frozenset(place.split("/", 1)[1] for place in PACKAGE_DIRS.values() if "/" in place)
    for folder, place in PACKAGE_DIRS.items():
        _sync(ROOT / folder, STAGE / place, keep=inner if place == "wmr_cosim" else frozenset())
    for name in ALSO:
        _sync(ROOT / name, STAGE / name)
    for place in ("wmr_cosim", "wmr_cosim/components", "wmr_cosim/cosim", "wmr_cosim/fmus"):
        if not (STAGE / place / "__init__.py").exists():
            raise SystemExit(f"mutation: staging failed, {STAGE / place} has no __init__.py")
    _pristine_fmu_components()
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    markers = pyproject["tool"]["pytest"]["ini_options"]["markers"]
    config = "\n".join([
        "[tool.pytest.ini_options]",
        f"markers = {json.dumps(markers)}",
        "",
        "[tool.mutmut]",
        'source_paths = ["wmr_cosim"]',
        f"only_mutate = {json.dumps(only)}",
        f"also_copy = {json.dumps(list(ALSO))}",
        f"pytest_add_cli_args_test_selection = {json.dumps(TEST_SELECTION)}",
        'pytest_add_cli_args = ["-p", "no:cacheprovider"]',
        "timeout_multiplier = 10.0",
        "timeout_constant = 5.0",
        "use_git_change_detection = false",
        "",
    ])
    path = STAGE / "pyproject.toml"
    if not path.exists() or path.read_text(encoding="utf-8") != config:
        path.write_text(config, encoding="utf-8")


#: In the staged fmus/build.py: where an FMU's bundled copy of the components comes from.
_COMPONENTS_LINE = 'here = _HERE.parent / "components"'


def _pristine_fmu_components() -> None:
    """The FMUs the tests build bundle the staged, unmutated components, not mutmut's copy: mutmut's
    instrumented code cannot run in the FMU build's child process, and a mutant is planted in the
    process under test only.  (So a component mutant is killed by the tests of the component and of the
    direct loop, never through an FMU.)"""
    build = STAGE / "wmr_cosim" / "fmus" / "build.py"
    text = build.read_text(encoding="utf-8")
    if _COMPONENTS_LINE not in text:
        raise SystemExit(f"mutation: {build} no longer has the line `{_COMPONENTS_LINE}`; update "
                         "benchmarks/mutation.py to point the FMU build at the unmutated components")
    stat = (ROOT / "fmus" / "build.py").stat()
    build.write_text(text.replace(_COMPONENTS_LINE, f"here = Path({str(STAGE / 'wmr_cosim' / 'components')!r})"),
                     encoding="utf-8")
    os.utime(build, ns=(stat.st_atime_ns, stat.st_mtime_ns))  # unchanged for _sync's comparison


def results() -> dict[str, str]:
    """{mutant name: status} from mutmut's result files."""
    from mutmut.stats import status_by_exit_code

    out: dict[str, str] = {}
    for meta in sorted((STAGE / "mutants").rglob("*.py.meta")):
        data = json.loads(meta.read_text(encoding="utf-8"))
        for name, code in data.get("exit_code_by_key", {}).items():
            out[name] = status_by_exit_code[code]
    return out


def mutant_diff(name: str) -> str:
    """The mutated line(s) of one mutant, as mutmut shows them (``+`` lines of its diff)."""
    proc = subprocess.run([sys.executable, "-m", "mutmut", "show", name], cwd=STAGE, capture_output=True,
                          text=True, check=False)
    plus = [ln[1:].strip() for ln in proc.stdout.splitlines() if ln.startswith("+") and not ln.startswith("+++")]
    return "\n".join(plus)


def survivor_diffs(names: list[str]) -> str:
    """The diff of each named mutant against the original function, read from mutmut's mutated copies
    (one ``ast`` parse per file instead of one ``mutmut show`` process per mutant), grouped by file."""
    import ast
    import difflib

    by_module: dict[str, list[str]] = {}
    for name in names:
        by_module.setdefault(_module_of(name), []).append(name)
    out: list[str] = []
    for module, members in sorted(by_module.items()):
        path = STAGE / "mutants" / (module.replace(".", "/") + ".py")
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        funcs = {node.name: lines[node.lineno - 1:node.end_lineno]
                 for node in ast.walk(ast.parse(text)) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))}
        out.append(f"=== {path.relative_to(STAGE / 'mutants')}")
        for name in sorted(members, key=lambda n: (n.partition("__mutmut_")[0], int(n.rpartition("_")[2]))):
            local = name[len(module) + 1:]
            orig = funcs.get(local.partition("__mutmut_")[0] + "__mutmut_orig")
            mutant = funcs.get(local)
            if orig is None or mutant is None:
                out.append(f"--- {local}: not found in {path.name}")
                continue
            diff = [ln for ln in difflib.unified_diff(orig[1:], mutant[1:], lineterm="", n=0)
                    if ln[:1] in "+-" and not ln.startswith(("+++", "---"))]
            out.append(f"--- {local}")
            out.extend("  " + ln for ln in diff)
    return "\n".join(out) + "\n"


#: Run in mutmut's mutated tree by :func:`check`: imports the project and pytest once, then forks one
#: child per mutant that runs the test files with that mutant active (as mutmut does) and exits with
#: pytest's status; a child that runs longer than the limit is killed and counts as killed (a hang).
_CHECK_DRIVER = r"""
import json, os, sys, time
import numpy, fmpy, pytest
import wmr_cosim.cosim.runtime.execution, wmr_cosim.cosim.plan.ssp, wmr_cosim.cosim.instances.isolation, wmr_cosim.api
names, files, limit = json.loads(sys.argv[1]), json.loads(sys.argv[2]), float(sys.argv[3])
for name in names:
    pid = os.fork()
    if pid == 0:
        os.environ["MUTANT_UNDER_TEST"] = name
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(null, 2)
        os._exit(int(pytest.main(["-x", "-q", "-p", "no:cacheprovider", *files])))
    end = time.monotonic() + limit
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
            break
        if time.monotonic() > end:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            code = "timeout"
            break
        time.sleep(0.02)
    print(json.dumps([name, code]), flush=True)
"""


def check(names: list[str], test_files: list[Path], limit_s: float = 120.0) -> dict[str, str]:
    """Whether the given test files kill each named mutant: the files are copied beside mutmut's copy of
    the tests (``build/mutation/mutants/tests``, named ``_check_*``, removed afterwards) and run there
    with the mutant active, one forked pytest session per mutant.  {name: "killed" | "survived"}."""
    tests = STAGE / "mutants" / "tests"
    if not tests.is_dir():
        raise SystemExit("mutation: no mutants yet (run python benchmarks/mutation.py first)")
    copies = []
    for f in test_files:
        copy = tests / f"_check_{os.getpid()}_{Path(f).name}"
        shutil.copyfile(f, copy)
        copies.append(copy)
    env = {**_test_env(), "WMR_MUTATION_CHECK": "1"}     # (tests/conftest.py collects the copies only then)
    env.pop("MUTANT_UNDER_TEST", None)
    out: dict[str, str] = {}
    try:
        files = [c.relative_to(STAGE / "mutants").as_posix() for c in copies]
        proc = subprocess.run([sys.executable, "-c", _CHECK_DRIVER, json.dumps(names), json.dumps(files),
                               str(limit_s)], cwd=STAGE / "mutants", env=env, capture_output=True, text=True,
                              check=False)
        for line in proc.stdout.splitlines():
            if line.startswith("["):
                name, code = json.loads(line)
                out[name] = "survived" if code == 0 else "killed"
        missing = [n for n in names if n not in out]
        if missing:
            raise SystemExit(f"mutation: the check stopped before {missing[0]} ({proc.stderr.strip()[-500:]})")
    finally:
        for c in copies:
            c.unlink(missing_ok=True)
    return out


def record_kills(killed: list[str]) -> int:
    """Write "killed" into mutmut's results for these mutants (checked by :func:`check` with tests that
    are now in the suite), as mutmut would after testing them; returns how many changed.  Only while no
    mutmut run is going (it writes the same files)."""
    want = set(killed)
    n = 0
    for meta in (STAGE / "mutants").rglob("*.py.meta"):
        data = json.loads(meta.read_text(encoding="utf-8"))
        codes = data.get("exit_code_by_key", {})
        hit = [k for k in codes if k in want and codes[k] not in (1, 3)]
        for k in hit:
            codes[k] = 1
        if hit:
            meta.write_text(json.dumps(data), encoding="utf-8")
            n += len(hit)
    return n


def _equivalents_file(section: str) -> list[dict[str, str]]:
    """The entries of one section of the equivalents file."""
    if not EQUIVALENTS.exists():
        return []
    return tomllib.loads(EQUIVALENTS.read_text(encoding="utf-8")).get(section, [])


def load_equivalents() -> dict[str, dict[str, str]]:
    """{mutant name: {"line": ..., "reason": ...}} from the equivalents file."""
    return {e["mutant"]: e for e in _equivalents_file("equivalent")}


def load_unreachable() -> dict[str, str]:
    """{function (mutmut's name, without the mutant number): reason} of the code no test session of
    mutmut's can run (it runs in a child process started by the code under test)."""
    return {e["function"]: e["reason"] for e in _equivalents_file("unreachable")}


def _module_of(name: str) -> str:
    """The module of a mutant's name (``wmr_cosim.cosim.plan.ssp.x__typed__mutmut_9`` -> ``wmr_cosim.cosim.plan.ssp``)."""
    return name.split(".x_")[0].split(".xǁ")[0]


def _test_env() -> dict[str, str]:
    """The environment of mutmut's test sessions: no bytecode files, the built FMUs kept between sessions
    (tests/conftest.py reads WMR_TEST_FMU_CACHE)."""
    return {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "WMR_TEST_FMU_CACHE": str(STAGE / "fmu-cache")}


def _in_scope(name: str, only: list[str]) -> bool:
    """Whether mutant ``name`` sits in a file matched by one of the ``only`` globs."""
    path = _module_of(name).replace(".", "/") + ".py"
    return any(fnmatch.fnmatch(path, g) for g in only)


def area_of(name: str) -> str:
    for area in ("components", "cosim"):
        if name.startswith(f"wmr_cosim.{area}."):
            return area
    return "analysis"


def summarise(status: dict[str, str], equivalents: dict[str, dict[str, str]], minutes: float,
              unreachable: dict[str, str] | None = None, sample: dict[str, Any] | None = None) -> dict:
    """The figures: counts, kill rate overall and per area, survivors, equivalents (and stale ones),
    and the mutants of code only a child process runs (``unreachable``, when no test reached them);
    with a ``sample`` (default: the one in SAMPLE, if any), the estimate over every mutant."""
    unreachable = load_unreachable() if unreachable is None else unreachable
    sample = load_sample() if sample is None else sample
    out_of_reach = {n for n, st in status.items()
                    if st == "no tests" and n.partition("__mutmut_")[0] in unreachable}
    stale = []
    equivalent = set()
    for name, entry in equivalents.items():
        if name not in status:
            stale.append(name)
            continue
        if status[name] not in ("survived", "no tests"):
            continue  # not run yet, or a test kills it now (the entry is harmless)
        if entry["line"].strip() not in mutant_diff(name):
            stale.append(name)
            continue
        equivalent.add(name)
    counted = {n: s for n, s in status.items()
               if n not in equivalent and n not in out_of_reach and s != "not checked"}
    per_area: dict[str, dict[str, float]] = {}
    for area in ("components", "cosim", "analysis"):
        names = [n for n in counted if area_of(n) == area]
        k = sum(counted[n] in KILLED for n in names)
        per_area[area] = {"mutants": len(names), "killed": k,
                          "kill_rate": round(k / len(names), 4) if names else None}
    killed = sum(s in KILLED for s in counted.values())
    survivors = sorted(n for n, s in counted.items() if s not in KILLED)
    extra = {}
    if sample is not None:
        extra["estimate"] = estimate(status, counted, sample)
        extra["sample"] = {"fraction": sample["fraction"], "seed": sample["seed"], "drawn": len(sample["sample"]),
                           "checked": sum(status.get(n, "not checked") != "not checked" for n in sample["sample"]),
                           "population": sum(len(m) for m in sample["population"].values())}
    return {
        "mutants": len(counted),
        "killed": killed,
        "kill_rate": round(killed / len(counted), 4) if counted else None,
        "per_area": per_area,
        "equivalent": len(equivalent),
        "unreachable": len(out_of_reach),
        "stale_equivalents": sorted(stale),
        "not_checked": sum(s == "not checked" for s in status.values()),
        "statuses": dict(Counter(status.values())),
        "minutes": round(minutes, 1),
        **extra,
        "survivors": survivors,
    }


#: The sample of the mutants not checked when it was drawn (see :func:`draw_sample`).
SAMPLE = STAGE / "sample.json"


def load_sample() -> dict[str, Any] | None:
    """The sample kept in SAMPLE: {"fraction", "seed", "sample": names, "population": {file: names}}."""
    return json.loads(SAMPLE.read_text(encoding="utf-8")) if SAMPLE.exists() else None


def population_of(sample: dict[str, Any]) -> set[str]:
    """Every mutant a sample was drawn from."""
    return {n for names in sample["population"].values() for n in names}

#: Runs mutmut with the tests that cover a mutant ordered fastest first (mutmut hands them over in no
#: particular order and stops at the first failure): a killed mutant costs its cheapest killing test.
_MUTMUT_FASTEST_FIRST = r"""
import sys
from mutmut.runners.harness import PytestRunner
from mutmut.state import state
_args = PytestRunner._pytest_args_regular_run
def _fastest_first(self, tests):
    d = state().duration_by_test
    return _args(self, sorted(tests, key=lambda t: (d.get(t, 0.0), t)))
PytestRunner._pytest_args_regular_run = _fastest_first
from mutmut.__main__ import cli
sys.exit(cli())
"""

#: Makes (or brings up to date) mutmut's mutants without running anything, so that a sample can be drawn.
_MUTMUT_GENERATE = r"""
from mutmut.__main__ import copy_also_copy_files, copy_src_dir, create_mutants, setup_source_paths
copy_src_dir()
copy_also_copy_files()
setup_source_paths()
create_mutants(2)
"""


def generate_mutants() -> None:
    """mutmut's mutated copies and result files, made or brought up to date (changed functions' results
    reset) as ``mutmut run`` would before testing."""
    proc = subprocess.run([sys.executable, "-c", _MUTMUT_GENERATE], cwd=STAGE, env=_test_env(),
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"mutation: making the mutants failed: {proc.stderr.strip().splitlines()[-1:]}")


def draw_sample(status: dict[str, str], fraction: float, seed: int) -> list[str]:
    """A sample of the mutants not checked yet, stratified by file: ceil(fraction x n) of each file's n,
    drawn with ``seed``; kept in SAMPLE with the population it was drawn from (the names, per file), so
    that an interrupted run goes on with the same sample and :func:`estimate` can weigh it.  A sample
    already drawn with the same fraction and seed is kept; another fraction or seed draws a new one."""
    old = load_sample()
    if old is not None and old["fraction"] == fraction and old["seed"] == seed:
        return old["sample"]
    by_file: dict[str, list[str]] = {}
    for name, st in sorted(status.items()):
        if st == "not checked":
            by_file.setdefault(_module_of(name), []).append(name)
    rng = random.Random(seed)
    drawn = [n for members in by_file.values()
             for n in rng.sample(members, min(len(members), math.ceil(fraction * len(members))))]
    SAMPLE.write_text(json.dumps({"fraction": fraction, "seed": seed, "sample": sorted(drawn),
                                  "population": by_file}), encoding="utf-8")
    return sorted(drawn)


def wilson_low(k: int, n: int, z: float = 1.96) -> float:
    """The lower end of the Wilson score interval (95 % with z = 1.96) of a proportion k / n: unlike the
    normal approximation it does not shrink to nothing when no sampled mutant survived."""
    p = k / n
    return (p + z * z / (2 * n) - z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))) / (1 + z * z / n)


def estimate(status: dict[str, str], counted: dict[str, str], sample: dict[str, Any]) -> dict[str, Any]:
    """The kill rate per area over every mutant, from the census (the mutants checked before the sample
    was drawn, and any file whose whole population has been checked since) and the sample (each file's
    checked sample members standing for the rest of that file's population):
    {"components": {"mutants": estimated count, "killed": estimated, "kill_rate", "low95"}, ...}.
    ``counted``: {name: status} of the mutants that count (equivalents and unreachable ones left out);
    ``low95``: the kill rate with the sampled part at the lower end of the 95 % Wilson interval of the
    area's sample (pooled: every file is sampled at the same fraction)."""
    members = set(sample["sample"])
    in_population = population_of(sample)
    out: dict[str, Any] = {}
    for area in ("components", "cosim", "analysis"):
        census = [s for n, s in counted.items() if area_of(n) == area and n not in in_population]
        est_n = float(len(census))
        est_k = low_k = float(sum(s in KILLED for s in census))
        share_all = k_all = n_all = 0.0
        for f, names in sample["population"].items():
            if area_of(f) != area:
                continue
            names = [n for n in names if n in status]     # (a mutant gone with changed code is no longer one)
            if all(status[n] != "not checked" for n in names):   # checked whole
                whole = [counted[n] for n in names if n in counted]
                est_n += len(whole)
                est_k += sum(s in KILLED for s in whole)
                low_k += sum(s in KILLED for s in whole)
                continue
            drawn = [n for n in names if n in members and status[n] != "not checked"]
            kept = [counted[n] for n in drawn if n in counted]     # (equivalent ones stand for theirs)
            if not kept:
                continue
            k = sum(s in KILLED for s in kept)
            share = len(names) * len(kept) / len(drawn)            # the population's mutants that count
            est_n += share
            est_k += share * k / len(kept)
            share_all, k_all, n_all = share_all + share, k_all + k, n_all + len(kept)
        if n_all:
            low_k += share_all * wilson_low(int(k_all), int(n_all))
        out[area] = {"mutants": round(est_n), "killed": round(est_k),
                     "kill_rate": round(est_k / est_n, 4) if est_n else None,
                     "low95": round(low_k / est_n, 4) if est_n else None}
    return out


def _regenerate_newly_in_scope(only: list[str]) -> None:
    """A file copied unmutated by an earlier run with a narrower ``--only`` has no mutants: mutmut sees
    its copy as current, so the copy is removed and mutmut makes the file's mutants."""
    for src in (STAGE / "wmr_cosim").rglob("*.py"):
        rel = src.relative_to(STAGE).as_posix()
        copy = STAGE / "mutants" / rel
        if any(fnmatch.fnmatch(rel, g) for g in only) and copy.exists() and not Path(f"{copy}.meta").exists():
            copy.unlink()


def forget_survivors() -> int:
    """Mark every mutant that survived (or had no test) as unchecked, so that mutmut tests it again
    against today's tests (mutmut keeps a result until the function's code changes)."""
    n = 0
    for meta in (STAGE / "mutants").rglob("*.py.meta"):
        data = json.loads(meta.read_text(encoding="utf-8"))
        codes = data.get("exit_code_by_key", {})
        for name, code in codes.items():
            if code in (0, 5, 33):
                codes[name] = None
                n += 1
        meta.write_text(json.dumps(data), encoding="utf-8")
    return n


def run(only: list[str] | None = None, fresh: bool = False, max_children: int | None = None,
        retest: bool = True, sample: float | None = None, seed: int = 1, complete: list[str] | None = None) -> dict:
    """Stage, run mutmut, summarise.  ``only``: globs on the staged paths (default: every area).
    ``sample``: test only that fraction of the mutants not checked yet (see :func:`draw_sample`);
    ``complete``: globs of files whose every unchecked mutant is tested, keeping a sample drawn before."""
    only = only or list(AREAS.values())
    if fresh and (STAGE / "mutants").exists():
        shutil.rmtree(STAGE / "mutants")
    if fresh or (sample is None and not complete):   # (a run of every mutant leaves nothing to estimate)
        SAMPLE.unlink(missing_ok=True)
    stage(only)
    _regenerate_newly_in_scope(only)
    names: list[str] = []
    if sample is not None or complete:
        generate_mutants()
        before = {n: st for n, st in results().items() if _in_scope(n, only)}
        drawn = draw_sample(before, sample, seed) if sample is not None else []
        whole = [n for n, st in before.items() if st == "not checked" and _in_scope(n, complete or [])]
        kept = load_sample()
        if kept is not None:   # mutants made since the draw (code changed or added) are measured, not sampled
            population = population_of(kept)
            whole += [n for n, st in before.items() if st == "not checked" and n not in population]
        listed = load_equivalents()   # (a survivor listed as equivalent would only survive again)
        again = [n for n, st in before.items() if st in ("survived", "no tests") and n not in listed] if retest else []
        names = sorted({n for n in drawn if before.get(n) == "not checked"} | set(whole) | set(again))
        if not names:
            return summarise(results(), load_equivalents(), 0.0)
    elif retest:
        forget_survivors()
    env = _test_env()
    cmd = [sys.executable, "-c", _MUTMUT_FASTEST_FIRST, "run", "--max-children", str(max_children or os.cpu_count() or 2),
           *names]
    log = STAGE / "mutmut.log"
    t0 = time.monotonic()
    with open(log, "w", encoding="utf-8") as out:
        proc = subprocess.run(cmd, cwd=STAGE, env=env, stdout=out, stderr=subprocess.STDOUT, check=False)
    minutes = (time.monotonic() - t0) / 60
    status = results()
    unchecked = [n for n, st in status.items() if st == "not checked" and _in_scope(n, only)
                 and (not names or n in names)]
    if proc.returncode != 0 and (unchecked or not status):
        # (a process that hosted pythonfmu FMUs may abort while the interpreter tears down, after every
        # result was saved: only a run that left mutants unchecked failed)
        tail = log.read_text(encoding="utf-8", errors="replace")
        print("\n".join(tail.replace("\r", "\n").splitlines()[-15:]), file=sys.stderr)
        raise SystemExit(f"mutation: mutmut exited with {proc.returncode}, {len(unchecked)} mutants unchecked "
                         f"(log: {log})")
    return summarise(status, load_equivalents(), minutes)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", action="append", help="mutate only these staged paths (glob, repeatable), "
                    "e.g. 'wmr_cosim/cosim/plan/wiring.py'")
    ap.add_argument("--fresh", action="store_true", help="forget mutmut's earlier results")
    ap.add_argument("--keep-survivors", action="store_true",
                    help="do not test again the mutants that survived the last run")
    ap.add_argument("--max-children", type=int, default=None)
    ap.add_argument("--sample", type=float, metavar="FRACTION", help="test only this fraction of the mutants "
                    "not checked yet (drawn per file, kept for the next run) and estimate the kill rate over all")
    ap.add_argument("--seed", type=int, default=1, help="with --sample: the seed of the draw")
    ap.add_argument("--complete", action="append", metavar="GLOB", help="test every unchecked mutant of these "
                    "staged files, keeping the sample drawn before (their figures are then measured, not estimated)")
    ap.add_argument("--summary-only", action="store_true", help="summarise the last run without running")
    ap.add_argument("--diffs", metavar="FILE", help="with --summary-only: write the diff of every survivor "
                    "(of the --only files) to FILE")
    ap.add_argument("--check", nargs="+", metavar="MUTANT", help="run only --tests against these mutants "
                    "(names as in the survivors list) and print which the tests kill")
    ap.add_argument("--tests", nargs="+", type=Path, default=[], help="test files for --check")
    ap.add_argument("--record", action="store_true", help="with --check: write the kills into mutmut's "
                    "results (only for tests that are in the suite, and while no mutmut run is going)")
    args = ap.parse_args(argv)
    if args.check:
        verdicts = check(args.check, args.tests)
        if args.record:
            record_kills([n for n, v in verdicts.items() if v == "killed"])
        print(json.dumps({"killed": sorted(n for n, v in verdicts.items() if v == "killed"),
                          "survived": sorted(n for n, v in verdicts.items() if v == "survived")}))
        return 0
    if args.summary_only:
        figures = summarise(results(), load_equivalents(), 0.0)
        if args.diffs:
            chosen = [n for n in figures["survivors"] if _in_scope(n, args.only or list(AREAS.values()))]
            Path(args.diffs).write_text(survivor_diffs(chosen), encoding="utf-8")
    else:
        if args.sample is not None and not 0.0 < args.sample <= 1.0:
            raise SystemExit(f"mutation: --sample {args.sample}: a fraction in (0, 1]")
        figures = run(args.only, args.fresh, args.max_children, retest=not args.keep_survivors,
                      sample=args.sample, seed=args.seed, complete=args.complete)
    print(json.dumps({"bench": "mutation", **figures}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
