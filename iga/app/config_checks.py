"""The primitive checks of a pipeline configuration: each validates one value and names its key in the error
(``config key solver.tol: must be a number in (0, 1), got 'small'``)."""

from __future__ import annotations

import inspect
from numbers import Real

from geometry.errors import show
from geometry.numbers import is_real

from iga.errors import ProblemError
from iga.expressions import Expression

__all__ = ["fail", "number", "formula", "formula_table", "integer", "boolean", "string", "choice", "ints", "table", "kwargs", "tag"]


def fail(where: str, message: str):
    raise ProblemError(f"config key {where}: {message}")


def number(v, where, lo=None, hi=None, open_lo=True) -> float:
    if not is_real(v) or v != v or v in (float("inf"), float("-inf")):
        fail(where, f"must be a finite number, got {show(v)}")
    if lo is not None and (v <= lo if open_lo else v < lo):
        fail(where, f"must be {'>' if open_lo else '>='} {lo}, got {show(v)}")
    if hi is not None and v >= hi:
        fail(where, f"must be < {hi}, got {show(v)}")
    return float(v)


def formula(v, where, lo=None):
    """A number (checked against ``lo``) or a formula of the position x, y, z written as a string
    (:class:`iga.expressions.Expression`, checked for its grammar now and for finite values where evaluated)."""
    if isinstance(v, str):
        return Expression(v, f"config key {where}")
    if not is_real(v):
        fail(where, f"must be a finite number or a formula of x, y, z in quotes (e.g. \"20 + 3000 * z\"), "
                    f"got {show(v)}")
    return number(v, where, lo=lo)


def formula_table(v, where):
    """A material given as ``{formula = "..."}`` (a string alone is a channel name there): the
    :class:`iga.expressions.Expression`, or None when ``v`` is not a table."""
    if not isinstance(v, dict):
        return None
    t = table(v, where, {"formula"}, ("formula",))
    if not isinstance(t["formula"], str):
        fail(f"{where}.formula", f"must be a formula of x, y, z in quotes (e.g. \"16 * (1 + x)\"), got "
                                 f"{show(t['formula'])}")
    return formula(t["formula"], f"{where}.formula")


def integer(v, where, lo=0) -> int:
    if not isinstance(v, int) or isinstance(v, bool):
        fail(where, f"must be an integer >= {lo}, got {show(v)}")
    if v < lo:
        fail(where, f"must be an integer >= {lo}, got {show(v)}")
    return int(v)


def boolean(v, where) -> bool:
    if not isinstance(v, bool):
        fail(where, f"must be true or false, got {show(v)}")
    return v


def string(v, where) -> str:
    if not isinstance(v, str) or not v:
        fail(where, f"must be a non-empty string, got {show(v)}")
    return v


def choice(v, where, choices) -> str:
    if not isinstance(v, str) or v not in choices:
        fail(where, f"must be one of {sorted(choices)}, got {show(v)}")
    return v


def ints(v, where, n, lo=1) -> list[int]:
    if not isinstance(v, list) or len(v) != n:
        fail(where, f"must be a list of {n} integers >= {lo}, got {show(v)}")
    return [integer(x, f"{where}[{i}]", lo) for i, x in enumerate(v)]


def table(v, where, allowed, required=()) -> dict:
    if not isinstance(v, dict):
        fail(where, f"must be a table, got {type(v).__name__} {show(v)}")
    unknown = sorted(set(v) - set(allowed))
    if unknown:
        raise ProblemError(f"unknown config key {where}.{show(unknown[0])}; allowed keys: {sorted(allowed)}")
    missing = [k for k in required if k not in v]
    if missing:
        raise ProblemError(f"missing required config key {where}.{show(missing[0])}")
    return dict(v)


def kwargs(v, where, fn) -> dict:
    """Keyword arguments for ``fn``, bound against its signature; values typed like the defaults."""
    if not isinstance(v, dict):
        fail(where, f"must be a table of keyword arguments, got {show(v)}")
    params = {n: p for n, p in inspect.signature(fn).parameters.items()
              if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    out = {}
    for key, value in v.items():
        if key not in params:
            fail(f"{where}.{key}", f"is not an argument of {fn.__name__}; allowed: {sorted(params)}")
        default = params[key].default
        w = f"{where}.{key}"
        if isinstance(default, bool):
            out[key] = boolean(value, w)
        elif isinstance(default, Real):
            out[key] = number(value, w)
            if isinstance(default, int) and not float(value).is_integer():
                fail(w, f"must be an integer, got {show(value)}")
            out[key] = int(value) if isinstance(default, int) else float(value)
        elif isinstance(default, (tuple, list)):
            if not isinstance(value, list) or len(value) != len(default):
                fail(w, f"must be a list of {len(default)} numbers, got {show(value)}")
            out[key] = tuple(number(x, f"{w}[{i}]", None) for i, x in enumerate(value))
            if all(isinstance(d, int) for d in default):
                if not all(float(x).is_integer() for x in out[key]):
                    fail(w, f"must be a list of {len(default)} integers, got {show(value)}")
                out[key] = tuple(int(x) for x in out[key])
        elif isinstance(default, str):
            out[key] = string(value, w)
        elif default is None and key == "channels":
            tbl = table(value, w, set(value)) if isinstance(value, dict) else fail(w, "must be a table {name = value}")
            out[key] = {str(n): number(x, f"{w}.{n}") for n, x in tbl.items()}
        else:
            out[key] = value
    return out


def tag(v, where):
    """A tag, a tag expression ('exterior - vmin', 'umin | umax', 'rest') or a list of them (their union)."""
    if isinstance(v, list):
        if not v:
            fail(where, "an empty list names no face; give tags, e.g. [\"umin\", \"umax\"]")
        return [string(x, f"{where}[{i}]") for i, x in enumerate(v)]
    return string(v, where)
