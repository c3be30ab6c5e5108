"""Tiles, pavings and the Microstructure model (see issue: tiling).

Built on :mod:`geometry`; the paving schemes land with the tiling issue.
"""

from geometry.errors import ToolkitError


class TilingError(ToolkitError):
    """Invalid tile, paving request or micro-structure."""


__all__ = ["TilingError"]
