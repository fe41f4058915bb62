"""Hypothesis strategies of the contract harness (not a test module): scenario, requirement, sweep and
falsification documents and command lines, built from their schemas (tests/contract_schema.py), valid and
broken.

Each strategy gives a :class:`Case`: the files to write into a fresh folder, the command line, and what
the contract expects beyond its general rules (:class:`contract_support.Expectation`: an input known to be
bad must be refused, naming the key).  A valid document is drawn first (every key of every table a
candidate, its value by the key's kind); a broken one is that document with one mutation: a key misspelt,
a value of the wrong type, out of range, not finite, a huge or empty string, deep nesting, a key dropped,
bytes that are not UTF-8, the file cut short.
"""
from __future__ import annotations

import functools

import json
import math
from dataclasses import dataclass, field
from typing import Any

from hypothesis import strategies as st

import contract_schema as schema
from contract_support import Expectation

# --- TOML -----------------------------------------------------------------------------------------------


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):   # JSON's escapes are TOML's; TOML forbids DEL too
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, Raw):
        return v.text
    raise TypeError(type(v))


def _key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "_-" for c in k) and k.isascii() else json.dumps(k, ensure_ascii=False)


@dataclass(frozen=True)
class Raw:
    """TOML text placed as it is (deep nesting that no Python value of reasonable depth writes)."""

    text: str


def dumps(doc: dict[str, Any]) -> str:
    """A TOML document: every top-level key as ``key = value`` (inline tables and arrays)."""
    return "".join(f"{_key(k)} = {_value(v)}\n" for k, v in doc.items())


# --- cases ----------------------------------------------------------------------------------------------
@dataclass
class Case:
    target: str
    argv: list[str]
    files: dict[str, bytes] = field(default_factory=dict)
    expect: Expectation | None = None
    mutation: str = "valid"
    then: list[str] | None = None     # run after argv when it exited 0 (check, then run)

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:   # how Hypothesis prints an example: short
        p.text(repr(self))

    def __repr__(self) -> str:   # what Hypothesis prints of a falsifying example
        shown = {k: (v.decode("utf-8", "replace")[:3000] if len(v) < 20000 else f"<{len(v)} bytes>")
                 for k, v in self.files.items()}
        then = f", then={self.then!r}" if self.then else ""
        return f"Case({self.target!r}, mutation={self.mutation!r}, argv={self.argv!r}{then}, files={shown!r})"


# --- values by kind -------------------------------------------------------------------------------------
IDENT = st.from_regex(r"[a-z][a-z0-9_]{0,7}", fullmatch=True)
TEXT = st.text(max_size=20)
ANY_VALUE = st.recursive(st.none().map(lambda _: "x") | st.booleans() | st.integers(-10, 10)
                         | st.floats(allow_nan=False, allow_infinity=False, width=32) | TEXT,
                         lambda inner: st.lists(inner, max_size=3) | st.dictionaries(IDENT, inner, max_size=3),
                         max_leaves=6)


@dataclass
class System:
    """The instances of a drawn system and their variables ("inst.var" -> type)."""

    instances: dict[str, str]               # instance -> model
    parameters: dict[str, str]
    inputs: dict[str, str]
    outputs: dict[str, str]
    step: float
    stop: float

    def real(self, which: dict[str, str]) -> list[str]:
        return sorted(k for k, t in which.items() if t == "Real")


def value_of(draw: Any, kind: Any, sysm: System) -> Any:
    """A valid value of ``kind`` (contract_schema's kinds) in the system ``sysm``."""
    if isinstance(kind, tuple) and kind[0] == "enum":
        return draw(st.sampled_from(list(kind[1])))
    if isinstance(kind, tuple) and kind[0] == "subset":
        return draw(st.lists(st.sampled_from(list(kind[1])), unique=True))
    outs = sysm.real(sysm.outputs) or ["x.y"]
    return {
        "time": lambda: draw(st.sampled_from([0.0, sysm.step, sysm.stop / 2])),
        "time+": lambda: draw(st.sampled_from([sysm.step, 2 * sysm.step, sysm.stop])),
        "num": lambda: draw(st.floats(-10, 10, allow_nan=False)),
        "num+": lambda: draw(st.sampled_from([1e-6, 0.5, 1.0, 10.0])),
        "count": lambda: draw(st.integers(1, 1000)),
        "int": lambda: draw(st.integers(0, 1000)),
        "bool": lambda: draw(st.booleans()),
        "str": lambda: draw(TEXT),
        "ident": lambda: draw(IDENT),
        "ref": lambda: draw(st.sampled_from(outs)),
        "refs": lambda: draw(st.lists(st.sampled_from(outs), min_size=1, max_size=3, unique=True)),
        "formula": lambda: draw(formulas(sysm)),
        "table": lambda: {},
    }.get(kind, lambda: draw(ANY_VALUE))()


# --- formulas -------------------------------------------------------------------------------------------
G = schema.grammar()


@st.composite
def _atom(draw: Any, sysm: System) -> str:
    outs = sysm.real(sysm.outputs)
    bools = sorted(k for k, t in sysm.outputs.items() if t == "Boolean")
    choices = ["cmp", "const", "time"] + (["bool"] if bools else [])
    kind = draw(st.sampled_from(choices)) if outs else "const"
    if kind == "const":
        return draw(st.sampled_from(["true", "false"]))
    if kind == "bool":
        return draw(st.sampled_from(bools))
    if kind == "time":
        return f"t {draw(st.sampled_from(G.compare))} {draw(st.sampled_from([0, sysm.step, sysm.stop]))}"
    lhs = draw(st.sampled_from(outs))
    lhs = draw(st.sampled_from([lhs, f"abs({lhs})", f"{lhs} + 1", f"2 * {lhs}", f"-{lhs}",
                                f"sqrt({lhs} * {lhs})", f"({lhs} - 1)"]))
    return f"{lhs} {draw(st.sampled_from(G.compare))} {draw(st.floats(-5, 5, allow_nan=False)):.6g}"


