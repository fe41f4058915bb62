"""Conditions of events (``when = "plant.x_A > 1.5 and t > 5"``): the Boolean part of the requirements'
language (cosim.requirements.formula), parsed by its tokenizer and parser in the condition dialect (never
``eval``); the type check against the variables, and the compiled predicate the execution evaluates
between steps.

Grammar (keywords and names are case-sensitive; the formula language without implies, temporal
operators, arithmetic and units, refused with the requirements' messages)::

    condition  := disjunct ("or" disjunct)*
    disjunct   := negation ("and" negation)*
    negation   := "not" negation | primary
    primary    := "(" condition ")" | operand [COMPARE operand]
    operand    := NUMBER | "-" NUMBER | "true" | "false" | "t" | NAME
    COMPARE    := "<" | "<=" | ">" | ">=" | "==" | "!="
    NAME       := instance "." variable   (the variable may contain dots and an index: "x[1]", "a.b")

``t`` is the time [s] at the communication point.  A comparison takes two numbers (Real, Integer,
Enumeration variables, constants, ``t``) or two booleans (``==``, ``!=`` only); an operand alone must be
a Boolean variable or ``true``/``false``.  A condition is true or false (Python's comparisons); a
number beyond the largest is infinite.
"""
from __future__ import annotations

from typing import Any, Callable

from ..model.types import NUMERIC_KINDS
from ..requirements import formula
from ..requirements.formula import COMPARE, CONDITION, ConditionError, Token, not_a_condition

__all__ = ["COMPARE", "KEYWORDS", "MAX_DEPTH", "MAX_LENGTH", "ConditionError", "Token", "check_types",
           "compile_condition", "parse", "tokenize", "variables"]

KEYWORDS = CONDITION.keywords
MAX_LENGTH = CONDITION.max_length   # characters of a condition
MAX_DEPTH = CONDITION.max_depth     # nested parentheses and "not"s


def tokenize(text: str) -> list[Token]:
    """The tokens of a condition (the language's tokenizer, positions 0-based), ending with an ``end``
    token; refuses any character outside the condition's grammar."""
    return [Token(tok.kind, tok.text, tok.pos - 1) for tok in formula.tokenize(text, CONDITION)]


# The syntax tree: tuples, so that it is plain data.
#   ("or", a, b) ("and", a, b) ("not", a) ("cmp", op, left, right) ("is", operand)
#   operands: ("num", float) ("bool", bool) ("time",) ("var", "instance.variable")
Node = tuple


def parse(text: str) -> Node:
    """The syntax tree of a condition (ConditionError if it does not parse)."""
    return _tree(formula.parse(text, CONDITION))


def _tree(n: formula.Node) -> Node:
    """A condition's tree of the language's: a chain of and/or as nested pairs, left to right."""
    if isinstance(n, formula.Logic):
        node = _tree(n.args[0])
        for a in n.args[1:]:
            node = (n.op, node, _tree(a))
        return node
    if isinstance(n, formula.Not):
        return ("not", _tree(n.a))
    if isinstance(n, formula.Cmp):
        return ("cmp", n.op, _leaf(n.a), _leaf(n.b))
    return ("is", _leaf(n))


def _leaf(n: formula.Node) -> Node:
    if isinstance(n, formula.Num):
        return ("num", n.value)
    if isinstance(n, formula.Bool):
        return ("bool", n.value)
    if isinstance(n, formula.Time):
        return ("time",)
    assert isinstance(n, formula.Var), n   # (the condition dialect parses no other operand)
    return ("var", n.name)


def variables(node: Node) -> list[str]:
    """The "instance.variable" names a condition reads, in order of first appearance."""
    out: list[str] = []

    def walk(n: Node) -> None:
        if n[0] == "var":
            if n[1] not in out:
                out.append(n[1])
        elif n[0] in ("or", "and"):
            walk(n[1])
            walk(n[2])
        elif n[0] in ("not", "is"):
            walk(n[1])
        elif n[0] == "cmp":
            walk(n[2])
            walk(n[3])
    walk(node)
    return out


def _show(operand: Node) -> str:
    if operand[0] == "var":
        return operand[1]
    if operand[0] == "time":
        return "t"
    if operand[0] == "bool":
        return "true" if operand[1] else "false"
    return f"{operand[1]:g}"


def _kind(operand: Node, types: dict[str, str]) -> str:
    """'number' or 'boolean' (a String or Binary variable cannot be compared)."""
    if operand[0] in ("num", "time"):
        return "number"
    if operand[0] == "bool":
        return "boolean"
    t = types[operand[1]]
    if t in NUMERIC_KINDS:
        return "number"
    if t == "Boolean":
        return "boolean"
    raise ConditionError(f"{operand[1]} is {t}: a condition compares numbers and booleans only")


def check_types(node: Node, types: dict[str, str]) -> None:
    """Raise ConditionError where a comparison mixes a number and a boolean, orders booleans, or an operand
    alone is not a boolean.  ``types`` maps each variable of the condition to its FMI 2.0 type name."""
    if node[0] in ("or", "and"):
        check_types(node[1], types)
        check_types(node[2], types)
    elif node[0] == "not":
        check_types(node[1], types)
    elif node[0] == "is":
        if _kind(node[1], types) != "boolean":
            raise ConditionError(not_a_condition(_show(node[1])))
    else:
        _, op, a, b = node
        ka, kb = _kind(a, types), _kind(b, types)
        if ka != kb:
            names = [_show(x) for x in (a, b)]
            raise ConditionError(f"wrong type: {names[0]} {op} {names[1]} compares a {ka} with a {kb}")
        if ka == "boolean" and op not in ("==", "!="):
            raise ConditionError(f"booleans compare with == or != only, not {op}")


def compile_condition(node: Node, read: dict[str, Callable[[], Any]]) -> Callable[[float], bool]:
    """A predicate ``f(t)`` over the current values: ``read[name]()`` gives a variable's value."""
    kind = node[0]
    if kind == "or":
        a, b = compile_condition(node[1], read), compile_condition(node[2], read)
        return lambda t: a(t) or b(t)
    if kind == "and":
        a, b = compile_condition(node[1], read), compile_condition(node[2], read)
        return lambda t: a(t) and b(t)
    if kind == "not":
        a = compile_condition(node[1], read)
        return lambda t: not a(t)
    if kind == "is":
        v = _operand(node[1], read)
        return lambda t: bool(v(t))
    op, left, right = COMPARE[node[1]].truth, _operand(node[2], read), _operand(node[3], read)
    return lambda t: bool(op(left(t), right(t)))


def _operand(node: Node, read: dict[str, Callable[[], Any]]) -> Callable[[float], Any]:
    if node[0] in ("num", "bool"):
        value = node[1]
        return lambda t: value
    if node[0] == "time":
        return lambda t: t
    get = read[node[1]]
    return lambda t: get()
