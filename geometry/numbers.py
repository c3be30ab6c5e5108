"""What counts as a number, an integer and a flag in every public function's argument checks.

``isinstance(v, (int, float))`` refuses NumPy's scalars (``np.int64(1)`` as a radius: "must be a positive
length, got 1") and takes ``True`` as 1 (a bool is an int); the checks of the toolkit ask these helpers
instead, so a value is judged by what it is, whichever library made it.

:data:`TINY` is the one floor of a scale that is divided by: ``x / max(scale, TINY)`` where the scale may be
exactly zero (nothing flows, nothing moves), so the ratio stays finite and 0 / 0 reads as 0.
"""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np

__all__ = ["is_real", "is_integer", "is_flag", "TINY"]

#: the floor of a divisor that may be exactly zero (the smallest normal double is 2.2e-308)
TINY = 1e-300


def is_real(v) -> bool:
    """A real number: Python's or NumPy's int or float (finite or not: callers bound it); not a bool.

    >>> is_real(np.int64(1)), is_real(2.5), is_real(True), is_real("1")
    (True, True, False, False)
    """
    return isinstance(v, Real) and not isinstance(v, (bool, np.bool_))


def is_integer(v) -> bool:
    """An integer: Python's or NumPy's; not a bool, not a float (2.0 is a length, not a count).

    >>> is_integer(np.int32(3)), is_integer(3.0), is_integer(False)
    (True, False, False)
    """
    return isinstance(v, Integral) and not isinstance(v, (bool, np.bool_))


def is_flag(v) -> bool:
    """A boolean: Python's or NumPy's (1 and 0 are numbers, not flags).

    >>> is_flag(np.bool_(True)), is_flag(1)
    (True, False)
    """
    return isinstance(v, (bool, np.bool_))
