"""Exception type of the solvers package.

``solvers`` knows nothing about splines; it imports only the toolkit's base
exception from :mod:`geometry.errors` (a module without dependencies), so that
one ``except ToolkitError`` clause catches every error of the toolkit.
"""

from geometry.errors import ToolkitError


class SolverError(ToolkitError):
    """A linear system that cannot be solved: singular, diverging or non-finite."""
