"""Requirements in signal temporal logic (STL): the expression language of the master, its parser (a
tokenizer and a recursive-descent parser of our own, never ``eval``) and its check against the variables'
types and units.  The events' conditions (cosim.scenario.condition) are its Boolean part, parsed by the
same tokenizer and parser in the :data:`CONDITION` dialect; requirements' formulas take all of it
(:data:`FORMULA`).

Grammar (keywords are case-sensitive; precedence from loosest to tightest)::

    formula     := implication
    implication := disjunction ["implies" implication]
    disjunction := conjunction ("or" conjunction)*
    conjunction := until ("and" until)*
    until       := unary [("until" | "since") [BOUND] unary]
    unary       := ("not" | "always" | "eventually" | "historically" | "once") [BOUND] unary | comparison
    comparison  := sum [COMPARE sum]
    sum         := product (("+" | "-") product)*
    product     := sign (("*" | "/") sign)*
    sign        := "-" sign | atom
    atom        := NUMBER [UNIT] | "t" | "true" | "false" | NAME | ("abs" | "sqrt") "(" sum ")" | "(" formula ")"
    BOUND       := "[" NUMBER "," NUMBER "]"          (seconds, from now: future for always, eventually,
                                                        until; past for historically, once, since)
    COMPARE     := "<" | "<=" | ">" | ">=" | "==" | "!="
    NAME        := instance "." variable   (the variable may contain dots and an index: "x[1]", "a.b")

A condition is the part without ``implies``, the temporal operators, arithmetic, units, ``abs`` and
``sqrt``, where an operand of a comparison is a NAME, a NUMBER, ``-`` NUMBER, ``t``, ``true`` or ``false``
(never parenthesised)::

    condition   := disjunction                 (of conjunctions of "not" ... of comparisons)
    comparison  := "(" condition ")" | operand [COMPARE operand]
    operand     := NUMBER | "-" NUMBER | "true" | "false" | "t" | NAME

A chain of one operator (``or``, ``and``, ``+ -``, ``* /``) is one node of all its operands, parsed in a
loop and evaluated left to right (the roundings of nested pairs), so that no walk of a long formula
recurses deeply; what nests (parentheses, the prefix operators, abs/sqrt, ``implies``) is refused beyond
MAX_DEPTH levels.

A constant may carry a unit (``0.05 m``, ``8 N.m``, ``5 cm``): it is converted into the unit of what it is
compared with or added to (a unit of another dimension is refused); a constant without a unit is in that
unit.  ``t`` is the time [s].  ``sqrt`` halves the exponents of its operand's unit (a distance:
``sqrt((a.x - 2 m) * (a.x - 2 m) + a.y * a.y) < 5 cm``); a square root of a negative number is NaN, and a
comparison whose value is NaN (of either side) is false, robustness -inf.

The quantitative semantics (robustness: how far from violation, in the comparison's unit), on the
communication points t_k = k h: ``a > b`` and ``a >= b`` give a - b, ``a < b`` and ``a <= b`` give b - a,
``a == b`` gives -|a - b|, ``a != b`` gives |a - b|; a Boolean variable (or ``true``/``false``) gives +inf
when true and -inf when false; ``not`` negates, ``and``/``or`` take the minimum/maximum, ``p implies q`` is
``not p or q``; ``always[a,b] p`` at t_k is the minimum of p over t_k+a..t_k+b, ``eventually`` the
maximum, ``historically`` and ``once`` the same over t_k-b..t_k-a (without a bound: from the start);
``p until[a,b] q`` at t_k is the maximum over t_j in t_k+a..t_k+b of min(q(t_j), p over t_k..t_j-h), and
``p since[a,b] q`` the maximum over t_j in t_k-b..t_k-a of min(q(t_j), p over t_j+h..t_k) (rtamt's
discrete-time semantics).  A requirement holds when its robustness is >= 0.  (A condition is true or
false: its comparisons are Python's, :data:`COMPARE`; where no comparison is at a tie, the robustness of
the same text is > 0 exactly where the condition is true.)

A requirement is evaluated at t = 0; one without a temporal operator means "at every communication point"
(it is read as ``always p``).  ``always`` without a bound is allowed as the outermost operator only (over
the whole run); every other future operator needs a bound (a verdict must be reachable in a finite run).
"""
from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, NamedTuple

from ..messages.errors import CosimError
from ..messages.suggest import did_you_mean
from ..model.types import NUMERIC_KINDS
from ..model.units import KNOWN, Unit, conversion

