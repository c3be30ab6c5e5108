"""G+Smo XML export of a heat problem, and import of a G+Smo multipatch as an analysis model.

:func:`export_gismo` writes the model's physical patches (each placed tile
patch composed exactly into the map, NURBS weights kept), the identity
interfaces with their orientation, the free sides, the boundary conditions
per side and the conductivity and source (:mod:`geometry.io.gismo` holds the
format).  Conventions written into the file as a comment:

* ``Dirichlet``: the temperature (K or C);
* ``Neumann``: the inward heat flux q = k dT/dn (W/m^2), n the outward normal;
* ``Robin``: the ambient temperature, with ``coefficient`` the film
  coefficient h: -k dT/dn = h (T - ambient).

Every patch is written at one common degree (the largest after
composition; degree elevation is exact), so that sides glued in the model
stay conforming in the file.

What G+Smo's multipatch cannot say is written in the toolkit's own elements,
which G+Smo skips, named by a :class:`GismoExtensionWarning` (or refused with
``strict=True``); :func:`problem_from_gismo` reads them back:

* branch interfaces (a child face constrained to a refinement of a
  sub-rectangle of its parent face, Massarwi et al. 2018, Eqs. 11-12): G+Smo
  topologies glue whole sides only: ``<BranchInterfaces>`` (parent side, its
  sub-rectangle, child side);
* slot faces (the free parts of discontinuity planes) are not sides:
  ``<SlotFaces>`` (their rectangles) and ``<SlotConditions>`` (the conditions on them);
* a conductivity channel: ``<ChannelFunctions>`` (the channel values are in ``<Channels>``);
* the solution bases (each patch's tile basis, with the elevation, refinement,
  degree and quadrature of the exported problem): ``<AnalysisBases>``, so that
  the re-import analyses in the same spaces, not at the composed geometry's degree.

Numbers and formulas of x, y, z (:class:`iga.expressions.Expression`, what a
pipeline's quoted values are) are written as G+Smo expressions (``^`` for
powers, ``if`` for where; G+Smo's own parser evaluates them to round-off, tested
with pygismo) and read back; conditions given as Python functions have no
expression: export refuses them, naming the tag.

:func:`load_gismo` reads a G+Smo file back as a :class:`geometry.MultiPatch`
whose topology is detected from the geometry (and checked against the
file's interfaces).
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from geometry import MultiPatch
from geometry.errors import SplineError, show
from geometry.faces import FACE_NAMES
from geometry.io.gismo import GismoCondition, number_text, read_gismo, write_gismo

from iga.errors import ProblemError
from iga.expressions import Expression
from iga.heat.problem import HeatProblem

__all__ = ["export_gismo", "load_gismo", "problem_from_gismo", "GismoExtensionWarning"]

_KINDS = {"dirichlet": "Dirichlet", "neumann": "Neumann", "robin": "Robin"}


def _expression(field, what) -> str:
    """A number or a formula (:class:`iga.expressions.Expression`) in G+Smo's expression syntax."""
    if field.kind == "callable" and isinstance(field.spec, Expression):
        return field.spec.exprtk()
    if field.kind != "number":
        raise ProblemError(f"{what} is a {field.kind}; G+Smo XML export writes numbers and formulas of x, y, z "
                           "(iga.expressions.Expression, what pipelines write in quotes), not Python functions: "
                           "give it as Expression(\"...\"), or export the geometry alone with "
                           "geometry.io.gismo.write_gismo")
    return repr(float(field.spec))


class GismoExtensionWarning(UserWarning):
    """Part of an exported problem is written in elements of the toolkit's own, which G+Smo skips."""


