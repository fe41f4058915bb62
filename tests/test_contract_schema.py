"""The contract harness's schemas against the code, and the harness against planted bugs.

tests/contract_schema.py reads the keys of every table from the code's own key tables and writes down
once what the code does not declare (the kind of each key's value): a key added to the code without its
kind here fails the first test (docs/contributing.md says how to add it).  The other tests plant one
defect of each kind the contract rules out and check that the harness reports it, so that a harness
that stopped looking would be noticed."""
from __future__ import annotations

import os
import sys
import tempfile
import time

import pytest

import contract_schema as schema
from contract_support import Expectation, check_case, violations, run_cli
from reference_fmus import fmi2


def test_every_key_of_the_code_has_its_kind_written_in_the_harness():
    code = schema.code_key_tables()
    assert set(code) == set(schema.VALUE_KINDS)
    for table, keys in code.items():
        written = set(schema.VALUE_KINDS[table])
        assert keys - written == set(), f"{table}: keys of the code without their kind in contract_schema.py"
        assert written - keys == set(), f"{table}: keys in contract_schema.py that the code no longer has"


def test_the_formula_grammar_is_the_parsers():
    from wmr_cosim.cosim.requirements import formula

    g = schema.grammar()
    assert set(g.unary_temporal) | set(g.binary_temporal) | set(g.logic) | set(g.functions) | {"not"} \
        <= formula.KEYWORDS
    assert set(g.compare) == set(formula.COMPARE)
    for op in g.unary_temporal:   # each keyword parses where the harness puts it
        formula.parse(f"{op}[0, 1] (a.x > 0)")


def test_the_commands_and_options_come_from_the_parser():
    commands = schema.commands()
    assert {"check", "run", "linearize", "sweep", "falsify", "plot", "info"} <= set(commands)
    run = {o.flag: o for o in commands["run"].options}
    assert run["--stop"].kind == "float" and run["--workers"].kind == "int" and run["--set"].repeatable
    assert {o.kind for c in commands.values() for o in c.options} <= {"flag", "float", "int", "path", "str",
                                                                      "float+", "str+", "int+", "path+"}


def test_the_models_variables_are_read_from_their_model_descriptions():
    m = schema.models()
    assert m["Dahlquist"].outputs == {"x": "Real"} and m["Dahlquist"].parameters == {"k": "Real"}
    assert "e" in m["BouncingBall"].tunable


# --- the harness finds planted bugs ---------------------------------------------------------------------
def _scenario() -> dict[str, bytes]:
    return {"s.toml": f'[experiment]\nstop = 0.02\nstep = 0.01\n[instances.d]\nfmu = "{fmi2("Dahlquist")}"\n'.encode()}


@pytest.fixture
def base():
    with tempfile.TemporaryDirectory() as d:
        yield __import__("pathlib").Path(d)


def _keys(found):
    return [v.key for v in found]


def test_a_healthy_check_and_run_keep_the_contract(base):
    assert check_case(_scenario(), ["check", "s.toml"], None, base) == []
    assert check_case(_scenario(), ["run", "s.toml", "--out", "o", "--quiet"], None, base) == []


def test_planted_exception_is_found(base, monkeypatch):
    from wmr_cosim.cosim.scenario import document

    def broken(*a, **k):
        raise KeyError("planted")
    monkeypatch.setattr(document, "merge", broken)
    doc = _scenario()
    doc["b.toml"] = doc["s.toml"]
    doc["s.toml"] = b'base = "b.toml"\n'
    assert any("KeyError out of the command" in k for k in _keys(check_case(doc, ["check", "s.toml"], None, base)))


def test_planted_second_line_and_traceback_text_are_found(base, monkeypatch):
    from wmr_cosim import cli

    def two_lines(exc):
        return f"{exc}\nTraceback (most recent call last): planted"
    monkeypatch.setattr(cli, "error_message", two_lines)
    doc = {"s.toml": b"stuff = 1\n"}
    keys = _keys(check_case(doc, ["check", "s.toml"], None, base))
    assert any("several lines" in k for k in keys) and any("traceback printed" in k for k in keys)


