"""Boundary tags and their algebra: ``"exterior - vmin"``, ``"umin | umax"``, ``"A & wmin"``, lists, ``"rest"``.

A tag names a set of (patch, face) pairs of a model.  An expression combines
tags with ``|`` (union), ``&`` (intersection) and `` - `` (difference: a minus
with spaces on both sides, since tag names such as ``branch-in`` hold
hyphens), left to right, ``&`` binding tighter, with parentheses.  A list (a
TOML array) is the union of its items.  A name that is itself a tag of the
model is always that tag.  ``rest`` means every free face that no other
condition of the problem covers; a problem resolves it once all its
conditions are known (:func:`resolve` with ``rest=``).
"""

from __future__ import annotations

import re

from geometry.errors import show

from .errors import ProblemError

__all__ = ["REST", "resolve", "check_expression", "mentions_rest", "as_expression", "parse_expression",
           "condition_faces"]

REST = "rest"
_TOKENS = re.compile(r"\s+-\s+|\||&|\(|\)")


def _tokens(expr: str) -> list[str]:
    out, pos = [], 0
    for m in _TOKENS.finditer(expr):
        name = expr[pos:m.start()].strip()
        if name:
            out.append(name)
        out.append(m.group().strip() or "-")
        pos = m.end()
    tail = expr[pos:].strip()
    if tail:
        out.append(tail)
    return out


def _parse(tokens: list[str], expr: str, leaf, what: str = "tag", example: str = "'exterior - vmin'"):
    """Recursive descent over ``tokens``; ``leaf(name)`` resolves the names to values that combine with ``|``,
    ``&`` and ``-`` (sets of faces; or the primitives of a V-model); ``what`` names them in messages."""
    pos = 0

    def fail(why: str):
        raise ProblemError(f"{what} expression {show(expr)}: {why}; combine {what}s with |, &, ' - ' and "
                           f"parentheses, e.g. {example}")

    def atom():
        nonlocal pos
        if pos >= len(tokens):
            fail(f"it ends where a {what} is expected")
        tok = tokens[pos]
        pos += 1
        if tok == "(":
            val = union()
            if pos >= len(tokens) or tokens[pos] != ")":
                fail("a parenthesis is not closed")
            pos += 1
            return val
        if tok in ("|", "&", "-", ")"):
            fail(f"{tok!r} stands where a {what} is expected")
        return leaf(tok)

    def term():
        nonlocal pos
        val = atom()
        while pos < len(tokens) and tokens[pos] == "&":
            pos += 1
            val = val & atom()
        return val

    def union():
        nonlocal pos
        val = term()
        while pos < len(tokens) and tokens[pos] in ("|", "-"):
            op = tokens[pos]
            pos += 1
            val = (val | term()) if op == "|" else (val - term())
        return val

    val = union()
    if pos != len(tokens):
        fail(f"{tokens[pos]!r} is left over")
    return val


def parse_expression(expr: str, leaf, what: str, example: str):
    """``expr`` combined by |, & and ' - ' (module notes) over the values ``leaf(name)`` gives its names."""
    return _parse(_tokens(expr), expr, leaf, what, example)


def resolve(model, tag, rest: list | None = None, unknown=None) -> list:
    """The (patch, face) pairs of a tag, an expression or a list of them, in the model's order.

    ``rest``: the faces ``rest`` stands for (None: ``rest`` is refused); ``unknown(name)`` raises for a name that
    is no tag (default: a :class:`ProblemError` listing the model's tags).
    """
    items = list(tag) if isinstance(tag, (list, tuple)) else [tag]
    if not items or not all(isinstance(t, str) and t.strip() for t in items):
        raise ProblemError(f"a boundary tag must be a non-empty string, an expression or a list of them, got "
                           f"{show(tag)}")
    order: dict = {}
    for faces in model.tags.values():
        for f in faces:
            order.setdefault(f, len(order))

    def leaf(name: str) -> set:
        if name in model.tags:
            return set(model.tags[name])
        if name == REST:
            if rest is None:
                raise ProblemError("the tag 'rest' (every free face no other condition covers) only names faces in "
                                   "a problem's boundary condition")
            return set(rest)
        (unknown or _unknown)(model, name)
        return set()

    out: set = set()
    for item in items:
        out |= leaf(item) if item in model.tags else _parse(_tokens(item), item, leaf)
    return sorted(out, key=lambda f: order.get(f, len(order)))


def as_expression(tag) -> str:
    """A tag, expression or list of them as one expression string (a list is the union of its items)."""
    if not isinstance(tag, (list, tuple)):
        return tag
    return " | ".join(f"({t})" if isinstance(t, str) and _TOKENS.search(t) else t for t in tag)


def mentions_rest(model, tag) -> bool:
    """Whether ``tag`` uses ``rest`` (then it resolves after the problem's other conditions)."""
    items = list(tag) if isinstance(tag, (list, tuple)) else [tag]
    return any(isinstance(t, str) and t not in model.tags and REST in _tokens(t) for t in items)


def condition_faces(faces: list, tag) -> list:
    """The faces a condition on ``tag`` resolved to, refused when there are none (a ``rest`` that the problem's
    other conditions leave empty)."""
    if not faces:
        raise ProblemError(f"tag {show(tag)} names no face here (the other conditions cover them all)")
    return faces


def check_expression(model, tag) -> None:
    """Refuse a malformed expression or an unknown name now (``rest`` is accepted: it resolves later)."""
    resolve(model, tag, rest=[])


def _unknown(model, name):
    known = sorted(model.tags, key=lambda t: (t.startswith("patch"), t))
    shown = known if len(known) <= 30 else known[:30] + ["..."]
    raise ProblemError(f"unknown boundary tag {show(name)}; this model has tags {shown}")
