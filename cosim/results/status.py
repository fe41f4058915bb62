"""How a run ended: a closed set of statuses (what a command exits with for each is the application's)."""
from __future__ import annotations

from enum import StrEnum


class RunStatus(StrEnum):
    """How a run ended.  A str (``RunStatus.OK == "ok"``), so it is written to JSON and compared as its value.

    - ``OK``: every step was taken;
    - ``TERMINATED``: an FMU ended the simulation itself (Discard with fmi2Terminated / fmi3 terminateSimulation);
    - ``STOPPED``: a stop event, or the script, ended it early;
    - ``VIOLATED``: a requirement with ``on_violation = "stop"`` was violated: the run ended when that was
      known (the recording up to it is kept);
    - ``FAILED``: an FMU returned a non-OK status, a value became non-finite, or the master raised;
    - ``INTERRUPTED``: the user pressed Ctrl-C;
    - ``DIVERGED``: the run ended ok but an application's check of its results rejected it (the paper's
      controller: its tracking error far above the paper's, as ``wmr_cosim.paper.analysis.divergence`` judges).
    """

    OK = "ok"
    TERMINATED = "terminated"
    STOPPED = "stopped"
    VIOLATED = "violated"
    FAILED = "failed"
    INTERRUPTED = "interrupted"
    DIVERGED = "diverged"

    @property
    def ended_well(self) -> bool:
        """Whether the run gave its results as asked (ok, or ended early by an FMU, a stop, or a requirement
        that stops it)."""
        return self in (RunStatus.OK, RunStatus.TERMINATED, RunStatus.STOPPED, RunStatus.VIOLATED)

    @property
    def measured(self) -> bool:
        """Whether a study measures the run as its scenario ran it: to the stop time, or to the point where a
        requirement that stops it was violated (the verdict is what the study asks).  Any other end makes
        the study's point failed (diverged, when the application's judge rejected it)."""
        return self in (RunStatus.OK, RunStatus.VIOLATED)

    @property
    def reached_stop(self) -> bool:
        """Whether every step was taken: ok, or diverged (it ran to its end, and the application's check of
        its results rejected it)."""
        return self in (RunStatus.OK, RunStatus.DIVERGED)
