"""The contract every input of wmr-cosim honours, as one check (not a test module): run a command line in
this process with its output captured, its own working and temporary folders and a time limit, and list
how the outcome breaks the contract (docs/contributing.md):

- the exit code is 0 (ok), 1 (the run failed), 2 (bad input) or 3 (a requirement was violated);
- no traceback anywhere, no exception out of the command;
- exit code 2: exactly one line on stderr (argparse's refusal of an option too);
- nothing left in the temporary folder (TMPDIR);
- no results folder whose summary.json says the run ended well when the exit code is not 0 or 3;
- bounded time (a per-example limit) and bounded memory;
- where the input is known to be bad (an unknown key, a non-finite number, bytes that are not UTF-8):
  refused with exit code 2, before anything runs (a sweep or falsification reaching its Dask cluster has
  run: the harness stops it there, :class:`WouldRun`).

:func:`run_cli` returns an :class:`Outcome`; :func:`violations` the list of :class:`Violation`, each with a
``key`` that names the defect (the same defect met by two inputs has one key), so a long run counts
distinct defects.
"""
from __future__ import annotations

import contextlib
import io
import os
import re
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator

#: Exit codes of the contract (wmr_cosim/exit_codes.py).
EXIT_CODES = {0, 1, 2, 3}
#: The largest growth of the process's peak memory one example may cause [MiB].
MEMORY_LIMIT_MIB = 1024


class WouldRun(Exception):
    """Raised where a sweep or falsification would start its Dask cluster: the input was accepted."""


class Hang(BaseException):
    """Raised by the time limit's alarm (a BaseException: no ``except Exception`` of the code swallows it)."""


@dataclass
class Expectation:
    """What a generated input must get beyond the contract: ``refused`` (exit code 2, before running), and
    ``words`` the one line must hold (the key or option it names)."""

    refused: bool = False
    words: tuple[str, ...] = ()
    why: str = ""        # what is wrong, in general (it names the defect: the same for every such input)
    this: str = ""       # what is wrong with this input


@dataclass
class Outcome:
    argv: list[str]
    code: int | None                 # None: an exception left the command, or it would run (would_run)
    stdout: str
    stderr: str
    seconds: float
    error: str | None = None         # the exception's traceback, when one left the command
    error_type: str | None = None
    where: str | None = None         # the innermost frame of the project's code it was raised in
    argparse: bool = False           # argparse refused the command line (SystemExit 2 with its usage)
    would_run: bool = False
    hang: bool = False
    left_in_tmp: list[str] = field(default_factory=list)
    claims: list[str] = field(default_factory=list)   # summary.json files saying the run ended well
    memory_mib: float = 0.0


@dataclass(frozen=True)
class Violation:
    key: str        # names the defect: the command, the broken rule and where (stable across inputs)
    detail: str     # this input's own evidence


def _project_frame(tb: Any) -> str | None:
    """'module.py:function' of the innermost frame of the project's code in a traceback."""
    where = None
    for frame in traceback.extract_tb(tb):
        f = frame.filename
        if ("wmr_cosim" in f or "/cosim/" in f or "/components/" in f) and "/tests/" not in f:
            where = f"{Path(f).name}:{frame.name}"
    return where


@contextlib.contextmanager
def _alarm(seconds: float) -> Iterator[None]:
    def ring(signum: int, frame: Any) -> None:
        raise Hang()

    old = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def _no_cluster() -> Iterator[None]:
    """Sweeps and falsifications stop where they would start their Dask cluster (WouldRun)."""
    from wmr_cosim.studies import cluster

    def refuse(self: Any, *args: Any, **kwargs: Any) -> None:
        raise WouldRun()

    old = cluster.Cluster.__init__
    cluster.Cluster.__init__ = refuse   # type: ignore[method-assign]
    try:
        yield
    finally:
        cluster.Cluster.__init__ = old   # type: ignore[method-assign]


@contextlib.contextmanager
def sandbox(work: Path) -> Iterator[Path]:
    """``work`` as the working folder, with a temporary folder of its own (TMPDIR, tempfile's) inside it;
    restores both after."""
    tmp = work / ".tmp"
    tmp.mkdir(parents=True, exist_ok=True)
    old_cwd, old_env, old_tempdir = os.getcwd(), os.environ.get("TMPDIR"), tempfile.tempdir
    os.chdir(work)
    os.environ["TMPDIR"], tempfile.tempdir = str(tmp), str(tmp)
    try:
        yield tmp
    finally:
        os.chdir(old_cwd)
        tempfile.tempdir = old_tempdir
        if old_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = old_env


#: The frames a ``wmr-cosim`` process has below ``main`` (``python -m wmr_cosim.cli``: runpy, entry).
_CLI_FRAMES = 8
#: Python's default recursion limit, the one the command runs with.
_DEFAULT_RECURSION_LIMIT = 1000