UNARY_TEMPORAL = {"always": "future", "eventually": "future", "historically": "past", "once": "past"}
BINARY_TEMPORAL = {"until": "future", "since": "past"}
#: The keywords of conditions (the Boolean part) and of formulas (all of the language).
CONDITION_KEYWORDS = frozenset({"and", "or", "not", "true", "false", "t"})
KEYWORDS = CONDITION_KEYWORDS | {"implies", "abs", "sqrt"} | UNARY_TEMPORAL.keys() | BINARY_TEMPORAL.keys()


class Comparison(NamedTuple):
    """A comparison operator: its truth (a condition's value) and the sign of its robustness (a
    requirement's: ``sign * (a - b)`` for an order, ``sign * |a - b|`` for an equality)."""

    truth: Callable[[Any, Any], bool]
    sign: float
    ordered: bool


#: The comparisons of the language, one table for conditions and formulas.
COMPARE: dict[str, Comparison] = {
    "<": Comparison(operator.lt, -1.0, True), "<=": Comparison(operator.le, -1.0, True),
    ">": Comparison(operator.gt, 1.0, True), ">=": Comparison(operator.ge, 1.0, True),
    "==": Comparison(operator.eq, -1.0, False), "!=": Comparison(operator.ne, 1.0, False)}
MAX_LENGTH = 4000   # characters of a formula
MAX_DEPTH = 60      # nesting

_TOKEN = re.compile(r"""
    (?P<space>\s+)
  | (?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<op><=|>=|==|!=|<|>|\+|-|\*|/)
  | (?P<paren>[()\[\],])
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*(?:\[\d+(?:,\d+)*\])?)*)
""", re.VERBOSE)
#: A unit after a number: letters, digits and . / ^ * (``N.m``, ``m/s2``, ``rad/s^2``), starting with a letter.
_UNIT = re.compile(r"[A-Za-z][A-Za-z0-9]*(?:[./^*][A-Za-z0-9]+)*")
#: The characters of arithmetic and bounds: tokens of a formula, unexpected in a condition.
_ARITHMETIC = frozenset({"+", "*", "/", "[", "]", ","})


# ------------------------------------------------------------------------------------------- messages
class ExpressionError(ValueError):
    """A formula or a condition that does not parse or check: ``reason`` at the 1-based character ``pos``
    (0: the whole) of ``text``; ``word``: the word it is about (a name that is no variable), ``found``: the
    token found where the reason's ``expected ...`` was ("" the end).  The message is one line, written by
    the subclass of the dialect (the same reason in both)."""

    def __init__(self, reason: str, pos: int = 0, text: str = "", *, word: str | None = None,
                 found: str | None = None) -> None:
        self.reason, self.pos, self.text, self.word, self.found = reason, pos, text, word, found
        super().__init__(self.render())

    def render(self) -> str:
        raise NotImplementedError


class FormulaError(ExpressionError):
    """A formula that does not parse or check: "at character 9: unexpected '$'"."""

    def render(self) -> str:
        reason = self.reason if self.word is None else f"{self.word!r}: {self.reason}"
        if self.found is not None:
            reason += f", found {self.found!r}" if self.found else ", found the end"
        return f"at character {self.pos}: {reason}" if self.pos else reason


class ConditionError(ExpressionError):
    """An event's condition that does not parse or check: "unexpected '$' at character 9 of 'a.x > 0 $'"."""

    def render(self) -> str:
        if self.word is not None:
            return f"{self.word!r} at character {self.pos}: {self.reason}"
        if self.found == "":
            return f"{self.reason}, found at the end of {self.text!r}"
        if self.found is not None:
            return f"{self.reason}, found {self.found!r} at character {self.pos} of {self.text!r}"
        return f"{self.reason} at character {self.pos} of {self.text!r}" if self.pos and self.text else self.reason


def not_a_condition(what: str) -> str:
    """The reason given for a number where a condition is expected (``what``: as written)."""
    return f"{what} is a number, not a condition: compare it (e.g. {what} > 0)"


@dataclass(frozen=True)
class Dialect:
    """What a use of the language takes of it: ``full`` (formulas) implies, the temporal operators,
    arithmetic, units, abs and sqrt, operands in parentheses; without (conditions) comparisons of names,
    numbers, t, true and false under and, or, not and parentheses.  The rest is how its messages read."""

    noun: str                        # "formula" or "condition"
    full: bool
    keywords: frozenset[str]
    max_length: int                  # characters
    max_depth: int                   # levels of nesting
    too_deep: str                    # the reason given beyond them ({n}: max_depth)
    after: str                       # what may follow a complete expression
    operand: str                     # what an operand may be
    error: type[ExpressionError]


