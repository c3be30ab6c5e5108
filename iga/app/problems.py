"""The heat problems a pipeline configures: the model, the [material] and [solver] sections, the [[bc]] tables."""

from __future__ import annotations

from iga.heat.problem import HeatProblem

__all__ = ["heat_problem"]


def heat_problem(cfg: dict, ms, cls=HeatProblem, **extra):
    """The configured heat problem (a ``cls``, :class:`iga.HeatProblem` or
    :class:`iga.TransientHeatProblem` with its ``extra`` arguments) on the model ``ms`` with its conditions."""
    mat, scfg = cfg["material"], cfg["solver"]
    prob = cls(ms, conductivity=mat["conductivity"], source=mat["source"], refine=scfg["refine"],
               degree_elevation=scfg["degree_elevation"], degree=scfg["degree"],
               quadrature_extra=scfg["quadrature_extra"], **extra)
    for bc in cfg["bc"]:
        if bc["kind"] == "dirichlet":
            prob.dirichlet(bc["tag"], bc["value"])
        elif bc["kind"] == "neumann":
            prob.neumann(bc["tag"], bc["value"])
        elif bc["kind"] == "radiation":
            prob.radiation(bc["tag"], bc["emissivity"], bc["ambient"], bc["scale"])
        else:
            prob.robin(bc["tag"], bc["h"], bc["ambient"])
    return prob
