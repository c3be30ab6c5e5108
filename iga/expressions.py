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
in G+Smo's expression syntax (exprtk) for :func:`iga.io.gismo.export_gismo`, and
read back from it.
"""

from __future__ import annotations

import ast
import functools
import operator
import re

import numpy as np

from .errors import ProblemError

__all__ = ["Expression", "VectorExpression", "FUNCTIONS", "ARITY"]

#: the functions an expression may call, by name: NumPy's elementwise ones (``fmod``: the remainder that
#: truncates, as exprtk's ``%`` does; Python's ``%`` floors)
FUNCTIONS = {name: getattr(np, name) for name in (
    "sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh", "exp", "log", "log10",
    "sqrt", "abs", "hypot", "minimum", "maximum", "where", "floor", "ceil", "fmod")}
#: how many arguments each function takes: (least, most); minimum and maximum take two or more (exprtk's
#: min and max are variadic).  Checked when a formula is read: NumPy's extra positional argument would be its
#: ``out=``, which would write into the caller's points
ARITY = {**{name: (1, 1) for name in FUNCTIONS}, "arctan2": (2, 2), "hypot": (2, 2), "fmod": (2, 2),
         "minimum": (2, None), "maximum": (2, None), "where": (3, 3)}
_CONSTANTS = {"pi": np.float64(np.pi), "e": np.float64(np.e)}
_COORDINATES = ("x", "y", "z")
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
           ast.Pow: operator.pow, ast.Mod: operator.mod}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_COMPARE = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge}
_EXAMPLE = "e.g. \"20 + 3000 * z\" or \"where(x < 0.01, 80, 20)\""
_MAX_LENGTH = 2000  # characters: a formula, not a program (deeper nesting exhausts Python's parser)
_MAX_EXPORTED = 100_000  # characters of a formula written in G+Smo's syntax


def _arguments(name: str, n: int) -> str:
    lo, hi = ARITY[name]
    return (f"{lo} or more arguments" if hi is None else f"{lo} argument{'s' if lo > 1 else ''}" if lo == hi
            else f"{lo} to {hi} arguments")


class Expression:
    """A scalar formula of the position: ``Expression("20 + 3000 * z")(x)`` -> (N,) for points x (N, 3).

    ``where`` (e.g. ``"config key bc[0].value"``) names the value in every error: a syntax error or a construct
    outside the grammar (module notes) when it is made, a value that is not finite when it is evaluated.
    The formula is compiled once into a postfix program (no recursion: a sum of a thousand terms reads and
    evaluates like a short one), and evaluated on copies of the point columns (nothing the formula does can
    write into the caller's array)."""

    def __init__(self, text: str, where: str = "expression", truncating_mod: bool = False):
        self.text, self.where = str(text), where
        if len(self.text) > _MAX_LENGTH:
            raise ProblemError(f"{where}: a formula of {len(self.text)} characters is longer than {_MAX_LENGTH}; write "
                               f"a shorter expression of x, y, z, {_EXAMPLE}")
        try:
            tree = ast.parse(self.text.strip(), mode="eval")
        except SyntaxError as exc:
            at = len(self.text.strip())
            # Python reports an incomplete formula ("80 + ") at column 0 or past its end
            place = "at its end" if not exc.offset or exc.offset > at or exc.lineno != 1 else \
                f"at column {exc.offset}"
            raise ProblemError(f"{where}: {self._shown} is not a formula ({exc.msg} {place}); write "
                               f"an expression of x, y, z, {_EXAMPLE}") from None
        except (RecursionError, MemoryError):
            raise ProblemError(f"{where}: {self._shown} is nested too deeply to read; write it with fewer levels "
                               "of operators and parentheses") from None
        self._program = self._compile(tree.body, truncating_mod)

    @property
    def _shown(self) -> str:
        """The text for messages, cut to 80 characters."""
        return repr(self.text if len(self.text) <= 80 else self.text[:77] + "...")

    def _fail(self, what: str):
        raise ProblemError(f"{self.where}: {self._shown} {what}; a formula may use numbers, x, y, z, pi, e, "
                           f"+ - * / ** %, comparisons inside where(...), and {', '.join(FUNCTIONS)}")

    def _compile(self, root, truncating_mod: bool) -> list:
        """The checked tree as a postfix program [(op, argument)], built without recursion.

        Every node must be one the grammar allows (module notes); comparisons and ``and`` / ``or`` only as
        where's condition.  ``truncating_mod``: ``%`` is exprtk's truncating remainder (``fmod``)."""
        out = []
        stack = [(root, False, False)]  # (node, children done, a where condition)
        while stack:
            node, done, condition = stack.pop()
            if done:
                out.append(self._op(node, truncating_mod))
                continue
            children = self._children(node, condition)
            stack.append((node, True, condition))
            stack.extend(reversed(children))
        return out

    def _children(self, node, condition: bool) -> list:
        """The children of an allowed node, each with whether it is a where condition; refuses the others."""
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self._fail(f"holds {node.value!r}, which is not a number")
            if not abs(node.value) <= 1.7976931348623157e308:  # 1e999 (inf) or a 400-digit integer
                self._fail("holds a number beyond the largest finite one (1.8e308)")
            return []
        if isinstance(node, ast.Name):
            if node.id not in _COORDINATES and node.id not in _CONSTANTS:
                self._fail(f"names {node.id!r}, which is neither a coordinate nor a constant")
            return []
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return [(node.left, False, False), (node.right, False, False)]
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            return [(node.operand, False, False)]
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS:
            name = node.func.id
            if node.keywords:
                self._fail(f"passes keywords to {name}")
            lo, hi = ARITY[name]
            if len(node.args) < lo or (hi is not None and len(node.args) > hi):
                self._fail(f"calls {name} with {len(node.args)} argument{'s' if len(node.args) != 1 else ''}; "
                           f"{name} takes {_arguments(name, len(node.args))}")
            if any(isinstance(a, ast.Starred) for a in node.args):
                self._fail(f"unpacks arguments into {name}")
            return [(a, False, name == "where" and k == 0) for k, a in enumerate(node.args)]
        if condition and isinstance(node, ast.BoolOp):
            return [(v, False, True) for v in node.values]
        if condition and isinstance(node, ast.Compare):
            if not all(type(op) in _COMPARE for op in node.ops):
                self._fail("compares with an operator other than <, <=, >, >=")
            return [(v, False, False) for v in [node.left] + node.comparators]
        if isinstance(node, (ast.Compare, ast.BoolOp)):
            self._fail("compares outside where(condition, a, b)")
        self._fail(f"uses {type(node).__name__.lower()} {_unparse(node)!r}, which a formula cannot hold")

    @staticmethod
    def _op(node, truncating_mod: bool) -> tuple:
        if isinstance(node, ast.Constant):
            return ("const", np.float64(node.value))  # NumPy's arithmetic: an overflow is inf (refused), no error
        if isinstance(node, ast.Name):
            return ("name", node.id)
        if isinstance(node, ast.BinOp):
            if truncating_mod and isinstance(node.op, ast.Mod):
                return ("call", ("fmod", 2))
            return ("bin", type(node.op))
        if isinstance(node, ast.UnaryOp):
            return ("un", type(node.op))
        if isinstance(node, ast.BoolOp):
            return ("bool", (type(node.op), len(node.values)))
        if isinstance(node, ast.Compare):
            return ("cmp", tuple(type(op) for op in node.ops))
        return ("call", (node.func.id, len(node.args)))

    def __call__(self, x) -> np.ndarray:
        """The values (N,) at the points x (N, 3) (m)."""
        try:
            x = np.array(x, float)  # a copy: the columns handed to NumPy are never the caller's
        except (TypeError, ValueError):
            raise ProblemError(f"{self.where}: {self._shown} is evaluated at points given as an array of shape (N, "
                               f"3); got {type(x).__name__}") from None
        if x.ndim != 2 or x.shape[1] != 3:
            raise ProblemError(f"{self.where}: {self._shown} is evaluated at points given as an array of shape (N, "
                               f"3); got shape {x.shape}")
        names = {**_CONSTANTS, **{c: np.ascontiguousarray(x[:, k]) for k, c in enumerate(_COORDINATES)}}
        with np.errstate(all="ignore"):
            try:
                out = np.broadcast_to(np.asarray(self._run(names), float), (len(x),))
            except (TypeError, ValueError) as exc:
                raise ProblemError(f"{self.where}: {self._shown} cannot be evaluated: {exc}") from None
        if not np.all(np.isfinite(out)):
            bad = x[~np.isfinite(out)][0]
            raise ProblemError(f"{self.where}: {self._shown} is not finite at x = {bad.tolist()} (a division by zero, "
                               "a logarithm or root of a negative number, or an overflow there)")
        return np.array(out)

    def _run(self, names):
        """Evaluate the postfix program on a value stack."""
        st = []
        for op, arg in self._program:
            if op == "const":
                st.append(arg)
            elif op == "name":
                st.append(names[arg])
            elif op == "bin":
                b = st.pop()
                st.append(_BINARY[arg](st.pop(), b))
            elif op == "un":
                st.append(_UNARY[arg](st.pop()))
            elif op == "bool":
                kind, n = arg
                vals = [np.asarray(v) != 0 for v in st[-n:]]
                del st[-n:]
                st.append(functools.reduce(np.logical_and if kind is ast.And else np.logical_or, vals))
            elif op == "cmp":
                n = len(arg) + 1
                vals = st[-n:]
                del st[-n:]
                result = True
                for k, kind in enumerate(arg):
                    result = np.logical_and(result, _COMPARE[kind](vals[k], vals[k + 1]))
                st.append(result)
            else:
                name, n = arg
                args = st[-n:]
                del st[-n:]
                f = FUNCTIONS[name]
                st.append(functools.reduce(f, args) if name in ("minimum", "maximum") else f(*args))
        return st[0]

    def exprtk(self) -> str:
        """The formula in G+Smo's expression syntax (``gsFunctionExpr``, exprtk), fully parenthesised: ``^`` for
        powers, ``if`` for where, ``asin`` ... ``min``, ``max`` for NumPy's names, Python's floored ``a % b`` as
        ``a - b floor(a / b)`` and ``fmod(a, b)`` as exprtk's truncating ``a % b``, ``e`` as its digits."""
        st = []
        for op, arg in self._program:
            if op == "const":
                st.append(repr(float(arg)))
            elif op == "name":
                st.append(repr(float(_CONSTANTS["e"])) if arg == "e" else arg)
            elif op == "bin":
                b, a = st.pop(), st.pop()
                if arg is ast.Mod:
                    if 2 * (len(a) + len(b)) > _MAX_EXPORTED:  # each % spells its operands out twice
                        raise ProblemError(f"{self.where}: {self._shown} becomes more than {_MAX_EXPORTED} "
                                           "characters in G+Smo's syntax (each % writes its operands twice); "
                                           "write it with fewer nested %")
                    st.append(f"({a} - {b} * floor({a} / {b}))")
                else:
                    st.append(f"({a} {_EXPRTK_OPS[arg]} {b})")
            elif op == "un":
                v = st.pop()
                st.append(f"(-{v})" if arg is ast.USub else v)
            elif op == "bool":
                kind, n = arg
                vals = st[-n:]
                del st[-n:]
                st.append("(" + f" {_EXPRTK_OPS[kind]} ".join(vals) + ")")
            elif op == "cmp":
                n = len(arg) + 1
                vals = st[-n:]
                del st[-n:]
                st.append("(" + " and ".join(f"({vals[k]} {_EXPRTK_OPS[kind]} {vals[k + 1]})"
                                             for k, kind in enumerate(arg)) + ")")
            else:
                name, n = arg
                args = st[-n:]
                del st[-n:]
                st.append(f"({args[0]} % {args[1]})" if name == "fmod" else
                          f"{_EXPRTK_CALLS.get(name, name)}({', '.join(args)})")
        return st[0]

    @classmethod
    def from_exprtk(cls, text: str, where: str = "expression") -> "Expression":
        """A formula written in G+Smo's expression syntax, as far as this grammar goes (what :meth:`exprtk`
        writes, and hand-written formulas of the same operators and functions): exprtk's ``%`` truncates
        (``-7 % 3`` is -1, Python's 2), its ``min`` and ``max`` take any number of arguments."""
        words = {"asin": "arcsin", "acos": "arccos", "atan": "arctan", "atan2": "arctan2", "min": "minimum",
                 "max": "maximum", "if": "where"}
        python = re.sub(r"\b(asin|acos|atan2|atan|min|max|if)(\s*\()", lambda m: words[m.group(1)] + m.group(2),
                        str(text)).replace("^", "**")
        return cls(python, where, truncating_mod=True)

    def __repr__(self) -> str:
        return f"Expression({self.text!r})"

    def __str__(self) -> str:
        return self.text


def _unparse(node) -> str:
    """A node's text for a message (cut), or its kind where unparsing itself would recurse too deeply."""
    try:
        text = ast.unparse(node)
    except RecursionError:
        return type(node).__name__.lower()
    return text if len(text) <= 60 else text[:57] + "..."


_EXPRTK_CALLS = {"arcsin": "asin", "arccos": "acos", "arctan": "atan", "arctan2": "atan2", "minimum": "min",
                 "maximum": "max", "where": "if"}
_EXPRTK_OPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "^", ast.Lt: "<", ast.LtE: "<=",
               ast.Gt: ">", ast.GtE: ">=", ast.And: "and", ast.Or: "or"}


class VectorExpression:
    """Three components, each a number or an :class:`Expression`: ``(x (N, 3)) -> (N, 3)``."""

    def __init__(self, components):
        self.components = list(components)

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, float)
        return np.stack([c(x) if callable(c) else np.full(len(x), float(c)) for c in self.components], axis=1)

    def __repr__(self) -> str:
        return f"VectorExpression({[str(c) for c in self.components]})"
