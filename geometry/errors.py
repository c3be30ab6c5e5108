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
