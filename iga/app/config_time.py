"""The [time] section of a pipeline (physics.kind = "transient-heat") and the heat capacity of its [material].

    [time]  end = seconds | "steady", step = s, tolerance = K, method = "bdf2" | "crank-nicolson" |
            "backward-euler" | "theta", theta, initial = number | formula, every = n, fraction, max_steps

``end = "steady"`` runs until the point of largest steady change (among the points no Dirichlet condition holds;
the hottest point of a part heated from the initial temperature) has changed by ``fraction`` (default 0.95)
of its steady change, with adaptive steps (``tolerance``); a number of seconds
runs to that time with fixed steps (``step``) or adaptive ones (``tolerance``, ``step`` the first).
``every``: every n-th step is kept and written to the ParaView series.
"""

from __future__ import annotations

from geometry.errors import show

from iga.app.config_checks import choice, fail, formula, formula_table, integer, number, string, table
from iga.app.config_schema import allowed, default, required
from iga.errors import ProblemError
from iga.heat.transient import SCHEMES

__all__ = ["time_section", "capacity", "TIME_SOLVERS"]

#: the solvers a transient run prepares once per step size (:func:`solvers.prepare`)
TIME_SOLVERS = ("auto", "direct", "amg-cg", "cg")


def time_section(config: dict, kind: str, solver_method: str) -> dict | None:
    """The checked [time] section for ``kind`` (None unless "transient-heat", which needs it)."""
    if kind != "transient-heat":
        if "time" in config:
            raise ProblemError(f"config section time applies to physics.kind = 'transient-heat', not {kind!r}")
        return None
    if "time" not in config:
        raise ProblemError("physics.kind = 'transient-heat' needs a [time] section (end, step or tolerance)")
    t = table(config["time"], "time", allowed("time"), required("time"))
    steady = isinstance(t["end"], str)
    if steady and t["end"] != "steady":
        fail("time.end", f"must be a number of seconds or \"steady\", got {show(t['end'])}")
    out = {"end": "steady" if steady else number(t["end"], "time.end", lo=0),
           "step": None if "step" not in t else number(t["step"], "time.step", lo=0),
           "tolerance": None if "tolerance" not in t else number(t["tolerance"], "time.tolerance", lo=0),
           "method": choice(t.get("method", default("time", "method")), "time.method", tuple(SCHEMES) + ("theta",)),
           "theta": None, "every": integer(t.get("every", default("time", "every")), "time.every", 1),
           "max_steps": integer(t.get("max_steps", default("time", "max_steps")), "time.max_steps", 1),
           "fraction": None, "initial": formula(t.get("initial", default("time", "initial")), "time.initial")}
    if out["method"] == "theta":
        if "theta" not in t:
            raise ProblemError("config key time.method = 'theta' needs time.theta in [0.5, 1]")
        out["theta"] = number(t["theta"], "time.theta")
        if not 0.5 <= out["theta"] <= 1:
            fail("time.theta", f"must be in [0.5, 1] (0.5 Crank-Nicolson, 1 backward Euler), got {show(t['theta'])}")
    elif "theta" in t:
        fail("time.theta", "applies to time.method = 'theta'")
    if steady:
        if out["tolerance"] is None:
            fail("time.end", "\"steady\" runs for as long as the part takes to settle: give time.tolerance (K, "
                 "the error allowed per step) for adaptive steps")
        out["fraction"] = number(t.get("fraction", default("time", "fraction")), "time.fraction", lo=0, hi=1)
    elif "fraction" in t:
        fail("time.fraction", "applies to time.end = \"steady\"")
    if out["step"] is None and out["tolerance"] is None:
        raise ProblemError("config section time needs step (s, fixed steps) or tolerance (K, adaptive steps)")
    if solver_method not in TIME_SOLVERS:
        fail("solver.method", f"a transient run prepares one of {list(TIME_SOLVERS)} per step size, got "
             f"{show(solver_method)}")
    return out


def capacity(material: dict, kind: str):
    """material.capacity (J/(m^3 K): a number, a channel name or a formula table) for a transient run."""
    if kind != "transient-heat":
        if "capacity" in material:
            fail("material.capacity", "applies to physics.kind = 'transient-heat' (the steady problem stores no "
                 "heat)")
        return None
    if "capacity" not in material:
        raise ProblemError("physics.kind = 'transient-heat' needs material.capacity (rho c in J/(m^3 K), e.g. "
                           "2.4e6 for aluminium)")
    v = material["capacity"]
    if isinstance(v, dict):
        return formula_table(v, "material.capacity")
    return string(v, "material.capacity") if isinstance(v, str) else number(v, "material.capacity", lo=0)