FORMULA = Dialect("formula", True, frozenset(KEYWORDS), MAX_LENGTH, MAX_DEPTH,
                  "nested too deeply (at most {n} levels of parentheses, prefix operators and implies)",
                  "an operator or the end", "a variable, a number, t, true, false, abs(...), sqrt(...) or '('",
                  FormulaError)
CONDITION = Dialect("condition", False, CONDITION_KEYWORDS, 2000, 50, "nested more than {n} deep",
                    "and, or or the end", "a variable, a number, true, false, t or '('", ConditionError)


@dataclass(frozen=True)
class Token:
    kind: str      # number, unit, op, paren, name, keyword, end
    text: str
    pos: int       # 1-based


def _not_a_name(d: Dialect, word: str, pos: int, text: str) -> ExpressionError:
    """The refusal of a word without a dot that is no keyword of the dialect (at character ``pos``)."""
    if word in UNARY_TEMPORAL or word in BINARY_TEMPORAL:   # (only a condition gets here)
        return d.error("a temporal operator: a condition is true or false at each communication point "
                       "(temporal operators are for requirements)", pos, text, word=word)
    if word in KEYWORDS:
        return d.error("an operator of requirements, not of conditions (a condition compares variables, t and "
                       "numbers under and, or, not)", pos, text, word=word)
    hint = did_you_mean(word, d.keywords)   # a misspelt operator (eventualy, untl, adn)
    if hint:
        return d.error(f"not an operator, nor a variable (\"instance.variable\"){hint}", pos, text, word=word)
    return d.error("a variable is \"instance.variable\" (or t for the time)", pos, text, word=word)


def tokenize(text: str, dialect: Dialect = FORMULA) -> list[Token]:
    """The tokens of a formula (or of a condition, ``dialect`` :data:`CONDITION`), ending with an ``end``
    token; the dialect's error where a character or a word is none of its own."""
    d = dialect
    if not isinstance(text, str):
        raise d.error(f"must be a string, not {text!r}")
    if len(text) > d.max_length:
        raise d.error(f"a {d.noun} of {len(text)} characters: at most {d.max_length}")
    out: list[Token] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or (not d.full and m.group() in _ARITHMETIC):
            raise d.error(f"unexpected {text[pos]!r}", pos + 1, text)
        kind = m.lastgroup
        assert kind is not None   # every alternative of _TOKEN is a named group
        if kind != "space":
            word = m.group()
            if kind == "name" and word in d.keywords:
                kind = "keyword"
            elif kind == "name" and "." not in word:
                raise _not_a_name(d, word, pos + 1, text)
            # (a condition's number beyond the largest is infinite, as it always was)
            if kind == "number" and d.full and not math.isfinite(float(word)):
                raise d.error(f"{word}: beyond the largest number (about 1.8e308)", pos + 1, text)
            out.append(Token(kind, word, pos + 1))
            if kind == "number" and d.full:   # a unit may follow
                j = m.end()
                while j < len(text) and text[j] in " \t":
                    j += 1
                u = _UNIT.match(text, j)
                if u is not None and u.group() not in KEYWORDS:
                    hint = "" if u.group() in KNOWN else did_you_mean(u.group(), KEYWORDS)
                    if hint:   # a misspelt operator after a number (a.x > 0 untl ...), not a unit
                        raise d.error(f"not a unit, nor an operator{hint}", j + 1, text, word=u.group())
                    out.append(Token("unit", u.group(), j + 1))
                    pos = u.end()
                    continue
        pos = m.end()
    out.append(Token("end", "", len(text) + 1))
    return out


# ------------------------------------------------------------------------------------------- syntax tree
@dataclass(frozen=True)
class Node:
    pos: int


@dataclass(frozen=True)
class Num(Node):
    value: float
    unit: str | None = None
    unit_pos: int = 0


@dataclass(frozen=True)
class Bool(Node):
    value: bool


@dataclass(frozen=True)
class Time(Node):
    pass


@dataclass(frozen=True)
class Var(Node):
    name: str


@dataclass(frozen=True)
class Neg(Node):
    a: Node