def _bound(draw: Any, sysm: System) -> str:
    """[a, b]: whole multiples of the step, 0 <= a <= b."""
    i = draw(st.integers(0, 1))
    j = i + draw(st.integers(0, 3))
    return f"[{i * sysm.step:g}, {j * sysm.step:g}]"


@st.composite
def _formula(draw: Any, sysm: System, depth: int) -> str:
    if depth <= 0 or draw(st.integers(0, 3)) == 0:
        return draw(_atom(sysm))
    op = draw(st.sampled_from(["not", "logic", "unary", "binary", "paren"]))
    sub = _formula(sysm, depth - 1)
    if op == "not":
        return f"not {draw(sub)}"
    if op == "logic":
        return f"{draw(sub)} {draw(st.sampled_from(G.logic))} {draw(sub)}"
    if op == "unary":
        name = draw(st.sampled_from(G.unary_temporal))
        return f"{name}{_bound(draw, sysm)} ({draw(sub)})"
    if op == "binary":
        name = draw(st.sampled_from(G.binary_temporal))
        return f"({draw(sub)}) {name}{_bound(draw, sysm)} ({draw(sub)})"
    return f"({draw(sub)})"


@st.composite
def formulas(draw: Any, sysm: System) -> str:
    """A formula of the grammar over the system's outputs (the outermost ``always`` may be unbounded)."""
    f = draw(_formula(sysm, 3))
    return draw(st.sampled_from([f, f"always ({f})"]))


