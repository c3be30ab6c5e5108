"""The [adapt] section of a pipeline: adaptive refinement by tiles of a steady heat analysis.

    [adapt]  tolerance = relative energy-norm error, max_unknowns = n, marking = fraction, refine = "h" |
             "h-in-place", max_steps = n

The analysis is solved by :func:`iga.adaptivity.loop.adaptive_solve`; the summary holds every step (unknowns,
patches, estimate, seconds) and why the loop stopped, the VTU the refinement of every patch as cell data.
"""

from __future__ import annotations

from iga.app.config_checks import choice, fail, integer, number, table
from iga.app.config_schema import allowed, filled, required
from iga.errors import ProblemError

__all__ = ["adapt_section"]


def adapt_section(config: dict, kind: str) -> dict | None:
    """The checked [adapt] section (None when absent); only a steady heat analysis adapts."""
    if "adapt" not in config:
        return None
    if kind != "heat":
        raise ProblemError(f"config section adapt refines a steady heat analysis (physics.kind = 'heat'), not "
                           f"{kind!r}; drop [adapt] or the other physics")
    a = filled("adapt", table(config["adapt"], "adapt", allowed("adapt"), required("adapt")))
    return {"tolerance": number(a["tolerance"], "adapt.tolerance", lo=0),
            "max_unknowns": None if a["max_unknowns"] is None else integer(a["max_unknowns"], "adapt.max_unknowns", 1),
            "marking": _marking(a["marking"]),
            "refine": choice(a["refine"], "adapt.refine", ("h", "h-in-place")),
            "max_steps": integer(a["max_steps"], "adapt.max_steps", 1)}


def _marking(v) -> float:
    m = number(v, "adapt.marking", lo=0)
    if m > 1:
        fail("adapt.marking", f"must lie in (0, 1] (the share of the squared estimate the marked patches carry), "
             f"got {m:g}")
    return m