def _depth() -> int:
    f, n = sys._getframe(), 0
    while f is not None:
        f, n = f.f_back, n + 1
    return n


@contextlib.contextmanager
def _command_recursion_limit() -> Iterator[None]:
    """The recursion limit the command has in its own process, counted from here: Hypothesis raises the
    limit while a test runs, which would hide a RecursionError the user meets."""
    old = sys.getrecursionlimit()
    sys.setrecursionlimit(_depth() + _DEFAULT_RECURSION_LIMIT - _CLI_FRAMES)
    try:
        yield
    finally:
        sys.setrecursionlimit(old)


def call(fn: Callable[[], Any], timeout: float) -> tuple[Any, Outcome]:
    """Run ``fn()`` (a reader, a command) under the time limit and the command's own recursion limit, with
    output captured: (its value or None, the outcome with any exception that left it)."""
    out, err = io.StringIO(), io.StringIO()
    o = Outcome([], None, "", "", 0.0)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    value = None
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _alarm(timeout), \
                _command_recursion_limit():
            value = fn()
    except Hang:
        o.hang = True
    except BaseException as exc:   # noqa: BLE001 (what left is the finding)
        o.error, o.error_type = "".join(traceback.format_exception(exc)), type(exc).__name__
        o.where = _project_frame(exc.__traceback__)
    o.seconds = time.perf_counter() - t0
    o.memory_mib = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    o.stdout, o.stderr = out.getvalue(), err.getvalue()
    return value, o


def run_cli(argv: list[str], work: Path, timeout: float = 30.0) -> Outcome:
    """``wmr-cosim ARGV`` in this process, in the folder ``work`` (with its own TMPDIR), output captured,
    stopped after ``timeout`` seconds; what is left in TMPDIR and which results folders claim success."""
    from wmr_cosim.cli import main

    o = Outcome(list(argv), None, "", "", 0.0)

    def go() -> int:
        try:
            return main(list(argv))
        except SystemExit as exc:
            o.argparse = True
            return exc.code if isinstance(exc.code, int) else 2

    with sandbox(work) as tmp, _no_cluster():
        code, r = call(go, timeout)
        o.left_in_tmp = sorted(p.name for p in tmp.iterdir())
        shutil.rmtree(tmp, ignore_errors=True)
    o.code = code
    o.stdout, o.stderr, o.seconds, o.hang, o.memory_mib = r.stdout, r.stderr, r.seconds, r.hang, r.memory_mib
    o.error, o.error_type, o.where = r.error, r.error_type, r.where
    if r.error_type == "WouldRun":
        o.would_run, o.error, o.error_type, o.where = True, None, None, None
    return o


def run_child(argv: list[str], work: Path, timeout: float = 60.0) -> Outcome:
    """``wmr-cosim ARGV`` in a child process (``python -m wmr_cosim.cli``), in ``work`` with its own TMPDIR,
    killed after ``timeout`` seconds: what the in-process run cannot see (a crash of the interpreter, a
    hang in C code, output written at exit)."""
    import subprocess

    tmp = work / ".tmp"
    tmp.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "TMPDIR": str(tmp)}
    o = Outcome(list(argv), None, "", "", 0.0)
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", *argv], cwd=work, env=env, capture_output=True,
                           text=True, errors="replace", timeout=timeout)
        o.code, o.stdout, o.stderr = p.returncode, p.stdout, p.stderr
        lines = p.stderr.strip().splitlines()
        o.argparse = p.returncode == 2 and bool(lines) and lines[-1].endswith("-h lists the options)")
    except subprocess.TimeoutExpired:
        o.hang = True
    o.seconds = time.perf_counter() - t0
    o.left_in_tmp = sorted(q.name for q in tmp.iterdir())
    shutil.rmtree(tmp, ignore_errors=True)
    return o


def summaries_claiming_success(work: Path, given: dict[str, bytes] | None = None) -> list[str]:
    """summary.json files under ``work`` whose status says the run ended well (those of ``given``, the
    input files, left out while unchanged: a results folder given to ``plot`` is not a claim of its)."""
    import json

    from wmr_cosim.cosim import RunStatus

    out = []
    for s in _new_summaries(work, given):
        try:
            doc = json.loads(s.read_text(encoding="utf-8"))
            status = RunStatus(doc.get("status"))
        except (ValueError, OSError, AttributeError):
            continue
        if status.ended_well:
            out.append(str(s.relative_to(work)))
    return out


def _new_summaries(work: Path, given: dict[str, bytes] | None) -> list[Path]:
    """summary.json files under ``work`` the command wrote (not among ``given``, or changed)."""
    return [s for s in work.rglob("summary.json")
            if not (given and s.relative_to(work).as_posix() in given
                    and s.read_bytes() == given[s.relative_to(work).as_posix()])]


