"""Exception types of the toolkit.

Every user-facing error of the project derives from :class:`ToolkitError`, so a
script can catch them all with one ``except`` clause.  Each package keeps its
own subclasses in its ``errors`` module: ``geometry.SplineError`` here,
``tiling.TilingError``, ``iga.ProblemError`` and ``solvers.SolverError``.
:class:`ToolkitError` derives from :class:`ValueError`, so code that catches
ValueError for bad input keeps working.
"""


class ToolkitError(ValueError):
    """Base class of every error the toolkit raises for bad input."""


class SplineError(ToolkitError):
    """Invalid spline data or an operation a spline cannot perform."""


def show(value) -> str:
    """``repr`` of a value for a message, NumPy scalars and arrays shown as plain numbers and lists.

    ``show(np.float64(0.5))`` is ``0.5``, not ``np.float64(0.5)``; strings keep their quotes.
    """
    return repr(_plain(value))


def _plain(v):
    if hasattr(v, "item") and getattr(v, "shape", None) == ():  # NumPy scalar or 0-d array
        return v.item()
    if hasattr(v, "tolist") and hasattr(v, "shape"):
        return v.tolist()
    if isinstance(v, tuple):
        return tuple(_plain(x) for x in v)
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v


def check_seed(seed, error=SplineError) -> None:
    """Raise ``error`` unless ``seed`` is a non-negative integer (what numpy.random.default_rng takes)."""
    from .numbers import is_integer

    if not is_integer(seed) or seed < 0:
        raise error(f"seed must be a non-negative integer (the random generator's seed), got {show(seed)}")
