"""G+Smo XML: multipatch geometry with topology, read and written exactly (interoperability with G+Smo).

Written (and read) elements, as G+Smo's ``gsXml`` does:

* ``<Geometry type="TensorBSpline{d}"|"TensorNurbs{d}" id=..>`` with a
  ``<Basis>`` of one ``BSplineBasis`` per direction (``<KnotVector
  degree=..>``), NURBS ``<weights>``, and ``<coefs geoDim="3">`` listed with
  the first parametric direction fastest;
* ``<MultiPatch parDim=.. id=..>`` with ``<patches type="id_range">``,
  ``<interfaces>`` (``p1 s1 p2 s2`` then the direction map and the direction
  orientation, d numbers each) and ``<boundary>`` (``patch side`` pairs);
  sides are numbered 1..2d: west, east, south, north, front, back
  (u = 0, u = 1, v = 0, v = 1, w = 0, w = 1);
* material channels, which G+Smo has no place for, as ``<Channels patch=..
  names="..">`` beside their geometry (G+Smo skips unknown elements);
* ``<boundaryConditions>`` and ``<Function>`` elements are passed through
  as :class:`GismoCondition` / strings (the analysis package fills them in).

Values are written with ``repr`` precision (17 significant digits), so the
round trip is bit-exact.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from geometry.bspline import BSpline
from geometry.errors import SplineError, show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.io.files import atomic_write

__all__ = ["GismoModel", "GismoCondition", "read_gismo", "write_gismo", "number_text", "side_number", "side_name",
           "interface_maps"]

BC_TYPES = ("Dirichlet", "Neumann", "Robin")


def side_number(face: str) -> int:
    """G+Smo's side index (1..6) of a face name (``umin`` .. ``wmax``)."""
    return FACE_NAMES.index(face) + 1


def side_name(number: int, dim: int = 3) -> str:
    """The face name of G+Smo side ``number``."""
    if not 1 <= int(number) <= 2 * dim:
        raise SplineError(f"G+Smo side {number} does not exist in {dim} dimensions (sides 1..{2 * dim})")
    return FACE_NAMES[int(number) - 1]


@dataclass
class GismoCondition:
    """A boundary condition: ``kind`` (Dirichlet, Neumann, Robin), faces [(patch, face)], an expression string.

    ``coefficient``: the Robin film coefficient (an expression string), else None.
    """

    kind: str
    faces: list
    expression: str
    coefficient: str | None = None


@dataclass
class GismoModel:
    """What a G+Smo XML file holds: patches, interfaces [(a, b, dir_map, dir_orient)], boundary, conditions."""

    patches: list
    interfaces: list = field(default_factory=list)
    boundary: list = field(default_factory=list)
    conditions: list = field(default_factory=list)
    functions: dict = field(default_factory=dict)  # {label: expression} (e.g. conductivity, source)
    branches: list = field(default_factory=list)  # [(parent (patch, face), box ((a, b), (c, d)), child (patch, face))]
    root: object = None  # the parsed XML root, for elements of the writer's own (write_gismo's extensions)


def interface_maps(a_face: str, b_face: str, swap: bool, flip) -> tuple[list, list]:
    """G+Smo's direction map and orientation (d = 3) of our face orientation (``swap``, ``flip``).

    Ours: point (s, t) of face a (its two in-face directions in order) is
    point (s', t') of face b, (s', t') = (t, s) if swap else (s, t), then
    reversed per ``flip`` (b's axes).  G+Smo: direction i of patch a runs
    along direction dir_map[i] of patch b, in the same sense if dir_orient[i].
    """
    ka, sa = FACE_AXIS[a_face]
    kb, sb = FACE_AXIS[b_face]
    ra = [j for j in range(3) if j != ka]
    rb = [j for j in range(3) if j != kb]
    dmap, orient = [0] * 3, [1] * 3
    dmap[ka], orient[ka] = kb, int(sa == sb)
    first, second = (ra[1], ra[0]) if swap else (ra[0], ra[1])  # a's directions landing on b's s' and t'
    dmap[first], orient[first] = rb[0], int(not flip[0])
    dmap[second], orient[second] = rb[1], int(not flip[1])
    return dmap, orient


def number_text(values) -> str:
    """Numbers as text, each with 17 significant digits (``repr`` of Python floats: exact round trip)."""
    return " ".join(map(repr, np.ravel(np.asarray(values, float)).tolist()))