@dataclass(frozen=True)
class Abs(Node):
    a: Node


@dataclass(frozen=True)
class Sqrt(Node):
    a: Node


@dataclass(frozen=True)
class Arith(Node):
    """A left-associative chain of arithmetic, ((first op x1) op x2) ...: each of ``rest`` is (operator, its
    1-based position, its right operand); the operators of one chain are all + and - or all * and /.
    (A chain, not nested pairs: a formula of 2,000 terms is walked in a loop, never by deep recursion.)"""
    first: Node
    rest: tuple[tuple[str, int, Node], ...]


@dataclass(frozen=True)
class Cmp(Node):
    op: str
    a: Node
    b: Node


@dataclass(frozen=True)
class Not(Node):
    a: Node


@dataclass(frozen=True)
class Logic(Node):
    """``and``/``or`` of every one of ``args`` (two or more, a chain parsed in a loop, evaluated left to
    right), or ``implies`` of two (p implies q: not p or q)."""
    op: str        # and, or, implies
    args: tuple[Node, ...]


@dataclass(frozen=True)
class Temporal(Node):
    op: str        # always, eventually, historically, once
    lo: float      # [s]
    hi: float | None   # [s]; None: unbounded
    a: Node


@dataclass(frozen=True)
class Until(Node):
    op: str        # until, since
    lo: float
    hi: float | None
    a: Node
    b: Node


