"""The long run of the contract harness (``python benchmarks/bench.py contract``): every target of
tests/contract_targets.py under the ``contract-long`` profile (random, not derandomised: each run draws
new examples) for a share of a time budget, in chunks of examples.  A chunk stops at the first example
that breaks the contract in a way not seen before (a new defect: the violation's key); Hypothesis then
shrinks it to a minimal example (at most ``shrink_s`` seconds), which is printed with its evidence, and
the target goes on with the defects found so far known, until its share of the budget is spent.

Figures: examples (per target and in all: examples generated and checked, shrinking's re-runs apart),
shrink_runs, defects (distinct keys, per target and in all), seconds.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parents[1]


def _found_type(key: str, cache: dict[str, type] = {}) -> type:
    """An exception class of its own per defect, so that Hypothesis shrinks each as a distinct bug."""
    if key not in cache:
        cache[key] = type(f"Defect{len(cache)}", (Exception,), {})
    return cache[key]


def _leaves(exc: BaseException) -> list[BaseException]:
    """The exceptions an exception stands for: itself, or every leaf of a (nested) ExceptionGroup."""
    if isinstance(exc, BaseExceptionGroup):
        return [leaf for e in exc.exceptions for leaf in _leaves(e)]
    return [exc]


def _short(detail: str) -> str:
    """The evidence's first line and, for a traceback, its last frames."""
    first, _, rest = detail.partition("\n")
    return first[:800] + ("\n  ..." + rest[-1200:] if rest else "")


def run(budget_s: float = 600.0, targets: list[str] | None = None, shrink_s: float = 20.0,
        chunk: int = 50, say: Any = print) -> dict[str, Any]:
    sys.path.insert(0, str(HERE / "tests"))
    from hypothesis import given, settings
    from hypothesis.errors import Flaky
    from hypothesis.internal.conjecture import engine

    from contract_targets import TARGETS, Scratch, check

    engine.MAX_SHRINKING_SECONDS = int(shrink_s)   # Hypothesis's own bound on shrinking (300 s by default)
    names = targets or list(TARGETS)
    unknown = sorted(set(names) - set(TARGETS))
    if unknown:
        raise SystemExit(f"bench.py contract: unknown target {unknown[0]!r} (targets: {', '.join(TARGETS)})")
    share = budget_s / len(names)
    t_start = time.perf_counter()
    examples: dict[str, int] = {}
    shrink_runs = 0
    defects: dict[str, dict[str, str]] = {}
    with Scratch() as base:
        for name in names:
            target = TARGETS[name]
            examples[name] = 0
            t_end = time.perf_counter() + share
            while time.perf_counter() < t_end:
                state = {"shrinking": False}

                @settings(settings.get_profile("contract-long"), max_examples=chunk)
                @given(target.strategy())
                def holds(case: Any) -> None:
                    nonlocal shrink_runs
                    if state["shrinking"]:
                        shrink_runs += 1
                    else:
                        examples[name] += 1
                    for v in check(case, base, target.timeout):
                        if v.key not in defects:
                            state["shrinking"] = True
                            raise _found_type(v.key)(v.key, v.detail, repr(case))

                try:
                    holds()
                except Flaky:
                    continue
                except Exception as exc:   # one defect, or several (ExceptionGroups, nested)
                    for e in _leaves(exc):
                        if not (e.__class__.__name__.startswith("Defect") and len(e.args) == 3):
                            raise
                        key, detail, minimal = e.args
                        if key in defects:
                            continue
                        defects[key] = {"target": name, "example": minimal, "detail": detail}
                        say(f"defect {len(defects)} [{name}]: {key}\n  minimal example: {minimal[:3000]}\n"
                            f"  evidence: {_short(detail)}\n", flush=True)
            say(f"# {name}: {examples[name]} examples, "
                f"{sum(1 for d in defects.values() if d['target'] == name)} defects", file=sys.stderr, flush=True)
    by_target = {n: sum(1 for d in defects.values() if d["target"] == n) for n in names}
    return {"examples": examples, "examples_total": sum(examples.values()), "shrink_runs": shrink_runs,
            "defects": len(defects), "defects_by_target": by_target, "defect_keys": sorted(defects),
            "seconds": round(time.perf_counter() - t_start, 1)}