def _write_patch(root, i: int, p: BSpline, d: int) -> None:
    """One ``<Geometry>`` element (and its ``<Channels>``) for patch ``i`` of parametric dimension ``d``."""
    kind = "Nurbs" if p.is_rational else "BSpline"
    tensor_name = f"Tensor{kind}" if d > 1 else kind  # G+Smo's curves are "BSpline" / "Nurbs"
    g = ET.SubElement(root, "Geometry", type=f"{tensor_name}{d if d > 1 else ''}", id=str(i))
    outer = ET.SubElement(g, "Basis", type=f"{tensor_name}Basis{d if d > 1 else ''}")
    if p.is_rational:
        tensor = ET.SubElement(outer, "Basis", type=f"TensorBSplineBasis{d}" if d > 1 else "BSplineBasis")
    else:
        tensor = outer
    for k in range(d):
        b = tensor if d == 1 else ET.SubElement(tensor, "Basis", type="BSplineBasis", index=str(k))
        ET.SubElement(b, "KnotVector", degree=str(p.degrees[k])).text = number_text(p.knots[k])
    order = tuple(range(d - 1, -1, -1))  # first parametric direction fastest
    if p.is_rational:
        ET.SubElement(outer, "weights").text = number_text(np.transpose(p.weights, order))
    cp = p.control_points
    ET.SubElement(g, "coefs", geoDim="3").text = number_text(np.transpose(cp[..., :3], order + (d,)))
    if p.channels:
        ET.SubElement(root, "Channels", patch=str(i), names=" ".join(p.channels)).text = number_text(
            np.transpose(cp[..., 3:], order + (d,)))


def _check_faces(n: int, d: int, interfaces, boundary, conditions, branches) -> None:
    """Every (patch, face) the topology names must be a patch index < n and a face of a d-variate patch."""
    for where, items in (("interfaces", [x for i in interfaces for x in i[:2]]), ("boundary", list(boundary)),
                         ("conditions", [f for c in conditions for f in c.faces]),
                         ("branches", [x for b in branches for x in (b[0], b[2])])):
        for pf in items:
            if (not isinstance(pf, tuple) or len(pf) != 2 or not isinstance(pf[0], (int, np.integer))
                    or not 0 <= pf[0] < n or pf[1] not in FACE_NAMES[:2 * d]):
                raise SplineError(f"{where}: {show(pf)} is not a (patch index < {n}, face name of a "
                                  f"{d}-variate patch) pair")


def write_gismo(path, patches, interfaces=(), boundary=(), conditions=(), functions=None, branches=(),
                comment: str = "", extensions=()) -> Path:
    """Write patches (geometry.BSpline, all of one parametric dimension) and their topology to G+Smo XML.

    ``interfaces``: [((pa, face_a), (pb, face_b), swap, flip)]; ``boundary``:
    [(patch, face)]; ``conditions``: [:class:`GismoCondition`]; ``functions``:
    {label: expression} written as ``<Function type="FunctionExpr">`` with that label;
    ``branches``: [(parent (patch, face), box, child (patch, face))] written as
    ``<BranchInterfaces>`` (G+Smo glues whole sides only and skips it);
    ``comment``: a line written at the top; ``extensions``: further ``xml.etree`` elements appended to the
    root (a writer's own data that G+Smo skips; :attr:`GismoModel.root` gives them back to its reader).
    """
    patches = list(patches)
    if not patches or not all(isinstance(p, BSpline) for p in patches):
        raise SplineError("write_gismo needs a non-empty list of geometry.BSpline patches")
    d = patches[0].dim
    if any(p.dim != d for p in patches):
        raise SplineError("G+Smo multipatches hold patches of one parametric dimension; got "
                          f"{sorted({p.dim for p in patches})}")
    root = ET.Element("xml")
    for i, p in enumerate(patches):
        _write_patch(root, i, p, d)
    mp = ET.SubElement(root, "MultiPatch", parDim=str(d), id=str(len(patches)))
    ET.SubElement(mp, "patches", type="id_range").text = f"0 {len(patches) - 1}"
    _check_faces(len(patches), d, interfaces, boundary, conditions, branches)
    if interfaces:
        lines = []
        for (pa, fa), (pb, fb), swap, flip in interfaces:
            dmap, orient = interface_maps(fa, fb, swap, flip)
            lines.append(" ".join(map(str, [pa, side_number(fa), pb, side_number(fb), *dmap, *orient])))
        ET.SubElement(mp, "interfaces").text = "\n" + "\n".join(lines) + "\n"
    if boundary:
        ET.SubElement(mp, "boundary").text = " ".join(f"{p} {side_number(f)}" for p, f in boundary)
    next_id = len(patches) + 1
    if conditions:
        bcs = ET.SubElement(root, "boundaryConditions", multipatch=str(len(patches)), id=str(next_id))
        for j, c in enumerate(conditions):
            if c.kind not in BC_TYPES:
                raise SplineError(f"boundary condition type {show(c.kind)} is not one of {list(BC_TYPES)}")
            ET.SubElement(bcs, "Function", type="FunctionExpr", dim=str(d), index=str(j)).text = c.expression
            attrs = {"type": c.kind, "function": str(j), "unknown": "0"}
            if c.coefficient is not None:
                attrs["coefficient"] = c.coefficient
            ET.SubElement(bcs, "bc", **attrs).text = " ".join(f"{p} {side_number(f)}" for p, f in c.faces)
        next_id += 1
    for label, expr in (functions or {}).items():
        ET.SubElement(root, "Function", type="FunctionExpr", dim=str(d), id=str(next_id), label=label).text = expr
        next_id += 1
    if branches:
        ET.SubElement(root, "BranchInterfaces", format="parent side box(4) child side").text = "\n" + "\n".join(
            f"{a[0]} {side_number(a[1])} {number_text(np.ravel(box))} {c[0]} {side_number(c[1])}" for a, box, c in branches)
    for el in extensions:
        root.append(el)
    ET.indent(root)
    data = ET.tostring(root, encoding="unicode")
    head = '<?xml version="1.0" encoding="UTF-8"?>\n' + (f"<!-- {comment} -->\n" if comment else "")

    def write(tmp):
        Path(tmp).write_text(head + data + "\n")

    return atomic_write(path, write, ".xml")