class _Parser:
    """A recursive-descent parser's place in the tokens of ``text`` (ending with an ``end`` token) and its
    nesting, for a formula or a condition (``dialect``)."""

    def __init__(self, text: str, dialect: Dialect) -> None:
        self.text, self.d = text, dialect
        self.toks = tokenize(text, dialect)
        self.i = 0
        self.depth = 0

    def peek(self) -> Token:
        return self.toks[self.i]

    def take(self) -> Token:
        tok = self.toks[self.i]
        self.i += 1
        return tok

    def is_kw(self, *words: str) -> bool:
        return self.peek().kind == "keyword" and self.peek().text in words

    def fail(self, tok: Token, wanted: str) -> ExpressionError:
        return self.d.error(f"expected {wanted}", tok.pos, self.text, found=tok.text)

    def deeper(self, tok: Token) -> None:
        self.depth += 1
        if self.depth > self.d.max_depth:
            raise self.d.error(self.d.too_deep.format(n=self.d.max_depth), tok.pos)

    def parse(self) -> Node:
        if self.peek().kind == "end":
            raise self.d.error(f"an empty {self.d.noun}")
        node = self.implication()
        if self.peek().kind != "end":
            raise self.fail(self.peek(), self.d.after)
        return node

    def implication(self) -> Node:
        node = self.disjunction()
        if self.is_kw("implies"):
            tok = self.take()
            self.deeper(tok)
            node = Logic(tok.pos, "implies", (node, self.implication()))
            self.depth -= 1
        return node

    # A chain of one operator (a or b or ...) is parsed in a loop into one node (its position the last
    # operator's); the loops are written out, so that a level of parentheses costs as few frames as it can.
    def disjunction(self) -> Node:
        args, pos = [self.conjunction()], 0
        while self.is_kw("or"):
            pos = self.take().pos
            args.append(self.conjunction())
        return args[0] if len(args) == 1 else Logic(pos, "or", tuple(args))

    def conjunction(self) -> Node:
        args, pos = [self.until()], 0
        while self.is_kw("and"):
            pos = self.take().pos
            args.append(self.until())
        return args[0] if len(args) == 1 else Logic(pos, "and", tuple(args))

    def until(self) -> Node:
        node = self.unary()
        if self.is_kw("until", "since"):
            tok = self.take()
            lo, hi = self.bound(tok)
            node = Until(tok.pos, tok.text, lo, hi, node, self.unary())
        return node

    def bound(self, op: Token) -> tuple[float, float | None]:
        if not (self.peek().kind == "paren" and self.peek().text == "["):
            return 0.0, None
        self.take()
        lo = self.number("the bound's start [s]")
        comma = self.take()
        if comma.text != ",":
            raise self.fail(comma, "','")
        hi = self.number("the bound's end [s]")
        close = self.take()
        if close.text != "]":
            raise self.fail(close, "']'")
        if not (0.0 <= lo <= hi) or not math.isfinite(hi):
            raise FormulaError(f"{op.text}[{lo:g},{hi:g}]: a bound [a,b] needs 0 <= a <= b (seconds)", op.pos)
        return lo, hi

    def number(self, what: str) -> float:
        tok = self.take()
        if tok.kind != "number":
            raise self.fail(tok, what)
        if self.peek().kind == "unit":
            unit = self.take()
            if unit.text != "s":
                raise FormulaError(f"a time bound is in seconds, not {unit.text}", unit.pos)
        return float(tok.text)

    def unary(self) -> Node:
        if self.is_kw("not"):
            tok = self.take()
            self.deeper(tok)
            node: Node = Not(tok.pos, self.unary())
            self.depth -= 1
            return node
        if self.is_kw(*UNARY_TEMPORAL):
            tok = self.take()
            lo, hi = self.bound(tok)
            self.deeper(tok)
            node = Temporal(tok.pos, tok.text, lo, hi, self.unary())
            self.depth -= 1
            return node
        return self.comparison()

    def comparison(self) -> Node:
        if not self.d.full:
            return self.condition_comparison()
        node = self.sum()
        if self.peek().kind == "op" and self.peek().text in COMPARE:
            tok = self.take()
            node = Cmp(tok.pos, tok.text, node, self.sum())
        return node

    def condition_comparison(self) -> Node:
        """A condition's comparison: a condition in parentheses (never compared), or an operand alone or
        compared with another."""
        if self.peek().kind == "paren" and self.peek().text == "(":
            return self.atom()
        node = self.operand()
        if self.peek().kind == "op" and self.peek().text in COMPARE:
            tok = self.take()
            node = Cmp(tok.pos, tok.text, node, self.operand())
        return node

    def operand(self) -> Node:
        """A condition's operand: an atom that is no parenthesis, or a negative number."""
        tok = self.peek()
        if tok.kind == "op" and tok.text == "-":
            self.take()
            num = self.take()
            if num.kind != "number":
                raise self.fail(num, "a number after '-'")
            return Num(tok.pos, -float(num.text))
        if tok.kind == "paren":
            raise self.fail(self.take(), self.d.operand)
        return self.atom()

    def sum(self) -> Node:
        first, rest = self.product(), []
        while self.peek().kind == "op" and self.peek().text in ("+", "-"):
            tok = self.take()
            rest.append((tok.text, tok.pos, self.product()))
        return Arith(rest[-1][1], first, tuple(rest)) if rest else first

    def product(self) -> Node:
        first, rest = self.sign(), []
        while self.peek().kind == "op" and self.peek().text in ("*", "/"):
            tok = self.take()
            rest.append((tok.text, tok.pos, self.sign()))
        return Arith(rest[-1][1], first, tuple(rest)) if rest else first

    def sign(self) -> Node:
        if self.peek().kind == "op" and self.peek().text == "-":
            tok = self.take()
            self.deeper(tok)
            node: Node = Neg(tok.pos, self.sign())
            self.depth -= 1
            return node
        return self.atom()

    def atom(self) -> Node:
        tok = self.take()
        if tok.kind == "number":
            if self.peek().kind == "unit":
                unit = self.take()
                return Num(tok.pos, float(tok.text), unit.text, unit.pos)
            return Num(tok.pos, float(tok.text))
        if tok.kind == "keyword" and tok.text in ("true", "false"):
            return Bool(tok.pos, tok.text == "true")
        if tok.kind == "keyword" and tok.text == "t":
            return Time(tok.pos)
        if tok.kind == "name":
            return Var(tok.pos, tok.text)
        if tok.kind == "keyword" and tok.text in ("abs", "sqrt"):
            open_ = self.take()
            if open_.text != "(":
                raise self.fail(open_, f"'(' after {tok.text}")
            self.deeper(tok)
            node: Node = (Abs if tok.text == "abs" else Sqrt)(tok.pos, self.sum())
            self.depth -= 1
            close = self.take()
            if close.text != ")":
                raise self.fail(close, "')'")
            return node
        if tok.kind == "paren" and tok.text == "(":
            self.deeper(tok)
            node = self.implication()
            self.depth -= 1
            close = self.take()
            if close.text != ")":
                raise self.fail(close, "')'")
            return node
        raise self.fail(tok, self.d.operand)


def parse(text: str, dialect: Dialect = FORMULA) -> Node:
    """The syntax tree of a formula (or of a condition, ``dialect`` :data:`CONDITION`); the dialect's error
    with the position where it does not parse."""
    return _Parser(text, dialect).parse()


