"""Arithmetic expressions over parameter values, for --set and grid ends.

`-2e-4 * shaker.omega**2`, `0.7*pi**2`, `sqrt(2)`: numbers, the FMU's
parameter names (dots and brackets allowed, as `q0[1]`), `pi`, `e`, + - * /
** and parentheses, sqrt/sin/cos/exp/log/abs. Nothing else is evaluated.
"""
from __future__ import annotations

import ast
import math
import operator
import re

from .errors import SweepError

_FUNCS = {"sqrt": math.sqrt, "sin": math.sin, "cos": math.cos, "exp": math.exp, "log": math.log, "abs": abs}
_CONSTS = {"pi": math.pi, "e": math.e}
_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_UNOPS = {ast.USub: operator.neg, ast.UAdd: operator.pos}
#: A name as the FMUs spell them: `omega`, `shaker.omega`, `q0[1]`.
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*|\[[0-9]+\])*")


class Expression:
    """A parsed expression; `names` are the parameters it reads."""

    def __init__(self, text: str, field: str, known: set[str]):
        self.text = text
        self.field = field
        aliases: dict[str, str] = {}

        def alias(m: re.Match) -> str:
            word = m.group(0)
            if word in _FUNCS or word in _CONSTS:
                return word
            if word not in known:
                raise SweepError(f"{field}: unknown name '{word}' in '{text}'; "
                                 f"known: pi, e, {', '.join(_FUNCS)} and the parameters {', '.join(sorted(known))}")
            aliases.setdefault(word, f"_p{len(aliases)}")
            return aliases[word]

        # numbers first, so that the e of 1e-3 is no name
        token = re.compile(r"(?P<num>\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?)|(?P<name>" + _NAME.pattern + ")")
        py = token.sub(lambda m: m.group(0) if m.group("num") else alias(m), text)
        try:
            self._tree = ast.parse(py.strip(), mode="eval").body
        except SyntaxError:
            raise SweepError(f"{field}: '{text}' is not an arithmetic expression") from None
        self._names = {v: k for k, v in aliases.items()}
        self.names = set(aliases)
        self._check(self._tree)

    def _check(self, node):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return
        if isinstance(node, ast.Name) and (node.id in self._names or node.id in _CONSTS):
            return
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            self._check(node.left)
            self._check(node.right)
            return
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNOPS:
            self._check(node.operand)
            return
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCS \
                and len(node.args) == 1 and not node.keywords:
            self._check(node.args[0])
            return
        raise SweepError(f"{self.field}: '{self.text}' may hold only numbers, parameters, pi, e, "
                         f"+ - * / ** and {', '.join(_FUNCS)}")

    def value(self, params: dict[str, float]) -> float:
        def ev(node):
            if isinstance(node, ast.Constant):
                return float(node.value)
            if isinstance(node, ast.Name):
                return _CONSTS[node.id] if node.id in _CONSTS else float(params[self._names[node.id]])
            if isinstance(node, ast.BinOp):
                return _BINOPS[type(node.op)](ev(node.left), ev(node.right))
            if isinstance(node, ast.UnaryOp):
                return _UNOPS[type(node.op)](ev(node.operand))
            return _FUNCS[node.func.id](ev(node.args[0]))

        try:
            v = float(ev(self._tree))
        except (ArithmeticError, ValueError) as err:
            raise SweepError(f"{self.field}: '{self.text}' cannot be evaluated ({err})") from None
        if not math.isfinite(v):
            raise SweepError(f"{self.field}: '{self.text}' = {v}, not a finite number")
        return v


def number(text: str, field: str) -> float:
    """A constant expression (no parameters)."""
    return Expression(text, field, set()).value({})