@st.composite
def broken_formulas(draw: Any, sysm: System) -> tuple[str, str]:
    """(a formula that is wrong or at the grammar's limits, what was done)."""
    f = draw(formulas(sysm))
    outs = sysm.real(sysm.outputs) or ["x.y"]
    words = f.split()
    how = draw(st.sampled_from(["typo", "unbalanced", "deep_not", "deep_parens", "long_or", "long_sum",
                                "unknown_variable", "bad_unit", "bad_bound", "too_long", "empty", "garbage"]))
    if how == "typo" and words:
        i = draw(st.integers(0, len(words) - 1))
        words[i] = draw(typos(words[i])) if words[i].isalpha() else words[i] + "x"
        return " ".join(words), how
    if how == "unbalanced":
        return f + draw(st.sampled_from([")", "(", "[", "]"])), how
    if how == "deep_not":
        return "not " * draw(st.integers(50, 3000)) + f, how
    if how == "deep_parens":
        n = draw(st.integers(50, 1900))
        return "(" * n + f + ")" * n, how
    if how == "long_or":   # as many operators as the length allows: the shortest operands
        op = draw(st.sampled_from(list(G.logic)))
        atom = draw(st.sampled_from(["true", f"{outs[0]} > 0"]))
        n = draw(st.integers(10, G.max_length // (len(atom) + len(op) + 2) + 1))
        return f" {op} ".join([atom] * n)[:G.max_length], how
    if how == "long_sum":
        op = draw(st.sampled_from(["+", "-", "*", "/"]))
        n = draw(st.integers(10, G.max_length // 2))
        return ("1" + op * 0 + "".join(f"{op}1" for _ in range(n)))[:G.max_length - 4] + " > 0", how
    if how == "unknown_variable":
        return f.replace(outs[0], outs[0] + "_nope") if outs[0] in f else f"{outs[0]}_nope > 0", how
    if how == "bad_unit":
        return f"{outs[0]} > 5 {draw(st.sampled_from(['furlong', 'kg', 's2', 'm/', 'N.m^']))}", how
    if how == "bad_bound":
        a, b = draw(st.sampled_from([(1, 0), (-1, 1), (0, 1e300), (0, float('inf')), (0, float('nan'))]))
        return f"eventually[{a}, {b}] ({outs[0]} > 0)", how
    if how == "too_long":
        return (f"{outs[0]} > 0 and " * 400)[:G.max_length + draw(st.integers(1, 100))] + "true", how
    if how == "empty":
        return draw(st.sampled_from(["", " ", "()", "always", "and"])), how
    return draw(st.text(max_size=60)), "garbage"


CG = schema.condition_grammar()


@st.composite
def conditions(draw: Any, sysm: System, depth: int = 2) -> str:
    """An event's condition of the grammar over the system's outputs."""
    outs = sysm.real(sysm.outputs)
    if depth <= 0 or draw(st.integers(0, 2)) == 0:
        lhs = draw(st.sampled_from(outs + ["t"] if outs else ["t"]))
        return f"{lhs} {draw(st.sampled_from(CG.compare))} {draw(st.floats(-2, 2, allow_nan=False)):.4g}"
    sub = conditions(sysm, depth - 1)
    how = draw(st.sampled_from(["and", "or", "not", "paren"]))
    if how == "not":
        return f"not {draw(sub)}"
    if how == "paren":
        return f"({draw(sub)})"
    return f"{draw(sub)} {how} {draw(sub)}"


@st.composite
def broken_conditions(draw: Any, sysm: System) -> tuple[str, str]:
    c = draw(conditions(sysm))
    outs = sysm.real(sysm.outputs) or ["x.y"]
    how = draw(st.sampled_from(["deep_not", "deep_parens", "long_or", "too_long", "unknown", "typo", "garbage",
                                "type", "empty"]))
    if how == "deep_not":
        return "not " * draw(st.integers(CG.max_depth - 2, 3 * CG.max_depth)) + c, how
    if how == "deep_parens":
        n = draw(st.integers(CG.max_depth - 2, 900))
        return "(" * n + c + ")" * n, how
    if how == "long_or":
        return " or ".join([f"{outs[0]} > 0"] * draw(st.integers(2, 400)))[:CG.max_length], how
    if how == "too_long":
        return (f"{outs[0]} > 0 or " * 300)[:CG.max_length + 5] + "true", how
    if how == "unknown":
        return f"{outs[0]}_nope > 1", how
    if how == "typo":
        return c.replace(" and ", " adn ").replace(" or ", " ro ") if (" and " in c or " or " in c) else c + " an", how
    if how == "type":
        return draw(st.sampled_from([f"{outs[0]}", f"{outs[0]} == true", "1", "t", f"{outs[0]} > true"])), how
    if how == "empty":
        return draw(st.sampled_from(["", " ", "()", "not", "and"])), how
    return draw(st.text(max_size=40)), "garbage"


def typos(word: str) -> st.SearchStrategy[str]:
    """Misspellings of ``word``: a letter dropped, doubled, changed or two swapped."""
    @st.composite
    def one(draw: Any) -> str:
        if len(word) < 2:
            return word + "x"
        i = draw(st.integers(0, len(word) - 2))
        how = draw(st.sampled_from(["drop", "double", "swap", "change"]))
        if how == "drop":
            return word[:i] + word[i + 1:]
        if how == "double":
            return word[:i] + word[i] + word[i:]
        if how == "swap":
            return word[:i] + word[i + 1] + word[i] + word[i + 2:]
        return word[:i] + draw(st.sampled_from("abcdefghijklmnopqrstuvwxyz_")) + word[i + 1:]
    return one()


# --- systems and scenario documents ---------------------------------------------------------------------
@st.composite
def systems(draw: Any) -> System:
    models = schema.models()
    n = draw(st.integers(1, 3))
    names = draw(st.lists(IDENT.filter(lambda s: s not in ("t",)), min_size=n, max_size=n, unique=True))
    instances = {name: draw(st.sampled_from(schema.MODELS)) for name in names}
    par, inp, out = {}, {}, {}
    for name, m in instances.items():
        md = models[m]
        par.update({f"{name}.{k}": t for k, t in md.parameters.items()})
        inp.update({f"{name}.{k}": t for k, t in md.inputs.items()})
        out.update({f"{name}.{k}": t for k, t in md.outputs.items()})
    step = draw(st.sampled_from([0.01, 0.05, 0.1]))
    return System(instances, par, inp, out, step, step * draw(st.integers(1, 5)))


def _optional(draw: Any, table: str, have: dict[str, Any], sysm: System, skip: tuple[str, ...] = ()) -> None:
    """Every other key of ``table`` the code declares, each drawn or not, with a value of its kind."""
    for k, kind in schema.keys(table).items():
        if k in have or k in skip or kind == "table":
            continue
        if draw(st.integers(0, 5)) == 0:
            have[k] = value_of(draw, kind, sysm)


@st.composite
def scenario_docs(draw: Any, sysm: System, requirements: bool = False) -> dict[str, Any]:
    """A scenario document of the system: instances (parameters), connections of Real outputs to Real
    inputs, the experiment, record, events, requirements, runs and variants, each key drawn from its table."""
    models = schema.models()
    doc: dict[str, Any] = {}
    exp: dict[str, Any] = {"stop": sysm.stop, "step": sysm.step}
    _optional(draw, "experiment", exp, sysm, skip=("order", "max_steps", "max_internal_steps", "algorithm", "start",
                                                   "workers"))
    if draw(st.booleans()):
        exp["algorithm"] = draw(st.sampled_from(["gauss-seidel", "jacobi"] + list(schema.keys("experiment")["algorithm"][1])))
    if exp.get("algorithm", "gauss-seidel") in ("gauss-seidel", "jacobi") and draw(st.integers(0, 5)) == 0:
        exp["workers"] = draw(st.integers(1, 4))   # (instances stepped at once: these two algorithms only)
    doc["experiment"] = exp
    doc["instances"] = {}
    for name, m in sysm.instances.items():
        inst: dict[str, Any] = {"fmu": models[m].path}
        reals = [p for p, t in models[m].parameters.items() if t == "Real"]
        chosen = draw(st.lists(st.sampled_from(reals), unique=True, max_size=2)) if reals else []
        if chosen:
            inst["parameters"] = {p: draw(_in_range(models[m], p)) for p in chosen}
        _optional(draw, "instance", inst, sysm, skip=("fmu", "isolate", "step_timeout", "names", "units", "interface",
                                                         "step", "solver", "max_step", "event_tolerance"))
        doc["instances"][name] = inst
    ins, outs = sysm.real(sysm.inputs), sysm.real(sysm.outputs)
    if ins and outs:
        targets = draw(st.lists(st.sampled_from(ins), unique=True, max_size=2))
        conns = []
        for to in targets:
            c: dict[str, Any] = {"from": draw(st.sampled_from(outs)), "to": to}
            _optional(draw, "connection", c, sysm, skip=("convert", "threshold"))
            conns.append(c)
        if conns:
            doc["connections"] = conns
    if draw(st.booleans()) and outs:
        rec: dict[str, Any] = {"variables": draw(st.lists(st.sampled_from(outs), min_size=1, max_size=3, unique=True))}
        # (event_rows: a lone model-exchange instance's only, which these systems of co-simulation are not)
        _optional(draw, "record", rec, sysm, skip=("max_bytes", "decimation", "event_rows"))
        doc["record"] = rec
    recorded = doc.get("record", {}).get("variables") or outs
    if draw(st.integers(0, 5)) == 0 and len(recorded) >= 2:   # the live view's path: two recorded outputs
        doc["live"] = {"xy": draw(st.lists(st.sampled_from(recorded), min_size=2, max_size=2, unique=True))}
    tunable = sorted(f"{i}.{p}" for i, m in sysm.instances.items() for p in models[m].tunable)
    if draw(st.integers(0, 3)) == 0 and tunable and sysm.stop > sysm.step:
        ref = draw(st.sampled_from(tunable))
        inst, par = ref.split(".", 1)
        ev: dict[str, Any] = {"variable": ref, "action": "set", "value": draw(_in_range(models[sysm.instances[inst]], par))}
        if draw(st.booleans()):
            ev["time"] = sysm.step
        else:
            ev["when"] = draw(conditions(sysm))
            ev["trigger"] = draw(st.sampled_from(schema.keys("event")["trigger"][1]))
        doc["events"] = [ev]
    elif draw(st.integers(0, 5)) == 0 and sysm.stop > sysm.step:
        doc["events"] = [{"when": draw(conditions(sysm)), "action": "stop"}]
    if requirements or draw(st.integers(0, 2)) == 0:
        names = draw(st.lists(IDENT, min_size=1, max_size=2, unique=True))
        reqs = []
        for n in names:
            r: dict[str, Any] = {"name": n, "formula": draw(formulas(sysm))}
            _optional(draw, "requirement", r, sysm, skip=("name", "formula", "runs"))
            reqs.append(r)
        doc["requirements"] = reqs
    if draw(st.integers(0, 4)) == 0:
        params = sorted(k for k, t in sysm.parameters.items() if t == "Real")
        if params:
            p = draw(st.sampled_from(params))
            inst, par = p.split(".", 1)
            value = _in_range(models[sysm.instances[inst]], par)
            doc["runs"] = [{"name": "first"}, {"name": "second", "parameters": {p: draw(value)}}]
            doc["variants"] = {"v": {"parameters": {p: draw(value)}}}
    if draw(st.integers(0, 5)) == 0:
        doc["description"] = draw(TEXT)
    return doc


def _in_range(model: schema.Model, name: str) -> st.SearchStrategy[float]:
    """A value within the parameter's declared range (about its start value)."""
    lo, hi = model.ranges.get(name, (None, None))
    start = float(model.starts.get(name) or 1.0)
    lo = start * 0.5 if lo is None else max(lo, min(start * 0.5, start * 1.5))
    hi = start * 1.5 if hi is None else min(hi, max(start * 0.5, start * 1.5))
    lo, hi = min(lo, hi), max(lo, hi)
    return st.floats(lo, hi, allow_nan=False) if lo < hi else st.just(lo)


# --- mutations ------------------------------------------------------------------------------------------
#: Which closed table of the schema a path of a scenario document is ((): the top-level table).
def table_of(path: tuple[Any, ...], kind: str = "scenario") -> str | None:
    if kind == "sweep":
        return {0: "sweep"}.get(len(path)) if not path else ("metric" if len(path) == 2 and path[0] == "metric" else None)
    if kind == "falsify":
        return "falsify" if not path else None
    pats = {(): "top", ("experiment",): "experiment", ("instances", "*"): "instance",
            ("connections", "#"): "connection", ("record",): "record", ("events", "#"): "event",
            ("requirements", "#"): "requirement", ("runs", "#"): "run", ("variants", "*"): "variant",
            ("inputs",): "inputs", ("experiment", "iteration"): "iteration", ("experiment", "adaptive"): "adaptive",
            ("live",): "live"}
    for pat, name in pats.items():
        if len(pat) == len(path) and all(p == q or (p == "*" and isinstance(q, str)) or (p == "#" and isinstance(q, int))
                                          for p, q in zip(pat, path)):
            return name
    return None


def _nodes(doc: Any, path: tuple[Any, ...] = ()) -> list[tuple[tuple[Any, ...], Any]]:
    out = [(path, doc)]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _nodes(v, path + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _nodes(v, path + (i,))
    return out


def _set(doc: Any, path: tuple[Any, ...], value: Any) -> None:
    for p in path[:-1]:
        doc = doc[p]
    doc[path[-1]] = value


def _kind_at(path: tuple[Any, ...], kind: str) -> Any:
    """The schema's kind of the value at ``path`` (None: not a key of a closed table)."""
    if not path or not isinstance(path[-1], str):
        return None
    table = table_of(path[:-1], kind)
    return schema.keys(table).get(path[-1]) if table else None


NUMERIC = ("time", "time+", "num", "num+", "count", "int")
MUTATIONS = ("typo_key", "wrong_type", "drop_key", "out_of_range", "not_finite", "huge_string", "empty_string",
             "deep_nesting", "not_utf8", "truncated")


@st.composite
def mutated(draw: Any, doc: dict[str, Any], kind: str = "scenario") -> tuple[bytes, str, Expectation | None]:
    """(the TOML bytes of ``doc`` with one mutation, its name, the expectation it makes known)."""
    import copy

    doc = copy.deepcopy(doc)
    how = draw(st.sampled_from(MUTATIONS))
    nodes = _nodes(doc)
    expect: Expectation | None = None
    if how == "typo_key":
        tables = [(p, n) for p, n in nodes if isinstance(n, dict) and table_of(p, kind) and n]
        path, node = draw(st.sampled_from(tables))
        table = table_of(path, kind)
        allowed = set(schema.keys(table)) | ({"grid", "random", "samples", "tasks"} if table == "top" else set())
        key = draw(st.sampled_from(sorted(node)))
        typo = draw(typos(key).filter(lambda s: s not in allowed and s != key and s))
        node[typo] = node.pop(key)
        expect = Expectation(True, (typo,), f"a misspelt key of {table}", f"the misspelt key {typo!r} of "
                                                                         f"{'.'.join(map(str, path)) or 'the top'}")
    elif how in ("wrong_type", "out_of_range", "not_finite", "huge_string", "empty_string", "deep_nesting"):
        leaves = [(p, n) for p, n in nodes if p]
        if how in ("out_of_range", "not_finite"):
            leaves = [(p, n) for p, n in leaves if isinstance(n, (int, float)) and not isinstance(n, bool)] or leaves
        path, node = draw(st.sampled_from(leaves))
        if how == "wrong_type":
            new = draw(st.sampled_from(["text", 3, 2.5, True, [1, "a"], {"a": 1}, []]).filter(
                lambda x: type(x) is not type(node)))
        elif how == "out_of_range":
            new = draw(st.sampled_from([-1, 0, -1e-300, 1e308, -1e308, 2 ** 63 - 1, -(2 ** 63), 1e-320]))
        elif how == "not_finite":
            new = draw(st.sampled_from([math.nan, math.inf, -math.inf]))
            k = _kind_at(path, kind)
            if k in NUMERIC:
                expect = Expectation(True, (str(path[-1]),), f"a non-finite {table_of(path[:-1], kind)}.{path[-1]}",
                                     f"{'.'.join(map(str, path))} = {new}")
        elif how == "huge_string":
            new = draw(st.sampled_from(["x" * 200_000, "é" * 50_000, "\u202e" * 1000, "a\x00b" * 10]))
        elif how == "empty_string":
            new = ""
        else:
            depth = draw(st.integers(50, 3000))
            new = Raw("[" * depth + "]" * depth)
        _set(doc, path, new)
    elif how == "drop_key":
        keyed = [(p, n) for p, n in nodes if p and isinstance(p[-1], str)]
        if keyed:
            path, _ = draw(st.sampled_from(keyed))
            parent = doc
            for p in path[:-1]:
                parent = parent[p]
            del parent[path[-1]]
    text = dumps(doc).encode("utf-8")
    if how == "not_utf8":
        i = draw(st.integers(0, len(text)))
        text = text[:i] + draw(st.sampled_from([b"\xff", b"\xc3\x28", b"\xed\xa0\x80", b"\x80\x80"])) + text[i:]
        expect = Expectation(True, (), "a file that is not UTF-8")
    elif how == "truncated":
        text = text[:draw(st.integers(0, max(0, len(text) - 1)))]
    return text, how, expect


# --- the targets' cases ---------------------------------------------------------------------------------
def _base_argv(draw: Any, command: str, file: str) -> list[str]:
    argv = [command, file]
    if command == "run":
        argv += ["--out", "out", "--quiet"]
    elif command == "export-ssp":
        argv += ["--out", "s.ssp"]
    elif command == "export-fmu":
        argv += ["--out", "s.fmu"]
    return argv


@st.composite
def scenario_cases(draw: Any, broken: bool, command: str = "check", requirements: bool = False) -> Case:
    """A scenario (with requirements, where asked) checked or run; broken: one mutation of it."""
    sysm = draw(systems())
    doc = draw(scenario_docs(sysm, requirements))
    if broken:
        text, how, expect = draw(mutated(doc))
    else:
        text, how, expect = dumps(doc).encode(), "valid", None
    return Case(f"{'requirements' if requirements else 'scenario'}-{command}", _base_argv(draw, command, "s.toml"),
                {"s.toml": text}, expect, how)


def isolated(case: Case) -> Case:
    """The case run with every instance in a child process (``--isolate``)."""
    case.argv, case.target = case.argv + ["--isolate"], case.target + "-isolated"
    return case


@st.composite
def requirement_cases(draw: Any, command: str = "check") -> Case:
    """A scenario whose one requirement has a broken formula, or a name at the edges (``time``, a column)."""
    sysm = draw(systems())
    doc = draw(scenario_docs(sysm, requirements=True))
    req = doc["requirements"][0]
    what = draw(st.sampled_from(["formula", "name"]))
    if what == "formula":
        req["formula"], how = draw(broken_formulas(sysm))
    else:
        req["name"] = draw(st.sampled_from(["time", "t", "", "a b", "x" * 300, "é", "always", "status",
                                            sorted(sysm.outputs)[0] if sysm.outputs else "q"]))
        how = f"requirement name {req['name'][:20]!r}"
    return Case(f"requirements-{command}", _base_argv(draw, command, "s.toml"), {"s.toml": dumps(doc).encode()},
                None, how)


#: Bad settings of a system with clocks (two Tickers: tests/c_fmu_support.py): what each changes of
#: ticker_scenario and the field its one-line refusal names.
CLOCK_BAD: dict[str, tuple[dict[str, str], str]] = {
    "a clock interval the step cannot meet": ({"step": "0.0003"}, "experiment.step"),
    "a tick off the grid": ({"a": "clock_ticks = { s = [0.00025] }"}, "instances.A.clock_ticks.s"),
    "a triggered clock with no source": ({"a": ""}, "instances.A.clock_ticks"),
    "ticks for a periodic clock": ({"a": "clock_ticks = { s = [0.001], r = [0.002] }"}, "instances.A.clock_ticks.r"),
    "an output clock connected to a variable": ({"extra": '[[connections]]\nfrom = "A.o"\nto = "B.u"\n'},
                                                "connections[2]"),
    "a variable connected to an input clock": ({"extra": '[[connections]]\nfrom = "A.n"\nto = "A.s"\n'},
                                               "connections[2]"),
    "an output clock connected to a periodic clock": ({"extra": '[[connections]]\nfrom = "A.o"\nto = "B.r"\n'},
                                                      "connections[2].to"),
    "an input clock as a source": ({"extra": '[[connections]]\nfrom = "A.s"\nto = "B.r"\n'},
                                   "connections[2].from"),
    "a clock connection against the order": ({"order": 'order = ["B", "A"]'}, "experiment.order"),
    "an event on a clocked input": ({"extra": '[[events]]\ntime = 0.001\nvariable = "A.u"\naction = "override"\n'
                                              "value = 1.0\n"}, "events[0].variable"),
    "another algorithm": ({"order": 'algorithm = "jacobi"'}, "experiment.algorithm"),
    "workers": ({"order": "workers = 2"}, "experiment.workers"),
    "isolation": ({"a": "clock_ticks = { s = [0.001] }\nisolate = true"}, "instances.A.isolate"),
    "its own step": ({"a": "clock_ticks = { s = [0.001] }\nstep = 0.001"}, "instances.A.step"),
}


@functools.cache
def _ticker() -> bytes:
    from c_fmu_support import ticker_bytes
    return ticker_bytes()


@st.composite
def clock_cases(draw: Any, command: str = "check") -> Case:
    """A system with clocks (two Tickers, in co-simulation or model exchange), valid or with one bad clock
    setting (:data:`CLOCK_BAD`: refused, in one line naming its field)."""
    from c_fmu_support import ticker_scenario

    interface = draw(st.sampled_from(["co-simulation", "model-exchange"]))
    how = draw(st.sampled_from(["valid", *CLOCK_BAD]))
    edits, fld = CLOCK_BAD.get(how, ({}, ""))
    text = ticker_scenario("ticker.fmu", interface, **edits)
    expect = Expectation(True, (fld,), f"a bad clock setting: {how}", how) if how != "valid" else None
    return Case(f"clocks-{command}", _base_argv(draw, command, "s.toml"),
                {"s.toml": text.encode(), "ticker.fmu": _ticker()}, expect, how)


@st.composite
def check_then_run_cases(draw: Any) -> Case:
    """A scenario, broken or not, checked and, where check accepts it, run: what check accepts, run must
    not refuse as bad input."""
    case = draw(scenario_cases(draw(st.booleans()), "check", requirements=draw(st.booleans())))
    case.target, case.then = "check-then-run", ["run", "s.toml", "--out", "out", "--quiet"]
    return case


@st.composite
def condition_cases(draw: Any, command: str = "check") -> Case:
    """A scenario with an event whose condition is broken or at the grammar's limits."""
    sysm = draw(systems())
    doc = draw(scenario_docs(sysm))
    when, how = draw(broken_conditions(sysm))
    doc["events"] = [{"when": when, "action": "stop"}]
    return Case(f"conditions-{command}", _base_argv(draw, command, "s.toml"), {"s.toml": dumps(doc).encode()},
                None, how)


@st.composite
def option_values(draw: Any, opt: schema.Option, broken: bool) -> list[str]:
    """The words of one option on a command line: its flag and a value of its kind (broken: any)."""
    if opt.kind == "flag":
        return [opt.flag]
    if opt.choices:
        good = [str(c) for c in opt.choices]
        v = draw(st.sampled_from(good)) if not broken or draw(st.booleans()) else draw(typos(good[0]))
        return [opt.flag, v]
    if opt.kind.startswith("float"):
        vals = [0.5, 0.01, 1.0] if not broken else [0.0, -1.0, 1e10, 1e-320, 1e308, "nan", "inf", "-inf", "x", ""]
    elif opt.kind.startswith("int"):
        vals = [1, 2] if not broken else [0, -1, 2 ** 32, 2 ** 63, "1.5", "x"]
    elif opt.kind.startswith("path"):
        vals = ["out2"] if not broken else ["afile", "afile/sub", "/proc/nope", "", "missing.csv", "é" * 300]
    else:
        vals = ["x"] if not broken else ["", "x" * 5000, "a.b=c", "=", "\udcff"]
    v = draw(st.sampled_from(vals))
    return [opt.flag, str(v)]


#: Options the command-line cases leave out: they change where the run goes, not what it is given
#: (--real-time paces to the wall clock, --isolate starts child processes, --live serves the run and waits for
#: its clients with --paused: they have their own tests, and live_option_cases their bad values).
SLOW_OPTIONS = {"--real-time", "--isolate", "--show", "--dashboard", "--scheduler", "--live", "--port", "--host",
                "--paused", "--open"}

#: Bad values of run --live's --port and --host.
BAD_LIVE_VALUES = {"--port": ["-1", "65536", str(2 ** 32), "1.5", "x", "", "80 81"],
                   "--host": ["", "nohost", "256.0.0.1", "127.0.0.1:80", "x" * 5000, "http://127.0.0.1", "\udcff"]}


@st.composite
def live_option_cases(draw: Any) -> Case:
    """``run --live`` with a bad --port or --host, or --port, --host, --paused or --open without --live: refused
    before anything runs or listens, in one line naming the option."""
    sysm = draw(systems())
    doc = draw(scenario_docs(sysm))
    argv = _base_argv(draw, "run", "s.toml")
    flag = draw(st.sampled_from(["--port", "--host", "--paused", "--open"]))
    if flag in BAD_LIVE_VALUES and draw(st.booleans()):
        value = draw(st.sampled_from(BAD_LIVE_VALUES[flag]))
        argv += ["--live", flag, value]
        why, this = f"a bad {flag}", f"{flag} {value!r}"
    else:
        argv += [flag, *{"--port": ["8000"], "--host": ["127.0.0.1"]}.get(flag, [])]
        why = this = f"{flag} without --live"
    return Case("cli-run-live", argv, {"s.toml": dumps(doc).encode()}, Expectation(True, (flag,), why, this),
                "broken live option")


#: What ``view`` is given that is not a results folder (a valid one would be served until Ctrl-C).
NOT_RESULTS = {"no such folder": {}, "an empty folder": {"r/.keep": b""}, "a file": {"r": b"x"},
               "no signals.npy": {"r/summary.json": b"{}", "r/scenario.json": b"{}"},
               "signals.npy empty": {"r/signals.npy": b""}, "signals.npy not one": {"r/signals.npy": b"\x93NUMPY"}}


@st.composite
def view_cases(draw: Any) -> Case:
    """``view`` of a folder that is not a results folder, or with a bad --port or --host: refused in one line
    (exit 2), before anything listens."""
    what = draw(st.sampled_from(sorted(NOT_RESULTS)))
    argv = ["view", "r"]
    words: tuple[str, ...] = ("r",)
    flag = draw(st.sampled_from([None, "--port", "--host"]))
    if flag is not None:
        value = draw(st.sampled_from(BAD_LIVE_VALUES[flag]))
        argv += [flag, value]
        words, what = (flag,), f"{what}, {flag} {value!r}"
    return Case("view-broken", argv, dict(NOT_RESULTS[what.split(",")[0]]),
                Expectation(True, words, "not a results folder" if flag is None else f"a bad {flag}", what), what)


@st.composite
def command_line_cases(draw: Any, command: str, broken: bool) -> Case:
    """A valid scenario and a command line of ``command`` with options drawn from its parser."""
    sysm = draw(systems())
    doc = draw(scenario_docs(sysm))
    cmd = schema.commands()[command]
    opts = [o for o in cmd.options if o.flag not in SLOW_OPTIONS]
    chosen = draw(st.lists(st.sampled_from(opts), max_size=3, unique_by=lambda o: o.flag))
    argv = _base_argv(draw, command, "s.toml")
    for o in chosen:
        if o.flag in ("--out", "--quiet") and command == "run":
            continue
        if o.flag == "--set":
            params = sorted(sysm.parameters) or ["x.k"]
            argv += ["--set", f"{draw(st.sampled_from(params))}={draw(st.sampled_from(['1.5', '-1', 'nan', 'x', '']) if broken else '0.5')}"]
        elif o.flag == "--record":
            argv += ["--record", draw(st.sampled_from(sorted(sysm.outputs) or ["x.y"])) if not broken else "nope.*"]
        elif o.flag == "--variant":
            argv += ["--variant", "v" if not broken else "nope"]
        else:
            argv += draw(option_values(o, broken))
    if command == "run" and "--format" in argv:
        pass
    files = {"s.toml": dumps(doc).encode(), "afile": b"x", "in.csv": b"time,x\n0,1\n"}
    return Case(f"cli-{command}", argv, files, None, "broken options" if broken else "valid")


@st.composite
def linearize_cases(draw: Any, broken: bool) -> Case:
    """``linearize`` of one Reference FMU with options drawn from its parser."""
    models = schema.models()
    m = draw(st.sampled_from(["Dahlquist", "VanDerPol", "Feedthrough"]))
    cmd = schema.commands()["linearize"]
    argv = ["linearize", models[m].path, "--out", "lin"]
    opts = [o for o in cmd.options if o.flag not in ("--out", "--inputs", "--outputs", "--break", "--state", "--set")]
    for o in draw(st.lists(st.sampled_from(opts), max_size=3, unique_by=lambda o: o.flag)):
        if o.flag == "--steps":
            argv += ["--steps", draw(st.sampled_from(["20", "5"] if not broken else ["0", "-1", "1", "100000000"]))]
        elif o.flag == "--at":
            argv += ["--at", draw(st.sampled_from(["0", "0.1"] if not broken else ["-1", "nan", "inf", "1e300"]))]
        else:
            argv += draw(option_values(o, broken))
    if draw(st.booleans()):
        outs = sorted(models[m].outputs)
        if outs:
            refs = [f"{m}.{o}" for o in outs]
            argv += ["--outputs", draw(st.sampled_from(refs)) if not broken else draw(st.sampled_from(refs + [f"{m}.nope", "x"]))]
    return Case("cli-linearize", argv, {}, None, "broken options" if broken else "valid")


# --- sweep and falsification files ----------------------------------------------------------------------
@st.composite
def sweep_docs(draw: Any, sysm: System) -> dict[str, Any]:
    params = sorted(k for k, t in sysm.parameters.items() if t == "Real") or ["x.k"]
    doc: dict[str, Any] = {"base": "s.toml"}
    if draw(st.booleans()):
        doc["grid"] = {draw(st.sampled_from(params)): draw(st.lists(st.floats(0.1, 2.0), min_size=1, max_size=3))}
    if draw(st.booleans()) or "grid" not in doc:
        key = draw(st.sampled_from(params))
        dist = draw(st.sampled_from(sorted(schema.DISTRIBUTIONS)))
        d: dict[str, Any] = {"dist": dist}
        for k in schema.DISTRIBUTIONS[dist]:
            d[k] = {"low": 0.5, "high": 1.5, "mean": 1.0, "std": 0.1, "sigma": 0.1, "values": [0.5, 1.0]}.get(k, 1.0)
        doc["random"] = {key: d}
    outs = sysm.real(sysm.outputs)
    if outs and draw(st.booleans()):
        of = draw(st.sampled_from(sorted(schema.METRIC_KINDS)))
        m: dict[str, Any] = {"of": of, "variable": draw(st.sampled_from(outs))}
        for k in schema.METRIC_KINDS[of]:
            m[k] = {"level": 0.5, "target": 1.0, "band": 0.1}.get(k, 1.0)
        if of == "rmse":
            m["reference"], m["column"] = "ref.csv", "y"
        doc["metric"] = {"m1": m}
    _optional(draw, "sweep", doc, sysm, skip=("base", "variant", "runs", "metrics", "grid", "random", "metric", "sets"))
    return doc


@st.composite
def sweep_cases(draw: Any, broken: bool) -> Case:
    sysm = draw(systems())
    base = draw(scenario_docs(sysm))
    for k in ("runs", "variants", "record"):   # one run, every output recorded: any metric's variable is
        base.pop(k, None)
    doc = draw(sweep_docs(sysm))
    how, expect = "valid", None
    if broken:
        pick = draw(st.sampled_from(["mutation", "unknown_parameter", "bad_distribution", "reference", "workers"]))
        if pick == "unknown_parameter":
            doc.setdefault("grid", {})["nope.k"] = [1.0]
            text, how = dumps(doc).encode(), "a grid over a parameter that does not exist"
            expect = Expectation(True, ("nope.k",), how)
        elif pick == "bad_distribution" and "random" in doc:
            key = next(iter(doc["random"]))
            k = draw(st.sampled_from(sorted(set(doc["random"][key]) - {"dist"}) or ["dist"]))
            doc["random"][key][k] = draw(st.sampled_from(["a", -1, math.inf, -math.inf, math.nan, [], {}]))
            text, how = dumps(doc).encode(), f"random.{key}.{k} broken"
        elif pick == "reference":
            doc["metric"] = {"m1": {"of": "rmse", "variable": (sysm.real(sysm.outputs) or ["x.y"])[0],
                                    "reference": "ref.csv", "column": "y"}}
            text, how = dumps(doc).encode(), "a reference CSV at the edges"
        elif pick == "workers":
            text = dumps(doc).encode()
        else:
            text, how, expect = draw(mutated(doc, "sweep"))
    else:
        text = dumps(doc).encode()
    ref = draw(st.sampled_from([b"time,y\n0,1\n1,1\n", b"time,y\n0,nan\n1,1\n", b"time,y\n0,1\ninf,1\n",
                                b"time,y\n0,1\n0.001,1\n", b"\xff\xfe\x00", b""])) if how == "a reference CSV at the edges" \
        else b"time,y\n0,1\n10,1\n"
    # (a broken --workers only where the file's own fault expects no line of its own: either is refused first)
    bad_workers = [["--workers", "0"], ["--workers", "-1"]] if broken and expect is None else []
    workers = draw(st.sampled_from([[], ["--workers", "1"]] + bad_workers))
    argv = ["sweep", "sw.toml", "--out", "sweep-out", "--quiet"] + workers
    if workers[1:] in (["0"], ["-1"]) and expect is None and how == "valid":
        expect = Expectation(True, ("--workers",), f"--workers {workers[1]}")
    return Case("sweep", argv, {"s.toml": dumps(base).encode(), "sw.toml": text, "ref.csv": ref}, expect, how)


@st.composite
def falsify_cases(draw: Any, broken: bool) -> Case:
    sysm = draw(systems())
    base = draw(scenario_docs(sysm, requirements=True))
    for k in ("runs", "variants"):
        base.pop(k, None)
    params = sorted(k for k, t in sysm.parameters.items() if t == "Real") or ["x.k"]
    doc: dict[str, Any] = {"base": "s.toml", "requirement": base["requirements"][0]["name"],
                           # (a box within every declared range of these FMUs' Real parameters: BouncingBall's e
                           # is in [0.5, 1], the others declare none)
                           "space": {draw(st.sampled_from(params)): {"low": 0.6, "high": 0.9}}}
    _optional(draw, "falsify", doc, sysm, skip=("base", "requirement", "space", "run", "variant", "budget"))
    doc["budget"] = draw(st.integers(10, 40))
    how, expect = "valid", None
    if broken:
        pick = draw(st.sampled_from(["mutation", "unknown_parameter", "seed", "unknown_requirement"]))
        if pick == "unknown_parameter":
            doc["space"]["nope.k"] = {"low": 0.0, "high": 1.0}
            text, how = dumps(doc).encode(), "a space over a parameter that does not exist"
            expect = Expectation(True, ("nope.k",), how)
        elif pick == "seed":
            doc["seed"] = draw(st.sampled_from([2 ** 32, 2 ** 63 - 1, -1]))
            text, how = dumps(doc).encode(), f"seed {doc['seed']}"
        elif pick == "unknown_requirement":
            doc["requirement"] = "nope"
            text, how = dumps(doc).encode(), "an unknown requirement"
            expect = Expectation(True, ("nope",), how)
        else:
            text, how, expect = draw(mutated(doc, "falsify"))
    else:
        text = dumps(doc).encode()
    return Case("falsify", ["falsify", "fa.toml", "--out", "fa-out", "--quiet"],
                {"s.toml": dumps(base).encode(), "fa.toml": text}, expect, how)