def children(node: Node) -> tuple[Node, ...]:
    """The direct subformulas or operands of a node, left to right."""
    if isinstance(node, (Neg, Abs, Sqrt, Not, Temporal)):
        return (node.a,)
    if isinstance(node, (Cmp, Until)):
        return (node.a, node.b)
    if isinstance(node, Logic):
        return node.args
    if isinstance(node, Arith):
        return (node.first, *(x for _, _, x in node.rest))
    return ()


def walk(node: Node) -> Iterator[Node]:
    """Every node of a formula, depth first, left to right (a loop over a stack: no recursion)."""
    stack = [node]
    while stack:
        n = stack.pop()
        yield n
        stack.extend(reversed(children(n)))


def variables(node: Node) -> dict[str, int]:
    """The "instance.variable" names a formula reads, in order of first appearance, each with the
    character position of its first appearance."""
    out: dict[str, int] = {}
    for n in walk(node):
        if isinstance(n, Var) and n.name not in out:
            out[n.name] = n.pos
    return out


def temporal(node: Node) -> bool:
    """Whether a formula has a temporal operator."""
    return any(isinstance(n, (Temporal, Until)) for n in walk(node))


# ------------------------------------------------------------------------------------------- the check
@dataclass(frozen=True)
class VarInfo:
    """What the check needs of a variable: its FMI type name and its unit (None: none declared)."""

    type: str
    unit: Unit | None


@dataclass
class Checked:
    """A formula checked against its variables: the syntax tree as it is evaluated (the outermost
    ``always`` made explicit), the unit of each comparison's robustness, the notes (bounds beyond the
    run) and the scaling of each constant and variable into the unit it is compared in."""

    text: str
    node: Node
    variables: list[str]
    notes: list[str] = field(default_factory=list)
    #: per numeric node (by id): (factor, offset) into the unit of its comparison
    scale: dict[int, tuple[float, float]] = field(default_factory=dict)
    #: per comparison node (by id): the unit of its robustness ("" when none)
    unit_of: dict[int, str] = field(default_factory=dict)


def _derived(name: str, exps: tuple[int, ...], factor: float) -> Unit:
    """A unit made by arithmetic, named as the common unit of its dimension and factor where there is one
    (sqrt of m*m is m), else ``name``."""
    same = sorted((u.name for u in KNOWN.values() if u.exps == exps and u.factor == factor and not u.offset),
                  key=lambda n: (len(n), n))
    return Unit(same[0] if same else name, exps, factor)


def _unit_named(name: str, pos: int) -> Unit:
    if name in KNOWN:
        return KNOWN[name]
    raise FormulaError(f"unknown unit {name!r} (known: {', '.join(sorted(KNOWN))})", pos)