def _int_attr(node, name, path, what, default=None) -> int:
    """An integer attribute, or a SplineError naming the file, the element and the attribute."""
    raw = node.get(name)
    if raw is None:
        if default is None:
            raise SplineError(f"{path}: {what} has no {name} attribute")
        return default
    try:
        return int(raw)
    except ValueError:
        raise SplineError(f"{path}: {what}: attribute {name}={show(raw)} is not an integer") from None


def _numbers(node, what, path, dtype=float) -> np.ndarray:
    try:
        parts = (node.text or "").split()
        if dtype is float:  # float() on the strings is several times faster than NumPy's string conversion
            return np.array(list(map(float, parts)), dtype=float)
        return np.array(parts, dtype=dtype)
    except ValueError:
        raise SplineError(f"{path}: {what} must be numbers, got {show((node.text or '')[:60])}") from None


def read_gismo(path) -> GismoModel:
    """Read a G+Smo XML file: its tensor B-spline / NURBS geometries, multipatch topology and conditions.

    Unsupported geometry types (e.g. hierarchical THB splines) and boundary
    condition types raise :class:`SplineError` naming them.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SplineError(f"{path}: malformed XML ({exc}); is it a G+Smo file?") from None
    except OSError as exc:
        raise SplineError(f"cannot read {path}: {exc.strerror or exc}") from None
    geos, ids = _geometries(root, path)
    model = GismoModel(geos, root=root)
    mp = next(root.iter("MultiPatch"), None)
    if mp is not None:
        order = _patch_order(mp, ids, path)
        model.patches = [geos[j] for j in order]
        position = {g: k for k, g in enumerate(order)}
        local = {int(i): position[j] for i, j in ids.items() if j in position and i.lstrip("-").isdigit()}
        model.interfaces = _interfaces(mp, local, geos[0].dim, path)
        b = mp.find("boundary")
        if b is not None:
            v = _numbers(b, "boundary", path, int).reshape(-1, 2)
            model.boundary = [(_patch(local, p, path), side_name(s, geos[0].dim)) for p, s in v]
    model.conditions += _conditions(root, len(model.patches), path)
    for f in root.findall("Function"):
        if f.get("label"):
            model.functions[f.get("label")] = (f.text or "").strip()
    model.branches += _branches(root, len(model.patches), path)
    return model


def _geometries(root, path):
    """The ``<Geometry>`` patches with their channels, and {id: index}."""
    geos, ids = [], {}
    for g in root.iter("Geometry"):
        gtype = g.get("type", "")
        if gtype not in ("BSpline", "Nurbs", "TensorBSpline2", "TensorBSpline3", "TensorNurbs2", "TensorNurbs3"):
            raise SplineError(f"{path}: geometry type {show(gtype)} (id {g.get('id')}) is not supported; the "
                              "toolkit reads BSpline, Nurbs, TensorBSpline2-3 and TensorNurbs2-3")
        gid = g.get("id", str(len(geos)))
        if gid in ids:
            raise SplineError(f"{path}: two <Geometry> elements have id {show(gid)}; ids must be unique")
        ids[gid] = len(geos)
        geos.append(_geometry(g, path))
    if not geos:
        raise SplineError(f"{path}: no <Geometry> element; a G+Smo multipatch file holds at least one")
    for c in root.iter("Channels"):
        i = ids.get(c.get("patch", ""))
        if i is None:
            raise SplineError(f"{path}: <Channels> refers to unknown patch {show(c.get('patch'))}")
        names = (c.get("names") or "").split()
        p = geos[i]
        values = _numbers(c, "channel values", path)
        if values.size != int(np.prod(p.shape)) * len(names):
            raise SplineError(f"{path}: patch {c.get('patch')} has {values.size} channel values for "
                              f"{len(names)} channels of {int(np.prod(p.shape))} control points")
        d = p.dim
        ch = np.transpose(values.reshape(tuple(reversed(p.shape)) + (len(names),)), tuple(range(d - 1, -1, -1)) + (d,))
        geos[i] = BSpline(p.degrees, p.knots, np.concatenate([p.control_points, ch], -1), p.weights, names)
    return geos, ids


def _conditions(root, n: int, path) -> list:
    """The ``<bc>`` entries of every ``<boundaryConditions>`` on the n patches of the multipatch."""
    out = []
    for bcs in root.iter("boundaryConditions"):
        funcs = {f.get("index"): (f.text or "").strip() for f in bcs.iter("Function")}
        for bc in bcs.iter("bc"):
            kind = bc.get("type", "")
            if kind not in BC_TYPES:
                raise SplineError(f"{path}: boundary condition type {show(kind)} is not supported (the heat "
                                  f"problem has {list(BC_TYPES)})")
            v = _numbers(bc, "boundary condition sides", path, int)
            if v.size % 2 or (v.size and (v[::2].min() < 0 or v[::2].max() >= n)):
                raise SplineError(f"{path}: a {kind} <bc> lists {show(v.tolist()[:6])}: not (patch, side) pairs of "
                                  f"patches 0..{n - 1}")
            v = v.reshape(-1, 2)
            out.append(GismoCondition(kind, [(int(p), side_name(s)) for p, s in v],
                                                   funcs.get(bc.get("function"), ""), bc.get("coefficient")))
    return out


def _branches(root, n: int, path) -> list:
    """The rows of ``<BranchInterfaces>``: (parent (patch, side), box, child (patch, side))."""
    out = []
    for b in root.iter("BranchInterfaces"):
        v = _numbers(b, "branch interfaces", path)
        if v.size % 8:
            raise SplineError(f"{path}: <BranchInterfaces> holds {v.size} numbers, not groups of 8 "
                              "(parent side, box a b c d, child side)")
        for row in v.reshape(-1, 8):
            for pi in (row[0], row[6]):
                if pi != int(pi) or not 0 <= int(pi) < n:
                    raise SplineError(f"{path}: <BranchInterfaces> names patch {show(float(pi))}, which is not in "
                                      f"the multipatch (0..{n - 1})")
            out.append(((int(row[0]), side_name(int(row[1]))), ((row[2], row[3]), (row[4], row[5])),
                                   (int(row[6]), side_name(int(row[7])))))
    return out


def _index(basis, g, path) -> int:
    """A tensor basis's ``index`` attribute (its direction, 0 when absent), refused unless a whole number."""
    text = basis.get("index", "0")
    try:
        return int(text)
    except ValueError:
        raise SplineError(f"{path}: geometry {g.get('id')} has a <Basis index={show(text)}>; the index of a "
                          "direction's basis is a whole number (0, 1, 2)") from None


