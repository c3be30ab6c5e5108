"""Exception types of the toolkit.

Every user-facing error of the project derives from :class:`ToolkitError`, so a
script can catch them all with one ``except`` clause.  Each package adds its own
subclass (``geometry.SplineError``, ``tiling.TilingError``, ``iga.ProblemError``);
``solvers.SolverError`` lives in ``solvers`` because that package knows nothing
about splines, but it derives from :class:`ValueError` like the others.
"""


class ToolkitError(ValueError):
    """Base class of every error the toolkit raises for bad input."""


class SplineError(ToolkitError):
    """Invalid spline data or an operation a spline cannot perform."""