class _Checker:
    def __init__(self, text: str, info: dict[str, VarInfo], step: float, stop: float) -> None:
        self.text, self.info, self.step, self.stop = text, info, step, stop
        self.out = Checked(text, Bool(0, True), [])   # (its node is set once checked)

    # numbers: return the unit (None: free) of a numeric expression; record conversions
    def numeric(self, n: Node) -> Unit | None:
        if isinstance(n, Num):
            return _unit_named(n.unit, n.unit_pos) if n.unit else None
        if isinstance(n, Time):
            return KNOWN["s"]
        if isinstance(n, Var):
            v = self.var(n)
            if v.type not in NUMERIC_KINDS:
                raise FormulaError(f"{n.name} is {v.type}: arithmetic and comparisons take numbers", n.pos)
            return v.unit
        if isinstance(n, (Neg, Abs)):
            return self.numeric(n.a)
        if isinstance(n, Sqrt):
            u = self.numeric(n.a)
            if u is None:
                return None
            if not u.exps or any(e % 2 for e in u.exps) or u.offset:
                raise FormulaError(f"sqrt of {u.name}: a unit whose exponents are not all even", n.pos)
            return _derived(f"sqrt({u.name})", tuple(e // 2 for e in u.exps), math.sqrt(u.factor))
        if isinstance(n, Arith):   # left to right, as ((first op x1) op x2) ...
            left, ua = n.first, self.numeric(n.first)
            for op, pos, b in n.rest:
                ub = self.numeric(b)
                ua = self.same(pos, left, ua, b, ub) if op in ("+", "-") else self.product(op, pos, ua, ub)
                left = n   # (the sum so far: not a constant)
            return ua
        if isinstance(n, (Bool, Cmp, Not, Logic, Temporal, Until)):
            raise FormulaError("a condition where a number is expected", n.pos)
        raise AssertionError(n)

    @staticmethod
    def product(op: str, pos: int, ua: Unit | None, ub: Unit | None) -> Unit | None:
        """The unit of a product or quotient (``op`` at character ``pos``) of operands in ``ua`` and ``ub``."""
        if ua is None or ub is None:
            return ua or ub
        if not ua.exps or not ub.exps:
            raise FormulaError(f"{ua.name} {op} {ub.name}: a product of units of unknown dimension", pos)
        sign = 1 if op == "*" else -1
        exps = tuple(x + sign * y for x, y in zip(ua.exps, ub.exps))
        return _derived(f"({ua.name}){op}({ub.name})", exps, ua.factor * ub.factor ** sign)

    def same(self, pos: int, a: Node, ua: Unit | None, b: Node, ub: Unit | None) -> Unit | None:
        """The common unit of two operands (of the operator at character ``pos``): the first one's, or the
        second one's when the first is a constant and the second is not (a constant is converted into the
        unit of what it meets); the other operand is converted into it."""
        if ua is None or ub is None:
            return ua or ub
        if isinstance(a, Num) and not isinstance(b, Num):
            a, ua, b, ub = b, ub, a, ua
        try:
            factor, offset = conversion(ub, ua)
        except CosimError:
            raise FormulaError(f"{ub.name} does not convert to {ua.name}: another dimension", pos) from None
        if (factor, offset) != (1.0, 0.0):
            self.out.scale[id(b)] = (factor, offset)
        return ua

    def var(self, n: Var) -> VarInfo:
        if n.name not in self.info:
            raise FormulaError(f"unknown variable {n.name}", n.pos)
        return self.info[n.name]

    def boolean(self, n: Node, top: bool = False) -> None:
        if isinstance(n, Bool):
            return
        if isinstance(n, Var):
            if self.var(n).type != "Boolean":
                raise FormulaError(not_a_condition(n.name), n.pos)
            return
        if isinstance(n, Cmp):
            ua, ub = self.numeric(n.a), self.numeric(n.b)
            unit = self.same(n.pos, n.a, ua, n.b, ub)
            self.out.unit_of[id(n)] = unit.name if unit else ""
            return
        if isinstance(n, Not):
            self.boolean(n.a)
            return
        if isinstance(n, Logic):
            for a in n.args:
                self.boolean(a)
            return
        if isinstance(n, (Temporal, Until)):
            self.bounds(n, top)
            self.boolean(n.a)
            if isinstance(n, Until):
                self.boolean(n.b)
            return
        raise FormulaError("a number where a condition is expected (compare it)", n.pos)

    def bounds(self, n: Temporal | Until, top: bool) -> None:
        future = (UNARY_TEMPORAL.get(n.op) or BINARY_TEMPORAL.get(n.op)) == "future"
        if n.hi is None:
            if future and not (top and n.op == "always"):
                raise FormulaError(f"{n.op} without a bound: a future operator needs one ({n.op}[a,b], "
                                   "seconds; only an outermost always may go without, over the whole run)", n.pos)
            return
        for value in (n.lo, n.hi):
            k = value / self.step
            if abs(k - round(k)) > 1e-9 * max(1.0, abs(k)):
                raise FormulaError(f"{n.op}[{n.lo:g},{n.hi:g}]: {value:g} s is not a multiple of the communication "
                                   f"step {self.step:g} s (the formula is evaluated at the communication points)",
                                   n.pos)
        if future and n.hi > self.stop + 1e-12:
            self.out.notes.append(f"{n.op}[{n.lo:g},{n.hi:g}] at character {n.pos} reaches beyond the stop time "
                                  f"{self.stop:g} s: its verdict may stay undecided")


def check(text: str, info: dict[str, VarInfo], step: float, stop: float, node: Node | None = None) -> Checked:
    """Check a requirement's formula (``node``: its syntax tree, parsed here when not given) against its
    variables (``info``: by "instance.variable"), the communication step [s] and the stop time [s];
    FormulaError with the position where it fails.  A formula without a temporal operator becomes
    ``always`` of it."""
    node = parse(text) if node is None else node
    c = _Checker(text, info, step, stop)
    if not temporal(node):
        node = Temporal(1, "always", 0.0, None, node)
    c.boolean(node, top=True)
    if isinstance(node, Temporal) and node.op == "always" and node.hi is None and (ahead := horizon(node.a)) > 0:
        c.out.notes.append(f"always without a bound at character {node.pos} over an operand that looks {ahead:g} s "
                           f"ahead: the last {ahead:g} s of the run are not judged (its window ends there)")
    c.out.node = node
    c.out.variables = list(variables(node))
    return c.out


def horizon(node: Node) -> float:
    """How far a formula looks ahead of the time it is evaluated at [s]: the sum of the bounds' ends of
    the future operators on the way down, the largest over its operands."""
    if isinstance(node, (Temporal, Until)) and (UNARY_TEMPORAL.get(node.op) or BINARY_TEMPORAL.get(node.op)) == "future":
        return (node.hi or 0.0) + max((horizon(c) for c in children(node)), default=0.0)
    return max((horizon(c) for c in children(node) if isinstance(c, (Temporal, Until, Logic, Not))), default=0.0)


# ------------------------------------------------------------------------------- atoms as functions

def compile_numeric(n: Node, checked: Checked, read: dict[str, Callable[[], float]]) -> Callable[[float], float]:
    """A function of the time [s] giving a numeric expression's value now, in its comparison's unit."""
    f = _numeric(n, checked, read)
    scale = checked.scale.get(id(n))
    if scale is not None:
        factor, offset = scale
        return lambda t: factor * f(t) + offset
    return f


def _numeric(n: Node, checked: Checked, read: dict[str, Callable[[], float]]) -> Callable[[float], float]:
    if isinstance(n, Num):
        value = n.value
        return lambda t: value
    if isinstance(n, Time):
        return lambda t: t
    if isinstance(n, Var):
        get = read[n.name]
        return lambda t: float(get())
    if isinstance(n, Neg):
        a = compile_numeric(n.a, checked, read)
        return lambda t: -a(t)
    if isinstance(n, Abs):
        a = compile_numeric(n.a, checked, read)
        return lambda t: abs(a(t))
    if isinstance(n, Sqrt):
        a = compile_numeric(n.a, checked, read)
        return lambda t: math.sqrt(x) if (x := a(t)) >= 0.0 else math.nan
    assert isinstance(n, Arith)
    first = compile_numeric(n.first, checked, read)
    if len(n.rest) == 1:   # (the common case, without the loop)
        op, _, b = n.rest[0]
        return _binary(op, first, compile_numeric(b, checked, read))
    rest = [(_OPS[op], compile_numeric(b, checked, read)) for op, _, b in n.rest]

    def chain(t: float) -> float:   # left to right: the same roundings as nested pairs
        x = first(t)
        for f, b in rest:
            x = f(x, b(t))
        return x
    return chain


def _divide(x: float, y: float) -> float:
    """x / y as IEEE 754 has it (without Python's ZeroDivisionError)."""
    if y == 0.0:
        return math.nan if x == 0.0 or math.isnan(x) else math.copysign(math.inf, x) * math.copysign(1.0, y)
    return x / y


_OPS: dict[str, Callable[[float, float], float]] = {
    "+": lambda x, y: x + y, "-": lambda x, y: x - y, "*": lambda x, y: x * y, "/": _divide}


def _binary(op: str, a: Callable[[float], float], b: Callable[[float], float]) -> Callable[[float], float]:
    if op == "+":
        return lambda t: a(t) + b(t)
    if op == "-":
        return lambda t: a(t) - b(t)
    if op == "*":
        return lambda t: a(t) * b(t)
    return lambda t: _divide(a(t), b(t))


def compile_atom(n: Node, checked: Checked, read: dict[str, Callable[[], float]]) -> Callable[[float], float]:
    """A function of the time [s] giving the robustness of an atom (a comparison or a Boolean) now."""
    if isinstance(n, Bool):
        value = math.inf if n.value else -math.inf
        return lambda t: value
    if isinstance(n, Var):
        get = read[n.name]
        return lambda t: math.inf if get() else -math.inf
    assert isinstance(n, Cmp)
    a, b = compile_numeric(n.a, checked, read), compile_numeric(n.b, checked, read)
    # the robustness a - b, b - a, -|a - b| or |a - b|; a comparison of NaN (r != r) is false: -inf
    sign = COMPARE[n.op].sign
    if COMPARE[n.op].ordered:
        return lambda t: r if (r := sign * (a(t) - b(t))) == r else -math.inf
    return lambda t: r if (r := sign * abs(a(t) - b(t))) == r else -math.inf
