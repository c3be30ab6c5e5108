"""Values written as formulas of the position: ``value = "20 + 3000 * z"`` in a pipeline, ``Expression(...)``
in a script, ``<Function type="FunctionExpr">`` in a G+Smo file.

A value that varies over a face (a Dirichlet temperature, a flux, a film
coefficient, a displacement or a traction component, a source or a
conductivity) is written as an arithmetic expression of the physical
coordinates ``x``, ``y``, ``z`` (model units, m) in Python syntax: numbers,
``+ - * / ** %``, parentheses, ``pi``, ``e``, the functions in
:data:`FUNCTIONS` (NumPy's, elementwise) and comparisons, joined by ``and`` /
``or``, inside ``where(condition, a, b)``.  The text is parsed once, when the
configuration is checked, into a syntax tree that holds nothing else (no names
but these, no attributes, no indexing, no other calls), so a configuration
file can say no more than a formula; :class:`Expression` then evaluates it on
whole point arrays, as the problems' callables are.  The same tree is written
in G+Smo's expression syntax (exprtk) for :func:`iga.gismo.export_gismo`, and
read back from it.
"""

from __future__ import annotations

import ast
import functools
import operator
import re

import numpy as np

from .errors import ProblemError

__all__ = ["Expression", "VectorExpression", "FUNCTIONS"]

#: the functions an expression may call, by name: NumPy's elementwise ones
FUNCTIONS = {name: getattr(np, name) for name in (
    "sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh", "exp", "log", "log10",
    "sqrt", "abs", "hypot", "minimum", "maximum", "where", "floor", "ceil")}
_CONSTANTS = {"pi": np.float64(np.pi), "e": np.float64(np.e)}
_COORDINATES = ("x", "y", "z")
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
           ast.Pow: operator.pow, ast.Mod: operator.mod}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_COMPARE = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge}
_EXAMPLE = "e.g. \"20 + 3000 * z\" or \"where(x < 0.01, 80, 20)\""
_MAX_LENGTH = 2000  # characters: a formula, not a program (deeper nesting exhausts Python's parser)
_MAX_EXPORTED = 100_000  # characters of a formula written in G+Smo's syntax


class Expression:
    """A scalar formula of the position: ``Expression("20 + 3000 * z")(x)`` -> (N,) for points x (N, 3).

    ``where`` (e.g. ``"config key bc[0].value"``) names the value in every error: a syntax error or a construct
    outside the grammar (module notes) when it is made, a value that is not finite when it is evaluated."""

    def __init__(self, text: str, where: str = "expression"):
        self.text, self.where = str(text), where
        if len(self.text) > _MAX_LENGTH:
            raise ProblemError(f"{where}: a formula of {len(self.text)} characters is longer than {_MAX_LENGTH}; write "
                               f"a shorter expression of x, y, z, {_EXAMPLE}")
        try:
            tree = ast.parse(self.text.strip(), mode="eval")
            self._tree = tree.body
            self._check(self._tree)
        except SyntaxError as exc:
            raise ProblemError(f"{where}: {self._shown} is not a formula ({exc.msg} at column {exc.offset}); write "
                               f"an expression of x, y, z, {_EXAMPLE}") from None
        except RecursionError:
            raise ProblemError(f"{where}: {self._shown} is nested too deeply to read; write it with fewer levels "
                               "of operators and parentheses") from None

    @property
    def _shown(self) -> str:
        """The text for messages, cut to 80 characters."""
        return repr(self.text if len(self.text) <= 80 else self.text[:77] + "...")

    def _fail(self, what: str):
        raise ProblemError(f"{self.where}: {self._shown} {what}; a formula may use numbers, x, y, z, pi, e, "
                           f"+ - * / ** %, comparisons inside where(...), and {', '.join(FUNCTIONS)}")

    def _check(self, node) -> None:
        """Every node of the tree is one the grammar allows (module notes)."""
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self._fail(f"holds {node.value!r}, which is not a number")
            if not abs(node.value) <= 1.7976931348623157e308:  # 1e999 (inf) or a 400-digit integer
                self._fail("holds a number beyond the largest finite one (1.8e308)")
        elif isinstance(node, ast.Name):
            if node.id not in _COORDINATES and node.id not in _CONSTANTS:
                self._fail(f"names {node.id!r}, which is neither a coordinate nor a constant")
        elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            self._check(node.operand)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS:
            if node.keywords:
                self._fail(f"passes keywords to {node.func.id}")
            for k, arg in enumerate(node.args):
                if node.func.id == "where" and k == 0:
                    self._condition(arg)
                else:
                    self._check(arg)
        elif isinstance(node, (ast.Compare, ast.BoolOp)):
            self._fail("compares outside where(condition, a, b)")
        else:
            self._fail(f"uses {type(node).__name__.lower()} {ast.unparse(node)!r}, which a formula cannot hold")

    def _condition(self, node) -> None:
        """where's first argument: comparisons joined by and / or, or a formula (non-zero is true)."""
        if isinstance(node, ast.BoolOp):
            for part in node.values:
                self._condition(part)
        elif isinstance(node, ast.Compare):
            if not all(type(op) in _COMPARE for op in node.ops):
                self._fail("compares with an operator other than <, <=, >, >=")
            for part in [node.left] + node.comparators:
                self._check(part)
        else:
            self._check(node)

    def __call__(self, x) -> np.ndarray:
        """The values (N,) at the points x (N, 3) (m)."""
        x = np.asarray(x, float)
        names = {**_CONSTANTS, **{c: x[:, k] for k, c in enumerate(_COORDINATES)}}
        with np.errstate(all="ignore"):
            try:
                out = np.broadcast_to(np.asarray(self._eval(self._tree, names), float), (len(x),))
            except (TypeError, ValueError) as exc:  # e.g. where() with the wrong number of arguments
                raise ProblemError(f"{self.where}: {self._shown} cannot be evaluated: {exc}") from None
            except RecursionError:
                raise ProblemError(f"{self.where}: {self._shown} is nested too deeply to evaluate; write it with "
                                   "fewer levels of operators and parentheses") from None
        if not np.all(np.isfinite(out)):
            bad = x[~np.isfinite(out)][0]
            raise ProblemError(f"{self.where}: {self._shown} is not finite at x = {bad.tolist()} (a division by zero, "
                               "a logarithm or root of a negative number, or an overflow there)")
        return np.array(out)

    def _eval(self, node, names):
        if isinstance(node, ast.Constant):
            return np.float64(node.value)  # NumPy's arithmetic: an overflow is inf (refused below), not an error
        if isinstance(node, ast.Name):
            return names[node.id]
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](self._eval(node.left, names), self._eval(node.right, names))
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](self._eval(node.operand, names))
        if isinstance(node, ast.BoolOp):
            join = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
            return functools.reduce(join, [np.asarray(self._eval(v, names)) != 0 for v in node.values])
        if isinstance(node, ast.Compare):
            left, result = self._eval(node.left, names), True
            for op, right in zip(node.ops, node.comparators):
                value = self._eval(right, names)
                result = np.logical_and(result, _COMPARE[type(op)](left, value))
                left = value
            return result
        return FUNCTIONS[node.func.id](*(self._eval(a, names) for a in node.args))

    def exprtk(self) -> str:
        """The formula in G+Smo's expression syntax (``gsFunctionExpr``, exprtk), fully parenthesised: ``^`` for
        powers, ``if`` for where, ``asin`` ... ``min``, ``max`` for NumPy's names, Python's floored ``a % b`` as
        ``a - b floor(a / b)`` (exprtk's ``%`` truncates), ``e`` as its digits."""
        try:
            return _exprtk(self._tree)
        except _TooLong:  # each % spells its operands out twice: nested ones double the text
            raise ProblemError(f"{self.where}: {self._shown} becomes more than {_MAX_EXPORTED} characters in "
                               "G+Smo's syntax (each % writes its operands twice); write it with fewer nested %") \
                from None

    @classmethod
    def from_exprtk(cls, text: str, where: str = "expression") -> "Expression":
        """A formula written in G+Smo's expression syntax, as far as this grammar goes (what :meth:`exprtk`
        writes, and hand-written formulas of the same operators and functions)."""
        words = {"asin": "arcsin", "acos": "arccos", "atan": "arctan", "atan2": "arctan2", "min": "minimum",
                 "max": "maximum", "if": "where"}
        python = re.sub(r"\b(asin|acos|atan2|atan|min|max|if)(\s*\()", lambda m: words[m.group(1)] + m.group(2),
                        str(text)).replace("^", "**")
        return cls(python, where)

    def __repr__(self) -> str:
        return f"Expression({self.text!r})"

    def __str__(self) -> str:
        return self.text