def command_of(argv: list[str]) -> str:
    return next((a for a in argv if not a.startswith("-")), "?")


def _norm(text: str) -> str:
    """A message with its numbers, quoted names and paths blanked: a defect's key, not this input's."""
    text = re.sub(r"'[^']*'|\"[^\"]*\"|\S*/\S*", "_", text)
    return re.sub(r"[-+]?\d[\d.e+-]*", "N", text)[:80]


def violations(o: Outcome, expect: Expectation | None = None, work: Path | None = None,
               given: dict[str, bytes] | None = None) -> list[Violation]:
    """How the outcome breaks the contract (empty: it holds)."""
    cmd = command_of(o.argv)
    v: list[Violation] = []
    shown = f"argv {o.argv}: exit {o.code}, stderr {o.stderr[-600:]!r}"
    if o.hang:
        v.append(Violation(f"{cmd}: no answer within the time limit", f"{shown} after {o.seconds:.1f} s"))
    if o.error is not None:
        v.append(Violation(f"{cmd}: {o.error_type} out of the command at {o.where}", f"{shown}\n{o.error[-3000:]}"))
    if o.code is not None and o.code not in EXIT_CODES:
        v.append(Violation(f"{cmd}: exit code {o.code}", shown))
    if "Traceback" in o.stdout + o.stderr:
        v.append(Violation(f"{cmd}: a traceback printed", shown))
    if o.code == 2:
        lines = o.stderr.strip().splitlines()
        if len(lines) != 1:
            v.append(Violation(f"{cmd}: exit code 2 with {'no' if not lines else 'several'} lines on stderr "
                               f"({_norm(lines[0]) if lines else ''})", shown))
    if o.left_in_tmp:
        v.append(Violation(f"{cmd}: left in TMPDIR", f"{shown}: {o.left_in_tmp[:5]}"))
    if work is not None and o.code not in (0, 3):
        claims = summaries_claiming_success(work, given)
        if claims and o.code == 1 and len(claims) < len(_new_summaries(work, given)):
            claims = []   # a protocol: the runs before the one that failed ended well, and say so
        if claims:
            v.append(Violation(f"{cmd}: a results folder claims success with exit {o.code}", f"{shown}: {claims}"))
    if o.memory_mib > MEMORY_LIMIT_MIB:
        v.append(Violation(f"{cmd}: memory grew by more than {MEMORY_LIMIT_MIB} MiB", f"{shown}: {o.memory_mib:.0f} MiB"))
    if expect is not None and expect.refused and not o.hang and o.error is None:
        if o.would_run or o.code != 2:
            what = "ran" if o.would_run or o.code in (0, 1, 3) else f"exit {o.code}"
            v.append(Violation(f"{cmd}: {expect.why} not refused ({what})", f"{expect.this or expect.why}: {shown}"))
        else:
            line = o.stderr.strip().splitlines()[-1] if o.stderr.strip() else ""
            missing = [w for w in expect.words if w not in line]
            if missing:
                v.append(Violation(f"{cmd}: {expect.why}: the line does not name it",
                                   f"{expect.this or expect.why}: {missing[0]!r} not in {shown}"))
    return v


def write_files(work: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        p = work / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)


def fresh(base: Path) -> Path:
    """A new empty working folder under ``base``."""
    return Path(tempfile.mkdtemp(prefix="ex-", dir=base))


def check_case(files: dict[str, bytes], argv: list[str], expect: Expectation | None, base: Path,
               timeout: float = 30.0, then: list[str] | None = None) -> list[Violation]:
    """Write ``files`` into a fresh folder under ``base``, run ``argv`` there, and list the violations;
    the folder is removed after.  ``then``: a second command run after a first that exited 0 (``check``
    then ``run``): it must not refuse as bad input what the first accepted (refuse early, at ``check``)."""
    work = fresh(base)
    try:
        write_files(work, files)
        o = run_cli(argv, work, timeout)
        found = violations(o, expect, work, files)
        if then and o.code == 0 and not found:
            o2 = run_cli(then, work, timeout)
            found = violations(o2, None, work, files)
            if o2.code == 2:
                found.append(Violation(f"{command_of(then)}: refuses as bad input what {command_of(argv)} accepted",
                                       f"{argv} exit 0, then {then}: {o2.stderr.strip()[-600:]!r}"))
        return found
    finally:
        shutil.rmtree(work, ignore_errors=True)


def fail_on(found: list[Violation]) -> None:
    """An AssertionError listing the violations (the property tests' failure)."""
    if found:
        raise AssertionError("the contract is broken:\n" + "\n".join(f"- {x.key}\n  {x.detail}" for x in found))
