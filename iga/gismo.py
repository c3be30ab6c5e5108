"""G+Smo XML export of a heat problem, and import of a G+Smo multipatch as an analysis model.

:func:`export_gismo` writes the model's physical patches (each placed tile
patch composed exactly into the map, NURBS weights kept), the identity
interfaces with their orientation, the free sides, the boundary conditions
per side and the conductivity and source (:mod:`geometry.gismo_xml` holds the
format).  Conventions written into the file as a comment:

* ``Dirichlet``: the temperature (K or C);
* ``Neumann``: the inward heat flux q = k dT/dn (W/m^2), n the outward normal;
* ``Robin``: the ambient temperature, with ``coefficient`` the film
  coefficient h: -k dT/dn = h (T - ambient).

Every patch is written at one common degree (the largest after
composition; degree elevation is exact), so that sides glued in the model
stay conforming in the file.

What G+Smo's multipatch cannot say, and how it is written:

* branch interfaces (a child face constrained to a refinement of a
  sub-rectangle of its parent face, Massarwi et al. 2018, Eqs. 11-12): G+Smo
  topologies glue whole sides only; they go into ``<BranchInterfaces>`` (parent
  side, its sub-rectangle, child side), which G+Smo ignores, so a G+Smo
  solver sees those faces as free;
* slot faces (the free parts of discontinuity planes) are not sides and are
  left out of the boundary lists;
* conditions given as Python callables or channel names have no expression:
  export refuses them, naming the tag.

:func:`load_gismo` reads a G+Smo file back as a :class:`geometry.MultiPatch`
whose topology is detected from the geometry (and checked against the
file's interfaces).
"""

from __future__ import annotations

from pathlib import Path

from geometry import MultiPatch
from geometry.errors import SplineError, show
from geometry.faces import FACE_NAMES
from geometry.gismo_xml import GismoCondition, read_gismo, write_gismo

from .errors import ProblemError
from .model import tag_faces
from .problem import HeatProblem

__all__ = ["export_gismo", "load_gismo", "problem_from_gismo"]

_KINDS = {"dirichlet": "Dirichlet", "neumann": "Neumann", "robin": "Robin"}


def _expression(field, what) -> str:
    if field.kind != "number":
        raise ProblemError(f"{what} is a {field.kind}; G+Smo XML export writes constants only (a number), "
                           "evaluate it yourself or export the geometry alone with geometry.gismo_xml.write_gismo")
    return repr(float(field.spec))


def export_gismo(problem, path) -> Path:
    """Write ``problem`` (an :class:`iga.HeatProblem`) as a G+Smo XML multipatch heat problem (module notes)."""
    model = problem.model
    if any(p.spline.dim != 3 for p in model.patches):
        raise ProblemError("G+Smo export writes trivariate models")
    k = problem.conductivity
    if k.scalar is None or k.scalar.kind != "number":
        raise ProblemError("G+Smo export needs a constant isotropic conductivity (a number); this problem's is "
                           f"{'a tensor' if k.tensor else 'a ' + (k.scalar.kind if k.scalar else 'callable')}")
    try:
        patches = model.compose_all()
    except SplineError as exc:
        raise ProblemError(f"cannot compose the model's patches for export: {exc}") from None
    # Composition may raise degrees patch by patch (a rotated placement in a trilinear map gives degree 3):
    # one common degree keeps every glued pair of sides conforming for G+Smo (elevation is exact)
    top = max(max(p.degrees) for p in patches)
    patches = [p if p.degrees == (top,) * 3 else p.elevate_to((top,) * 3) for p in patches]
    identity = [(i.a, i.b, bool(i.swap), tuple(i.flip)) for i in model.interfaces if i.kind == "identity"]
    sides = [f for f in model.tags.get("boundary", []) if f[1] in FACE_NAMES]
    conditions = []
    for c in problem.conditions:
        faces = [f for f in tag_faces(model, c.tag) if f[1] in FACE_NAMES]
        expr = _expression(c.value, f"the {c.kind} value on {show(c.tag)}")
        coef = _expression(c.h, f"the film coefficient on {show(c.tag)}") if c.h is not None else None
        conditions.append(GismoCondition(_KINDS[c.kind], faces, expr, coef))
    functions = {"conductivity": repr(float(k.scalar.spec)),
                 "source": _expression(problem.source, "the heat source")}
    branches = [(i.a, i.box, i.b) for i in model.interfaces if i.kind == "branch"]
    return write_gismo(path, patches, identity, sides, conditions, functions, branches, comment=(
        "iga-microstructures heat problem: Dirichlet = temperature; Neumann = inward heat flux q = k dT/dn "
        "(W/m^2); Robin = ambient temperature with coefficient h: -k dT/dn = h (T - ambient)"))


def load_gismo(path) -> MultiPatch:
    """A G+Smo XML multipatch as a :class:`geometry.MultiPatch`: topology detected from the geometry.

    Identity interfaces are found where sides coincide and conform (and must
    include every pair the file glues); the file's ``<BranchInterfaces>``
    become refinement-matrix interfaces.  Without interfaces in the file,
    touching sides that do not conform are refused; with them, the file decides.  Extra tags: ``bc{j}``, the sides of
    the file's j-th boundary condition.
    """
    try:
        g = read_gismo(path)
        model = MultiPatch.from_splines(g.patches, branches=g.branches, check_contact=not g.interfaces)
    except SplineError as exc:
        raise ProblemError(str(exc)) from None
    found = {frozenset([i.a, i.b]) for i in model.interfaces}
    for a, b, *_ in g.interfaces:
        if frozenset([a, b]) not in found:
            raise ProblemError(f"{path}: the file glues patch {a[0]} {a[1]} to patch {b[0]} {b[1]}, but those "
                               "sides do not coincide in the geometry")
    for j, c in enumerate(g.conditions):
        model.tags[f"bc{j}"] = list(c.faces)
    model.gismo = g
    return model


def problem_from_gismo(path, **options):
    """The :class:`iga.HeatProblem` of a G+Smo heat problem file (constants only; ``options`` for HeatProblem).

    Conductivity and source come from the functions labelled ``conductivity``
    and ``source`` (default 1 and 0); each boundary condition applies to its
    tag ``bc{j}``.  Expressions must be numbers.
    """
    model = load_gismo(path)
    g = model.gismo

    def number(expr, what):
        try:
            return float(expr)
        except (TypeError, ValueError):
            raise ProblemError(f"{path}: {what} is {show(expr)}; only constant expressions (numbers) are read") \
                from None

    k = number(g.functions.get("conductivity", "1"), "the conductivity")
    problem = HeatProblem(model, conductivity=k, source=number(g.functions.get("source", "0"), "the source"),
                          **options)
    for j, c in enumerate(g.conditions):
        value = number(c.expression, f"the value of {c.kind} condition {j}")
        if c.kind == "Dirichlet":
            problem.dirichlet(f"bc{j}", value)
        elif c.kind == "Neumann":
            problem.neumann(f"bc{j}", value)
        else:
            problem.robin(f"bc{j}", number(c.coefficient, f"the coefficient of Robin condition {j}"), value)
    return problem
