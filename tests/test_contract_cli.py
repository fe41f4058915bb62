"""The contract harness in CI: every target of tests/contract_targets.py (scenario, requirement, sweep and
falsification documents and command lines, valid and broken, drawn from their schemas; the readers of
untrusted bytes) under the ``contract-ci`` profile: a bounded number of examples each, derandomised (the
same examples every run), each example held to the contract (tests/contract_support.py).  A failure prints
the minimal example Hypothesis found and every rule it breaks.  ``python benchmarks/bench.py contract``
runs the same targets with many more examples (docs/contributing.md, docs/benchmarks.md)."""
from __future__ import annotations

import pytest
from hypothesis import given, settings

from contract_support import fail_on
from contract_targets import TARGETS, Scratch, check


@pytest.mark.parametrize("name", list(TARGETS))
def test_every_generated_input_keeps_the_contract(name):
    target = TARGETS[name]
    with Scratch() as base:
        @settings(settings.get_profile("contract-ci"), max_examples=target.ci_examples)
        @given(target.strategy())
        def holds(case):
            fail_on(check(case, base, target.timeout))

        holds()


#: The targets a few examples of which CI also runs in child processes (a crash of the interpreter, a
#: hang in C code: what the in-process run cannot survive or interrupt).
IN_CHILD = {"scenario-run-broken": 2, "model-description": 2, "elf-in-archive": 2}


@pytest.mark.parametrize("name", list(IN_CHILD))
def test_a_sample_keeps_the_contract_in_a_child_process(name):
    from contract_support import fresh, run_child, violations, write_files
    import shutil

    target = TARGETS[name]
    with Scratch() as base:
        @settings(settings.get_profile("contract-ci"), max_examples=IN_CHILD[name])
        @given(target.strategy())
        def holds(case):
            work = fresh(base)
            try:
                write_files(work, case.files)
                o = run_child(case.argv, work, timeout=60.0)
                fail_on(violations(o, case.expect, work, case.files))
            finally:
                shutil.rmtree(work, ignore_errors=True)

        holds()
