"""Exception type of the tiling package (derives from :class:`geometry.ToolkitError`)."""

from geometry.errors import ToolkitError


class TilingError(ToolkitError):
    """Invalid tile, paving request or micro-structure."""