def _geometry(g, path) -> BSpline:
    basis = g.find("Basis")
    if basis is None:
        raise SplineError(f"{path}: geometry {g.get('id')} has no <Basis>")
    rational = "Nurbs" in basis.get("type", "")
    tensor = basis.find("Basis") if rational else basis
    weights = basis.find("weights") if rational else None
    if tensor is None:
        raise SplineError(f"{path}: geometry {g.get('id')} has a NURBS basis without its B-spline basis")
    parts = [tensor] if tensor.get("type") == "BSplineBasis" else sorted(tensor.findall("Basis"),
                                                                          key=lambda b: _index(b, g, path))
    if not parts:
        raise SplineError(f"{path}: geometry {g.get('id')} has no BSplineBasis")
    degrees, knots = [], []
    for b in parts:
        kv = b.find("KnotVector")
        if kv is None:
            raise SplineError(f"{path}: geometry {g.get('id')} has a basis without <KnotVector>")
        degrees.append(_int_attr(kv, "degree", path, f"geometry {g.get('id')}: <KnotVector>"))
        knots.append(_numbers(kv, "knots", path))
    coefs = g.find("coefs")
    if coefs is None:
        raise SplineError(f"{path}: geometry {g.get('id')} has no <coefs>")
    gdim = _int_attr(coefs, "geoDim", path, f"geometry {g.get('id')}: <coefs>", 3)
    values = _numbers(coefs, "coefficients", path)
    shape = tuple(len(U) - p - 1 for U, p in zip(knots, degrees))
    for k, (U, p) in enumerate(zip(knots, degrees)):
        if p < 1 or len(U) < p + 2:
            raise SplineError(f"{path}: geometry {g.get('id')}: direction {k} has degree {p} and {len(U)} knots; a "
                              f"degree >= 1 needs at least degree + 2 knots")
    d = len(shape)
    if values.size != int(np.prod(shape)) * gdim or gdim < 1 or gdim > 3:
        raise SplineError(f"{path}: geometry {g.get('id')} has {values.size} coefficients, expected "
                          f"{int(np.prod(shape))} points of dimension {gdim} (<= 3)")
    cp = np.transpose(values.reshape(tuple(reversed(shape)) + (gdim,)), tuple(range(d - 1, -1, -1)) + (d,))
    if gdim < 3:
        cp = np.concatenate([cp, np.zeros(shape + (3 - gdim,))], -1)
    w = None
    if weights is not None:
        wv = _numbers(weights, "weights", path)
        if wv.size != int(np.prod(shape)):
            raise SplineError(f"{path}: geometry {g.get('id')} has {wv.size} weights for {int(np.prod(shape))} "
                              "control points; give one weight per control point")
        w = np.transpose(wv.reshape(tuple(reversed(shape))), tuple(range(d - 1, -1, -1)))
    try:
        return BSpline(tuple(degrees), knots, cp, w)
    except SplineError as exc:
        raise SplineError(f"{path}: geometry {g.get('id')}: {exc}") from None