def export_gismo(problem, path, strict: bool = False) -> Path:
    """Write ``problem`` (an :class:`iga.HeatProblem`) as a G+Smo XML multipatch heat problem (module notes).

    Everything the problem holds is written, so that :func:`problem_from_gismo` gives the same temperatures:
    what G+Smo's own format cannot say goes into elements of the toolkit's own (branch interfaces, conditions
    on slot faces, a conductivity channel, the solution bases), and a :class:`GismoExtensionWarning` names it;
    with ``strict`` the export refuses it instead, so that the file says nothing G+Smo does not read.
    """
    from iga.heat.problem import HeatProblem

    if not isinstance(problem, HeatProblem):
        raise ProblemError(f"G+Smo export writes heat problems (iga.HeatProblem), not {type(problem).__name__}: "
                           "G+Smo's XML holds no elasticity problem of this kind; export the model alone with "
                           "geometry.io.gismo, or write the elastic solution with iga.write_vtu")
    model = problem.model
    if any(p.spline.dim != 3 for p in model.patches):
        raise ProblemError("G+Smo export writes trivariate models")
    k = problem.conductivity
    formula = k.scalar is not None and k.scalar.kind == "callable" and isinstance(k.scalar.spec, Expression)
    if k.scalar is None or not (k.scalar.kind in ("number", "channel") or formula):
        raise ProblemError("G+Smo export needs an isotropic conductivity that is a number, a channel or a formula "
                           f"(iga.Expression); this problem's is {'a tensor' if k.tensor else 'a Python function'}: "
                           "evaluate it into a channel")
    identity = [(i.a, i.b, bool(i.swap), tuple(i.flip)) for i in model.interfaces if i.kind == "identity"]
    sides = [f for f in model.tags.get("boundary", []) if f[1] in FACE_NAMES]
    conditions, slot_conditions = [], []
    for j, c in enumerate(problem.conditions):
        if c.kind not in _KINDS:  # radiation: G+Smo's XML boundary conditions are linear
            raise ProblemError(f"the {c.kind} condition on {show(c.tag)} has no G+Smo XML form (its boundary "
                               "conditions are Dirichlet, Neumann and Robin); export the problem without it")
        faces = problem.tag_faces(c.tag)
        expr = _expression(c.value, f"the {c.kind} value on {show(c.tag)}")
        coef = _expression(c.h, f"the film coefficient on {show(c.tag)}") if c.h is not None else None
        conditions.append(GismoCondition(_KINDS[c.kind], [f for f in faces if f[1] in FACE_NAMES], expr, coef))
        slot_conditions += [(j, f) for f in faces if f[1] not in FACE_NAMES]
    functions = {"source": _expression(problem.source, "the heat source")}
    if k.scalar.kind != "channel":
        functions["conductivity"] = _expression(k.scalar, "the conductivity")
    branches = [(i.a, i.box, i.b) for i in model.interfaces if i.kind == "branch"]
    unseen = [what for what, n in ((f"{len(branches)} branch interfaces", len(branches)),
                                   (f"{len(slot_conditions)} conditions on slot faces", len(slot_conditions)),
                                   (f"the conductivity channel {show(k.scalar.spec)}", k.scalar.kind == "channel"))
              if n]
    if unseen and strict:
        raise ProblemError(f"G+Smo's format cannot hold {', '.join(unseen)} of this problem; export with "
                           "strict=False to write them in the toolkit's own elements (G+Smo skips them)")
    if unseen:
        warnings.warn(f"{path}: G+Smo itself will not see {', '.join(unseen)} (written in the toolkit's own "
                      "elements, which problem_from_gismo reads)", GismoExtensionWarning, stacklevel=2)
    try:
        patches = model.compose_all()
    except SplineError as exc:
        raise ProblemError(f"cannot compose the model's patches for export: {exc}") from None
    # Composition may raise degrees patch by patch (a rotated placement in a trilinear map gives degree 3):
    # one common degree keeps every glued pair of sides conforming for G+Smo (elevation is exact)
    top = max(max(p.degrees) for p in patches)
    patches = [p if p.degrees == (top,) * 3 else p.elevate_to((top,) * 3) for p in patches]
    extensions = _extensions(problem, slot_conditions, k)
    return write_gismo(path, patches, identity, sides, conditions, functions, branches, comment=(
        "iga-microstructures heat problem: Dirichlet = temperature; Neumann = inward heat flux q = k dT/dn "
        "(W/m^2); Robin = ambient temperature with coefficient h: -k dT/dn = h (T - ambient)"),
        extensions=extensions)


def _extensions(problem, slot_conditions, k) -> list:
    """The toolkit's own elements: solution bases and options, slot faces and their conditions, a
    conductivity channel."""
    model = problem.model
    q, e, r, d = problem.space_args
    opts = {"quadrature_extra": str(q), "degree_elevation": " ".join(map(str, np.atleast_1d(e))),
            "refine": str(r)}
    if d is not None:
        opts["degree"] = " ".join(map(str, d))
    bases = ET.Element("AnalysisBases", **opts)
    for i, (knots, degrees) in enumerate(problem.bases):
        b = ET.SubElement(bases, "Basis", patch=str(i))
        for U, p in zip(knots, degrees):
            ET.SubElement(b, "KnotVector", degree=str(p)).text = number_text(U)
    out = [bases]
    regions = getattr(model, "face_regions", {})
    if regions:
        out.append(ET.Element("SlotFaces", format="patch slot a1 b1 a2 b2"))
        out[-1].text = "\n" + "\n".join(f"{pi} {fid} " + number_text(rect)
                                          for (pi, fid), rects in regions.items() for rect in rects) + "\n"
    if slot_conditions:
        out.append(ET.Element("SlotConditions", format="condition patch slot"))
        out[-1].text = "\n" + "\n".join(f"{j} {pi} {fid}" for j, (pi, fid) in slot_conditions) + "\n"
    if k.scalar.kind == "channel":
        out.append(ET.Element("ChannelFunctions", conductivity=str(k.scalar.spec)))
    return out