def test_planted_leftover_in_tmpdir_is_found(base, monkeypatch):
    from wmr_cosim.cosim.scenario import document

    real = document.read_document

    def leaves(*a, **k):
        tempfile.mkstemp(prefix="planted-")
        return real(*a, **k)
    monkeypatch.setattr(document, "read_document", leaves)
    assert any("left in TMPDIR" in k for k in _keys(check_case(_scenario(), ["check", "s.toml"], None, base)))


def test_planted_success_claim_of_a_failed_run_is_found(base, monkeypatch):
    from wmr_cosim import cli

    real = cli.cmd_run
    monkeypatch.setattr(cli, "cmd_run", lambda args: real(args) or 1)
    keys = _keys(check_case(_scenario(), ["run", "s.toml", "--out", "o", "--quiet"], None, base))
    assert any("claims success with exit 1" in k for k in keys)


def test_planted_hang_is_found(base, monkeypatch):
    from wmr_cosim import cli

    def hangs(args):
        while True:
            time.sleep(0.01)
    monkeypatch.setattr(cli, "cmd_check", hangs)
    t0 = time.perf_counter()
    keys = _keys(check_case(_scenario(), ["check", "s.toml"], None, base, timeout=0.5))
    assert any("no answer within the time limit" in k for k in keys) and time.perf_counter() - t0 < 5


def test_planted_acceptance_of_an_unknown_key_is_found(base, monkeypatch):
    from wmr_cosim.cosim.scenario import document

    monkeypatch.setattr(document, "_keys", lambda *a, **k: None)
    doc = _scenario()
    doc["s.toml"] += b"[record]\nvariabels = [\"d.x\"]\n"
    expect = Expectation(True, ("variabels",), "the misspelt key 'variabels'")
    keys = _keys(check_case(doc, ["check", "s.toml"], expect, base))
    assert any("not refused" in k for k in keys), keys


def test_planted_sweep_that_runs_before_refusing_is_found(base, monkeypatch):
    from wmr_cosim.studies import sweep_file

    monkeypatch.setattr(sweep_file, "_read", lambda path: __import__("tomllib").loads(path.read_text()))
    doc = _scenario()
    doc["sw.toml"] = b'base = "s.toml"\ngridd = {"d.k" = [1.0]}\n'
    expect = Expectation(True, ("gridd",), "the misspelt key 'gridd'")
    keys = _keys(check_case(doc, ["sweep", "sw.toml", "--quiet"], expect, base))
    assert any("not refused" in k for k in keys), keys


def test_planted_reader_crash_is_found(monkeypatch):
    from contract_readers import ReaderCase, reader_violations
    from wmr_cosim.cosim.model import binary

    monkeypatch.setattr(binary, "_elf_exports", lambda data, wanted: data[10 ** 9])
    seed = __import__("contract_readers").elf_seed()
    found = reader_violations(ReaderCase("elf", seed, "planted"), 5.0)
    assert [v.key for v in found] == ["elf reader: IndexError at binary.py:<lambda>"] or \
        any("IndexError" in v.key for v in found)


def test_planted_refusal_at_run_of_what_check_accepted_is_found(base, monkeypatch):
    from wmr_cosim import cli
    from wmr_cosim.cosim import ScenarioError

    def refuses(args):
        raise ScenarioError("s.toml", "experiment.step", "planted: found only when running")
    monkeypatch.setattr(cli, "cmd_run", refuses)
    keys = _keys(check_case(_scenario(), ["check", "s.toml"], None, base,
                            then=["run", "s.toml", "--out", "o", "--quiet"]))
    assert keys == ["run: refuses as bad input what check accepted"]


def test_planted_deep_recursion_is_found_under_the_commands_own_limit(base, monkeypatch):
    """Hypothesis raises the recursion limit while a test runs: the harness runs the command under the
    limit it has in its own process, so that a RecursionError a user meets is met here too."""
    from wmr_cosim import cli

    def deep(n: int) -> int:
        return 0 if n == 0 else deep(n - 1) + 1
    monkeypatch.setattr(cli, "cmd_check", lambda args: deep(1200))
    old = sys.getrecursionlimit()
    sys.setrecursionlimit(old + 5000)   # as Hypothesis does
    try:
        keys = _keys(check_case(_scenario(), ["check", "s.toml"], None, base))
    finally:
        sys.setrecursionlimit(old)
    assert any("RecursionError out of the command" in k for k in keys), keys
