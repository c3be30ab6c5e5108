"""Linear solvers behind one backend-neutral interface (sparse matrices only).

This package knows nothing about splines; the backends land with the heat
transfer issue.
"""


class SolverError(ValueError):
    """A linear system that cannot be solved: singular, diverging or non-finite."""


__all__ = ["SolverError"]
