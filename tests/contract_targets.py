"""The targets of the contract harness (not a test module): each a strategy of cases and how many examples
CI tries of it.  tests/test_contract_cli.py runs each under the ``ci`` profile (bounded, derandomised);
``python benchmarks/bench.py contract`` runs them under the ``long`` profile.  A new command or document
kind gets its target here (docs/contributing.md).
"""
from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

import contract_readers as cr
import contract_strategies as cs
from contract_support import Violation, check_case


@dataclass(frozen=True)
class Target:
    strategy: Callable[[], st.SearchStrategy[cs.Case]]
    ci_examples: int     # examples CI tries (the ci profile)
    timeout: float = 30.0


TARGETS: dict[str, Target] = {
    "scenario-check": Target(lambda: cs.scenario_cases(False, "check"), 15),
    "scenario-check-broken": Target(lambda: cs.scenario_cases(True, "check"), 60),
    "scenario-run": Target(lambda: cs.scenario_cases(False, "run"), 10),
    "scenario-run-broken": Target(lambda: cs.scenario_cases(True, "run"), 15),
    # every instance in a child process of its own (about 1 s of set-up a run)
    "scenario-run-isolated": Target(lambda: cs.scenario_cases(False, "run", requirements=True).map(cs.isolated), 3),
    "requirements-check-broken": Target(lambda: cs.requirement_cases("check"), 30),
    "requirements-run": Target(lambda: cs.scenario_cases(False, "run", requirements=True), 10),
    "requirements-run-broken": Target(lambda: cs.requirement_cases("run"), 10),
    "check-then-run": Target(cs.check_then_run_cases, 15),
    "conditions-check-broken": Target(lambda: cs.condition_cases("check"), 20),
    "conditions-run-broken": Target(lambda: cs.condition_cases("run"), 5),
    "clocks-check-broken": Target(lambda: cs.clock_cases("check"), 15),
    "clocks-run": Target(lambda: cs.clock_cases("run"), 4),
    "export-ssp": Target(lambda: cs.scenario_cases(False, "export-ssp"), 5),
    "export-ssp-broken": Target(lambda: cs.scenario_cases(True, "export-ssp"), 10),
    "export-fmu": Target(lambda: cs.scenario_cases(False, "export-fmu"), 5, timeout=60.0),
    "export-fmu-broken": Target(lambda: cs.scenario_cases(True, "export-fmu"), 10, timeout=60.0),
    "cli-check": Target(lambda: cs.command_line_cases("check", True), 25),
    "cli-run": Target(lambda: cs.command_line_cases("run", True), 10),
    "cli-run-live-broken": Target(cs.live_option_cases, 10),
    "view-broken": Target(cs.view_cases, 10),
    "cli-linearize": Target(lambda: cs.linearize_cases(False), 5, timeout=60.0),
    "cli-linearize-broken": Target(lambda: cs.linearize_cases(True), 10, timeout=60.0),
    "sweep-broken": Target(lambda: cs.sweep_cases(True), 30),
    "sweep": Target(lambda: cs.sweep_cases(False), 5),
    "falsify-broken": Target(lambda: cs.falsify_cases(True), 25),
    "falsify": Target(lambda: cs.falsify_cases(False), 5),
    # the readers of untrusted bytes: through the command line ...
    "fmu-archive": Target(cr.archive_cases, 25, timeout=20.0),
    "model-description": Target(cr.model_description_cases, 40, timeout=20.0),
    "elf-in-archive": Target(cr.binary_in_archive_cases, 15, timeout=20.0),
    "results-plot": Target(cr.results_cases, 10, timeout=30.0),
    "ssp-archive": Target(cr.ssp_cases, 15, timeout=20.0),
    "inputs-csv": Target(cr.inputs_cases, 20, timeout=20.0),
    # ... and called directly (many more examples a second)
    "elf": Target(lambda: cr.reader_cases("elf"), 150, timeout=5.0),
    "pe": Target(lambda: cr.reader_cases("pe"), 150, timeout=5.0),
}

#: The profiles: ``ci`` (each target's ci_examples, the same examples every time; no shrinking, which runs
#: a failing target's command hundreds of times more: the bench shrinks), ``long`` (the bench's).
settings.register_profile("contract-ci", derandomize=True, deadline=None, database=None, print_blob=False,
                          suppress_health_check=list(HealthCheck),
                          phases=[Phase.explicit, Phase.reuse, Phase.generate])
settings.register_profile("contract-long", deadline=None, database=None, print_blob=False,
                          suppress_health_check=list(HealthCheck))


def check(case: cs.Case | cr.ReaderCase, base: Path, timeout: float) -> list[Violation]:
    """The contract's violations on one case: a command line run in a fresh folder under ``base``, or
    bytes given to a reader."""
    if isinstance(case, cr.ReaderCase):
        return cr.reader_violations(case, timeout)
    return check_case(case.files, case.argv, case.expect, base, timeout, case.then)


class Scratch:
    """A folder for the examples' working folders (under the session's TMPDIR), removed at the end."""

    def __enter__(self) -> Path:
        self.path = Path(tempfile.mkdtemp(prefix="contract-"))
        return self.path

    def __exit__(self, *exc: object) -> None:
        shutil.rmtree(self.path, ignore_errors=True)