def _patch_order(mp, ids, path) -> list:
    node = mp.find("patches")
    if node is None:
        return list(range(len(ids)))
    v = _numbers(node, "patches", path, int)
    if node.get("type") == "id_range":
        if v.size != 2 or v[1] < v[0] or v[1] - v[0] + 1 > len(ids):
            raise SplineError(f"{path}: <patches type=\"id_range\"> must give first and last id of at most "
                              f"{len(ids)} defined geometries, got {show(v.tolist()[:4])}")
        v = np.arange(v[0], v[1] + 1)
    names = [str(x) for x in v]
    missing = [n for n in names if n not in ids]
    if missing:
        raise SplineError(f"{path}: the multipatch names patches {missing} that the file does not define")
    return [ids[n] for n in names]


def _patch(local, pid, path) -> int:
    if int(pid) not in local:
        raise SplineError(f"{path}: the topology refers to patch id {int(pid)}, which is not in the multipatch")
    return local[int(pid)]


def _interfaces(mp, local, d, path) -> list:
    node = mp.find("interfaces")
    if node is None:
        return []
    v = _numbers(node, "interfaces", path, int)
    if v.size % (4 + 2 * d):
        raise SplineError(f"{path}: interfaces hold {v.size} numbers, not groups of {4 + 2 * d} "
                          "(patch side patch side, direction map, orientation)")
    out = []
    for row in v.reshape(-1, 4 + 2 * d):
        out.append(((_patch(local, row[0], path), side_name(row[1], d)), (_patch(local, row[2], path),
                                                                           side_name(row[3], d)),
                    [int(x) for x in row[4:4 + d]], [int(x) for x in row[4 + d:]]))
    return out
