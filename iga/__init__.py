"""Isogeometric analysis on micro-structures: spaces, assembly, heat problem, VTU export.

The heat problem lands with the heat-transfer issue; the command line
(``iga --help``) is available now.
"""

from geometry.errors import ToolkitError


class ProblemError(ToolkitError):
    """Invalid analysis set-up: unknown tag, bad material data, bad output path..."""


__all__ = ["ProblemError"]