def _read_slots(model, g, path) -> None:
    """Slot faces (``face_regions``) and the conditions on them (tags ``bc{j}``) from the toolkit's own
    elements of a G+Smo file, into ``model``."""
    root = g.root
    try:
        for el in root.iter("SlotFaces"):
            for line in (el.text or "").split("\n"):
                if line.strip():
                    pi, fid, *v = line.split()
                    model.face_regions.setdefault((int(pi), fid), []).append(
                        ((float(v[0]), float(v[1])), (float(v[2]), float(v[3]))))
        for el in root.iter("SlotConditions"):
            for line in (el.text or "").split("\n"):
                if line.strip():
                    j, pi, fid = line.split()
                    model.tags[f"bc{int(j)}"].append((int(pi), fid))
    except (ValueError, IndexError, KeyError) as exc:
        raise ProblemError(f"{path}: the toolkit's own <SlotFaces> / <SlotConditions> are malformed "
                           f"({type(exc).__name__}: {exc}); re-export the problem") from None


def _read_extensions(g, path) -> dict:
    """HeatProblem options (solution bases, conductivity channel) from the toolkit's own elements of a G+Smo
    file."""
    root, opts = g.root, {}
    try:
        el = root.find("AnalysisBases")
        if el is not None:
            opts["bases"] = [([np.array(kv.text.split(), float) for kv in b.iter("KnotVector")],
                              tuple(int(kv.get("degree")) for kv in b.iter("KnotVector"))) for b in el.iter("Basis")]
            opts["quadrature_extra"] = int(el.get("quadrature_extra", "0"))
            elev = [int(v) for v in el.get("degree_elevation", "0").split()]
            opts["degree_elevation"] = elev[0] if len(elev) == 1 else tuple(elev)
            opts["refine"] = int(el.get("refine", "0"))
            if el.get("degree"):
                opts["degree"] = tuple(int(v) for v in el.get("degree").split())
        el = root.find("ChannelFunctions")
        if el is not None and el.get("conductivity"):
            opts["conductivity"] = el.get("conductivity")
    except (ValueError, IndexError, KeyError, TypeError, AttributeError) as exc:
        raise ProblemError(f"{path}: the toolkit's own <AnalysisBases> / <ChannelFunctions> are "
                           f"malformed ({type(exc).__name__}: {exc}); re-export the problem") from None
    return opts


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
    _read_slots(model, g, path)  # slot faces and their conditions, written beside G+Smo's elements
    model.gismo = g
    return model


def problem_from_gismo(path, **options):
    """The :class:`iga.HeatProblem` of a G+Smo heat problem file (``options`` for HeatProblem).

    Conductivity and source come from the functions labelled ``conductivity``
    and ``source`` (default 1 and 0); each boundary condition applies to its
    tag ``bc{j}``.  Expressions are numbers or formulas of x, y, z in G+Smo's syntax with the operators and
    functions :class:`iga.expressions.Expression` reads (:meth:`~iga.expressions.Expression.from_exprtk`).
    """
    model = load_gismo(path)
    g = model.gismo

    def number(expr, what):  # a number, else a formula of x, y, z (what the export writes for formulas)
        try:
            return float(expr)
        except (TypeError, ValueError):
            return Expression.from_exprtk(expr, f"{path}: {what}")

    saved = _read_extensions(g, path)  # what the toolkit wrote beside G+Smo's elements
    if "conductivity" not in saved:
        saved["conductivity"] = number(g.functions.get("conductivity", "1"), "the conductivity")
    problem = HeatProblem(model, source=number(g.functions.get("source", "0"), "the source"),
                          **{**saved, **options})
    for j, c in enumerate(g.conditions):
        value = number(c.expression, f"the value of {c.kind} condition {j}")
        if c.kind == "Dirichlet":
            problem.dirichlet(f"bc{j}", value)
        elif c.kind == "Neumann":
            problem.neumann(f"bc{j}", value)
        else:
            problem.robin(f"bc{j}", number(c.coefficient, f"the coefficient of Robin condition {j}"), value)
    return problem