_EXPRTK_CALLS = {"arcsin": "asin", "arccos": "acos", "arctan": "atan", "arctan2": "atan2", "minimum": "min",
                 "maximum": "max", "where": "if"}
_EXPRTK_OPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "^", ast.Lt: "<", ast.LtE: "<=",
               ast.Gt: ">", ast.GtE: ">=", ast.And: "and", ast.Or: "or"}


class _TooLong(Exception):
    """A formula's G+Smo text outgrows :data:`_MAX_EXPORTED` (caught by :meth:`Expression.exprtk`)."""


def _exprtk(node) -> str:
    """One checked node in exprtk syntax (:meth:`Expression.exprtk`)."""
    if isinstance(node, ast.Constant):
        return repr(float(node.value))
    if isinstance(node, ast.Name):
        return repr(float(_CONSTANTS["e"])) if node.id == "e" else node.id
    if isinstance(node, ast.BinOp):
        a, b = _exprtk(node.left), _exprtk(node.right)
        if isinstance(node.op, ast.Mod):
            if 2 * (len(a) + len(b)) > _MAX_EXPORTED:
                raise _TooLong
            return f"({a} - {b} * floor({a} / {b}))"
        return f"({a} {_EXPRTK_OPS[type(node.op)]} {b})"
    if isinstance(node, ast.UnaryOp):
        return f"(-{_exprtk(node.operand)})" if isinstance(node.op, ast.USub) else _exprtk(node.operand)
    if isinstance(node, ast.BoolOp):
        return "(" + f" {_EXPRTK_OPS[type(node.op)]} ".join(_exprtk(v) for v in node.values) + ")"
    if isinstance(node, ast.Compare):
        parts = [node.left] + node.comparators
        return "(" + " and ".join(f"({_exprtk(a)} {_EXPRTK_OPS[type(op)]} {_exprtk(b)})"
                                  for a, op, b in zip(parts[:-1], node.ops, parts[1:])) + ")"
    name = node.func.id
    return f"{_EXPRTK_CALLS.get(name, name)}({', '.join(_exprtk(a) for a in node.args)})"


class VectorExpression:
    """Three components, each a number or an :class:`Expression`: ``(x (N, 3)) -> (N, 3)``."""

    def __init__(self, components):
        self.components = list(components)

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, float)
        return np.stack([c(x) if callable(c) else np.full(len(x), float(c)) for c in self.components], axis=1)

    def __repr__(self) -> str:
        return f"VectorExpression({[str(c) for c in self.components]})"
