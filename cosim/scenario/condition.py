"""Conditions of events (``when = "plant.x_A > 1.5 and t > 5"``): a tokenizer and a recursive-descent
parser of a small grammar of our own (never ``eval``), the type check against the variables, and the
compiled predicate the execution evaluates between steps.

Grammar (keywords and names are case-sensitive)::

    condition  := disjunct ("or" disjunct)*
    disjunct   := negation ("and" negation)*
    negation   := "not" negation | primary
    primary    := "(" condition ")" | operand [COMPARE operand]
    operand    := NUMBER | "-" NUMBER | "true" | "false" | "t" | NAME
    COMPARE    := "<" | "<=" | ">" | ">=" | "==" | "!="
    NAME       := instance "." variable   (the variable may contain dots and an index: "x[1]", "a.b")

``t`` is the time [s] at the communication point.  A comparison takes two numbers (Real, Integer,
Enumeration variables, constants, ``t``) or two booleans (``==``, ``!=`` only); an operand alone must be
a Boolean variable or ``true``/``false``.
"""
from __future__ import annotations

import operator
import re
from dataclasses import dataclass
from typing import Any, Callable

from ..model.types import NUMERIC_KINDS
from ..requirements.formula import Cursor

COMPARE = {"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge, "==": operator.eq,
           "!=": operator.ne}
KEYWORDS = {"and", "or", "not", "true", "false", "t"}
MAX_LENGTH = 2000   # characters of a condition
MAX_DEPTH = 50      # nested parentheses and "not"s

_TOKEN = re.compile(r"""
    (?P<space>\s+)
  | (?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<op><=|>=|==|!=|<|>)
  | (?P<paren>[()])
  | (?P<minus>-)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*(?:\[\d+(?:,\d+)*\])?)*)
""", re.VERBOSE)


class ConditionError(ValueError):
    """A condition that does not parse or does not type-check; the message is one line."""


@dataclass(frozen=True)
class Token:
    kind: str      # number, op, paren, minus, name, keyword, end
    text: str
    pos: int


def tokenize(text: str) -> list[Token]:
    """The tokens of a condition, ending with an ``end`` token; refuses any character outside the grammar."""
    if not isinstance(text, str):
        raise ConditionError(f"must be a string, not {text!r}")
    if len(text) > MAX_LENGTH:
        raise ConditionError(f"a condition of {len(text)} characters: at most {MAX_LENGTH}")
    out: list[Token] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise ConditionError(f"unexpected {text[pos]!r} at character {pos + 1} of {text!r}")
        kind = m.lastgroup
        assert kind is not None   # every alternative of _TOKEN is a named group
        if kind != "space":
            word = m.group()
            if kind == "name" and word in KEYWORDS:
                kind = "keyword"
            elif kind == "name" and "." not in word:
                raise ConditionError(f"{word!r} at character {pos + 1}: a variable is \"instance.variable\" "
                                     "(or t for the time)")
            out.append(Token(kind, word, pos))
        pos = m.end()
    out.append(Token("end", "", len(text)))
    return out


# The syntax tree: tuples, so that it is plain data.
#   ("or", a, b) ("and", a, b) ("not", a) ("cmp", op, left, right) ("is", operand)
#   operands: ("num", float) ("bool", bool) ("time",) ("var", "instance.variable")
Node = tuple


class _Parser(Cursor[Token]):
    def __init__(self, text: str) -> None:
        super().__init__(text, tokenize(text))

    def fail(self, tok: Token, wanted: str) -> ConditionError:
        where = "at the end" if tok.kind == "end" else f"{tok.text!r} at character {tok.pos + 1}"
        return ConditionError(f"expected {wanted}, found {where} of {self.text!r}")

    def parse(self) -> Node:
        if self.peek().kind == "end":
            raise ConditionError("an empty condition")
        node = self.condition()
        if self.peek().kind != "end":
            raise self.fail(self.peek(), "and, or or the end")
        return node

    def condition(self) -> Node:
        node = self.disjunct()
        while self.peek().text == "or" and self.peek().kind == "keyword":
            self.take()
            node = ("or", node, self.disjunct())
        return node

    def disjunct(self) -> Node:
        node = self.negation()
        while self.peek().text == "and" and self.peek().kind == "keyword":
            self.take()
            node = ("and", node, self.negation())
        return node

    def negation(self) -> Node:
        if self.peek().kind == "keyword" and self.peek().text == "not":
            self.take()
            self._deeper()
            node = ("not", self.negation())
            self.depth -= 1
            return node
        return self.primary()

    def _deeper(self) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise ConditionError(f"nested more than {MAX_DEPTH} deep")

    def primary(self) -> Node:
        tok = self.peek()
        if tok.kind == "paren" and tok.text == "(":
            self.take()
            self._deeper()
            node = self.condition()
            self.depth -= 1
            close = self.take()
            if close.text != ")":
                raise self.fail(close, "')'")
            return node
        left = self.operand()
        if self.peek().kind == "op":
            op = self.take().text
            return ("cmp", op, left, self.operand())
        return ("is", left)

    def operand(self) -> Node:
        tok = self.take()
        if tok.kind == "number":
            return ("num", float(tok.text))
        if tok.kind == "minus":
            num = self.take()
            if num.kind != "number":
                raise self.fail(num, "a number after '-'")
            return ("num", -float(num.text))
        if tok.kind == "keyword" and tok.text in ("true", "false"):
            return ("bool", tok.text == "true")
        if tok.kind == "keyword" and tok.text == "t":
            return ("time",)
        if tok.kind == "name":
            return ("var", tok.text)
        raise self.fail(tok, "a variable, a number, true, false, t or '('")


def parse(text: str) -> Node:
    """The syntax tree of a condition (ConditionError if it does not parse)."""
    return _Parser(text).parse()


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
            what = _show(node[1])
            raise ConditionError(f"{what} is a number, not a condition: compare it (e.g. {what} > 0)")
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
    op, left, right = COMPARE[node[1]], _operand(node[2], read), _operand(node[3], read)
    return lambda t: bool(op(left(t), right(t)))


def _operand(node: Node, read: dict[str, Callable[[], Any]]) -> Callable[[float], Any]:
    if node[0] in ("num", "bool"):
        value = node[1]
        return lambda t: value
    if node[0] == "time":
        return lambda t: t
    get = read[node[1]]
    return lambda t: get()
