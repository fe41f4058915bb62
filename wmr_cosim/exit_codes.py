"""The exit codes of the ``wmr-cosim`` command line: 0 success; 1 the run failed or diverged; 2 bad input
(a parameter, a file, an option); 3 a requirement was violated (the run stopped by one with
``on_violation = "stop"``, status "violated", or one recorded as violated); 130 interrupted (Ctrl-C).  The master (``wmr_cosim.cosim``) knows none of
them: the command decides here what each run status and each error exits with."""
from __future__ import annotations

from collections.abc import Iterable

from .cosim import RunError, RunStatus

OK = 0
RUN_FAILED = 1
BAD_INPUT = 2
REQUIREMENT_VIOLATED = 3
INTERRUPTED = 130


def for_status(status: str) -> int:
    """The exit code of a command whose run ended with ``status`` (a :class:`RunStatus` or its value): 0 for
    ok, terminated and stopped; 3 for violated; 130 for interrupted; 1 for failed and diverged."""
    s = RunStatus(status)
    if s is RunStatus.VIOLATED:
        return REQUIREMENT_VIOLATED
    if s.ended_well:
        return OK
    return INTERRUPTED if s is RunStatus.INTERRUPTED else RUN_FAILED


def for_runs(statuses: Iterable[str], requirements: Iterable[dict]) -> int:
    """The exit code of a command of runs that ended with ``statuses`` and gave these requirement verdicts
    (summary.json's ``requirements``): :func:`for_statuses`, but 3 where every run ended well and a
    requirement was violated."""
    code = for_statuses(statuses)
    if code == OK and any(r.get("verdict") == "violated" for r in requirements):
        return REQUIREMENT_VIOLATED
    return code


def for_statuses(statuses: Iterable[str]) -> int:
    """The exit code of a command of several runs (a protocol): the worst of theirs (0 for none)."""
    return max((for_status(s) for s in statuses), default=OK)


def for_error(exc: BaseException) -> int:
    """The exit code of a command stopped by ``exc``: 130 for Ctrl-C, 1 for a run that failed
    (:class:`~wmr_cosim.cosim.messages.errors.RunError`), 2 for anything else it reports as bad input (a scenario,
    an FMU, a results folder, a parameter, an option)."""
    if isinstance(exc, KeyboardInterrupt):
        return INTERRUPTED
    if isinstance(exc, RunError):
        return RUN_FAILED
    return BAD_INPUT
