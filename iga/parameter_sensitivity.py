"""Exact sensitivities of heat outputs (and of an elastic solution's compliance, :mod:`iga.elasticity.shape`) with
respect to the parameter field of a field-graded micro-structure (:func:`tiling.field_graded`): the derivative
of an output J by the values of the field on the cell walls (``wrt="faces"``) or by the field's control values
(``wrt="parameters"``), from one adjoint solve (none for the compliance, which is self-adjoint).

Every patch of a field-graded paving is x = D(A T(xi) + b) with T a patch of the tile ``family(umin=..,
wmax=..)`` of its cell's six wall values theta.  Changing a wall value moves the control points T_i of the two
tiles that share the wall, so every material point xi of them moves by the velocity

    V(xi) = D'(y) A dT(xi),    dT(xi) = sum_i R_i(xi) dT_i / dtheta,    y = A T(xi) + b,

(R_i the tile patch's basis, NURBS where it has weights).  Both tiles shape the wall from its value alone, so
they move it alike: the identity interfaces stay identities, and the shape derivative of
:func:`iga.shape_sensitivity.shape_densities` holds for this V as for a move of the map: dJ = sum_q Q_q :
grad V_q.  With J_x = D'(y) A T'(xi) (dx/dxi) and G = Q J_x^-T,

    Q : grad V = sum_aj G_aj dV_a/dxi_j,   dV/dxi_j = D''(y)[A dT, A T'_j] + D'(y) A d(dT)/dxi_j,

so dJ/dT_i = sum_q R_i(xi_q) A^T s_q + sum_j d_j R_i(xi_q) A^T D'^T G e_j, s_b = sum_aj G_aj D''_abc (A T'_j)_c:
one pass over the Gauss points and the boundary faces with the tile's own basis tables.  A conductivity read
from a channel k of D is not carried by this move (the point xi reads k at a moved y): its change
dk = grad_y k . A dT adds -grad lambda . grad T dk to the volume density.

The tile's control points as functions of the wall values come from the family itself: for a family marked
``affine_in_values`` (its control points affine in the six values, e.g. :func:`tiling.library.face_graded_cross`)
one central difference per value, exact to round-off, the same for every tile; for other families a Richardson
extrapolation of central differences per tile (error O(h^4); the geometry only, no analysis).  The wall values
are linear in the field's control values (a channel of D: its basis at the wall centres; a parameter spline:
its basis at the normalised centres; a number: their sum), which gives ``wrt="parameters"``.

Refused with :class:`iga.errors.ProblemError`: models not built by :func:`tiling.field_graded` (or refined by
splitting tiles), fields given as callables for ``wrt="parameters"`` (no control values; ``wrt="faces"``
works), sources and face data read from channels of D, anisotropic conductivities read from channels, families
whose tiles change structure with the values, and everything :func:`shape_densities` refuses.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry import SplineFunction
from geometry.errors import show
from geometry.numbers import is_real
from tiling import TilingError
from tiling.graded_layers import spline_parameters

from iga.adjoint import map_basis, map_basis_values, shape_map
from iga.errors import ProblemError
from iga.outputs import Output
from iga.shape_sensitivity import face_plane, shape_densities, steady_heat

__all__ = ["parameter_sensitivity", "tile_derivatives"]

#: the relative step of the central differences of a family's control points in its values
STEP = 1e-3


def parameter_sensitivity(solution, output: Output, wrt: str = "parameters", solver: str = "auto"):
    """dJ/d(field) of ``output`` on a field-graded micro-structure (module notes; a hierarchical sink whose leaves
    are graded, :func:`tiling.leaf_graded`, alike): ``wrt="faces"`` gives a tuple of three arrays shaped like
    ``model.grading.faces`` (per wall value; for graded leaves one array, per ``model.grading.site_centres``),
    ``wrt="parameters"`` an array shaped like
    the field's control values (a channel of D: D's control grid (n1, n2, n3); a parameter spline: its
    coefficients' grid; a number: a 0-d array).  Units: those of J per unit of the field."""
    what = f"wrt={wrt!r}"
    steady_heat(solution, what)
    prob = solution.problem
    ms = prob.model
    grading = getattr(ms, "grading", None)
    if grading is None:
        raise ProblemError(f"{what} differentiates by the parameter field of a field-graded micro-structure "
                           "(tiling.field_graded, tiling.leaf_graded); this model has none")
    if wrt == "parameters" and not isinstance(grading.field, (str, SplineFunction)) and not is_real(grading.field):
        raise ProblemError("wrt='parameters': the field is a callable, which has no control values; give the field "
                           "as a parameter spline (geometry.SplineFunction) or a channel of the map, or ask "
                           "wrt='faces' for the derivative by the values on the cell walls")
    D, _ = shape_map(prob)  # (placed: every patch is, _check_model)
    _check_model(ms, D)
    drag = _dragged_channel(prob, D, what)
    per_patch = _patch_gradients(solution, output, D, drag, solver, what)
    walls = _wall_gradients(ms, grading, per_patch)
    return grading.unflatten(walls) if wrt == "faces" else _field_gradient(grading, walls, D)


def _check_model(ms, D) -> None:
    """Every patch the tile's own patch in its cell (not split or refined by adaptivity), placed in D."""
    for i, p in enumerate(ms.patches):
        if p.outer is not D or p.refinement or p.spline is not ms.tiles[p.tile].patches[p.patch_in_tile]:
            raise ProblemError(f"wrt='parameters': patch {i} is not its tile's patch placed in the map (a model "
                               "refined by splitting tiles); differentiate the field-graded paving itself")


def _dragged_channel(prob, D, what: str):
    """The index of D's channel an isotropic conductivity (elasticity: Young's modulus) reads (its values move with
    the points: the drag term of the module notes), or None; sources, face data (Poisson's ratio) must not read
    D's channels."""
    # (a channel the map holds is read from the map, before an equally named channel of the tile)
    if hasattr(prob, "material"):
        from iga.elasticity.shape import drag_channel

        if prob.material.kind == "isotropic" and prob.poisson.kind == "channel" and prob.poisson.spec in D.channels:
            raise ProblemError(f"{what}: Poisson's ratio reads the map's channel {show(prob.poisson.spec)}; its "
                               "term is not built (give a number)")
        name = drag_channel(prob)  # Young's modulus, or a cubic material's table parameter
        return list(D.channels).index(name) if name is not None and name in D.channels else None
    k = prob.conductivity
    if k.channels is not None and any(c in D.channels for c in k.channels):
        raise ProblemError(f"{what}: an anisotropic conductivity read from channels of the map is not supported "
                           "(give the six components as numbers or an isotropic channel)")
    if prob.source.kind == "channel" and prob.source.spec in D.channels:
        raise ProblemError(f"{what}: the source reads the map's channel {show(prob.source.spec)}; give a number")
    for c in prob.conditions:
        for field in (c.value, c.h):
            if getattr(field, "kind", None) == "channel" and field.spec in D.channels:
                raise ProblemError(f"{what}: the {c.kind} data on {show(c.tag)} read the map's channel "
                                   f"{show(field.spec)}; give numbers")
    if k.scalar is not None and k.scalar.kind == "channel" and k.scalar.spec in D.channels:
        return list(D.channels).index(k.scalar.spec)  # (a tile's own channel moves with its points: no drag)
    return None


def _basis_key(T, axes, sides) -> tuple:
    """What T's basis on the grid ``axes`` depends on: the tiles of a graded paving share knots and degrees."""
    return (T.degrees, tuple(sides or ("right",) * 3), tuple(np.asarray(U).tobytes() for U in T.knots),
            tuple(np.asarray(v, float).tobytes() for v in axes),
            None if T.weights is None else np.asarray(T.weights, float).tobytes())


def _tile_basis(T, axes, sides=None):
    """T's basis on the grid ``axes`` (three 1-D arrays, C order; ``sides`` per direction "left"/"right" for a
    limit at a break): sparse (N, n) values and the three first derivatives, NURBS where T has weights
    (:func:`iga.adjoint.map_basis_values`)."""
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    idx, R, dR = map_basis_values(T, grid, derivatives=True, sides=sides)
    rows = np.repeat(np.arange(len(grid)), idx.shape[1])
    shape = (len(grid), int(np.prod(T.control_points.shape[:3])))

    def csr(values):
        return sp.csr_matrix((values.ravel(), (rows, idx.ravel())), shape=shape)

    return csr(R), [csr(d) for d in dR]


def _against_tile(patches, members, D, drag, B, dB, Qw, dk):
    """dJ/dT_i (P, n, 3) for the placed patches ``members`` (tile splines of one basis B, dB on N points each)
    from their densities Qw (P N, 3, 3) and dk (P N,) (module notes)."""
    P, n = len(members), B.shape[0]
    cps = np.stack([patches[i].spline.control_points[..., :3].reshape(-1, 3) for i in members], axis=1)  # (m, P, 3)
    flat = cps.reshape(len(cps), -1)
    vT = (B @ flat).reshape(n, P, 3).transpose(1, 0, 2)  # (P, N, 3)
    JT = np.stack([(d @ flat).reshape(n, P, 3) for d in dB], axis=-1).transpose(1, 0, 2, 3)  # (P, N, 3 [c], 3 [j])
    A = np.stack([patches[i].placement[:, :3] for i in members])  # (P, 3, 3)
    b = np.stack([patches[i].placement[:, 3] for i in members])
    y = np.clip((np.einsum("pab,pnb->pna", A, vT) + b[:, None]).reshape(-1, 3), D.domain[:, 0], D.domain[:, 1])
    Y = np.einsum("pab,pnbj->pnaj", A, JT).reshape(-1, 3, 3)  # dy/dxi
    der = D.derivatives(y, 2)
    e = np.eye(3, dtype=int)
    D1 = np.stack([der[tuple(e[k])][:, :3] for k in range(3)], axis=-1)  # (M, 3, 3) [x_a, y_b]
    D2 = np.empty(D1.shape + (3,))
    for i in range(3):
        for j in range(i, 3):
            D2[..., i, j] = D2[..., j, i] = der[tuple(e[i] + e[j])][:, :3]
    G = np.einsum("qaj,qkj->qak", Qw, np.linalg.inv(np.einsum("qab,qbj->qaj", D1, Y)))  # Q J_x^-T
    s = np.einsum("qabc,qcj->qabj", D2, Y)
    s = np.einsum("qaj,qabj->qb", G, s)
    if drag is not None:
        s += dk[:, None] * np.stack([der[tuple(e[k])][:, 3 + drag] for k in range(3)], axis=-1)
    t = np.einsum("qaj,qab->qjb", G, D1)  # (M, j, b): D'^T G e_j
    to_T = lambda v: v.reshape(P, n, 3).transpose(1, 0, 2).reshape(n, -1)  # noqa: E731  (N, P 3)
    g = B.T @ to_T(s) + sum(dB[j].T @ to_T(t[:, j]) for j in range(3))  # (m, P 3): dJ/d(A T_i)
    return np.einsum("mpb,pbe->pme", g.reshape(len(g), P, 3), A)  # back through A


def _patch_gradients(solution, output, D, drag, solver, what) -> dict:
    """{patch: dJ/dT (n, 3)} for every patch of the model (the tile patch's control points' coordinates): the
    densities of the volume and face passes kept per basis (tile knots, grid) and contracted in batches."""
    prob = solution.problem
    patches = prob.model.patches
    grads = {i: np.zeros((int(np.prod(p.spline.control_points.shape[:3])), 3)) for i, p in enumerate(patches)}
    pending: dict = {}

    def defer(i, axes, sides, Qw, dk):
        T = patches[i].spline
        key = _basis_key(T, axes, sides)
        pending.setdefault(key, (T, axes, sides, []))[3].append((i, Qw, dk))

    def volume(chunk, space, Qw, dk):
        n = len(Qw) // len(chunk)
        for j, i in enumerate(chunk):
            defer(i, space.qaxes, None, Qw[j * n:(j + 1) * n], dk[j * n:(j + 1) * n])

    def faces(fds, Qw):
        start = 0
        for fd in fds:
            axes, sides = _face_axes(patches[fd.patch].spline, fd.face, prob.spaces[fd.patch])
            m = len(fd.normal)
            defer(fd.patch, axes, sides, Qw[start:start + m], np.zeros(m))
            start += m

    shape_densities(solution, output, volume, faces, solver, what)
    for T, axes, sides, items in pending.values():
        B, dB = _tile_basis(T, axes, sides)
        step = max(1, _BATCH_POINTS // B.shape[0])
        for a in range(0, len(items), step):
            part = items[a:a + step]
            members = [i for i, _, _ in part]
            out = _against_tile(patches, members, D, drag, B, dB, np.concatenate([q for _, q, _ in part]),
                                np.concatenate([d for _, _, d in part]))
            for i, g in zip(members, out):
                grads[i] += g
    return grads


#: Gauss points per batch of the contraction (bounded temporaries: a few 3 x 3 x 3 fields a point)
_BATCH_POINTS = 1 << 15


def _face_axes(T, face: str, space):
    """The face's Gauss grid axes of ``space`` on the tile spline T and the side of each direction (at a slot
    plane the limit from the face's side), in the point order of :func:`iga.shape_sensitivity.face_parameters`."""
    axes = [np.asarray(d.qpts, float) for d in space.dirs]
    sides = ["right"] * 3
    k, at, sgn = face_plane(T, face)
    sides[k] = "left" if sgn < 0 else "right"
    axes[k] = np.array([at])
    return axes, sides


def tile_derivatives(grading, tile, t: int) -> dict:
    """{face: [dT/dtheta (n, 3) per patch of the tile]}: the derivative of tile t's control points by each of its
    six wall values (module notes); ``tile`` the tile the paving placed there."""
    family, values = grading.family, grading.values(t)
    affine = bool(getattr(family, "affine_in_values", False))
    out = {}
    for face, v in values.items():
        h = STEP * max(1.0, abs(v))
        d1 = _central(family, values, face, h, tile, t)
        out[face] = d1 if affine else [(4 * b - a) / 3 for a, b in zip(d1, _central(family, values, face, h / 2,
                                                                                   tile, t))]
    return out


def _central(family, values: dict, face: str, step: float, tile, t: int) -> list:
    """The central difference of the family's control points (per patch) in its ``face`` value."""
    lo, hi = (_control_points(family, {**values, face: values[face] + s * step}, tile, t, face) for s in (-1, 1))
    return [(b - a) / (2 * step) for a, b in zip(lo, hi)]


def _control_points(family, values: dict, tile, t: int, face: str) -> list:
    """The coordinates of the control points of each patch of ``family(**values)``; refused where the family
    refuses the values or returns a tile of another structure than ``tile``."""
    try:
        other = family(**values)
    except TilingError as exc:
        raise ProblemError(f"wrt='parameters': tile {t}'s family refuses its {face} value moved by a step of the "
                           f"derivative ({exc}); keep the field inside the family's range") from None
    if len(other.patches) != len(tile.patches) or any(
            a.control_points.shape != b.control_points.shape or a.degrees != b.degrees
            or any(not np.array_equal(u, w) for u, w in zip(a.knots, b.knots))
            or (a.weights is None) != (b.weights is None)
            or (a.weights is not None and not np.array_equal(a.weights, b.weights))
            or not np.array_equal(a.control_points[..., 3:], b.control_points[..., 3:])
            for a, b in zip(other.patches, tile.patches)):
        raise ProblemError(f"wrt='parameters': tile {t}'s family changes the tile's structure (patches, degrees, "
                           f"knots, weights or channels) when its {face} value moves; only its control points may "
                           "depend on the values")
    return [p.control_points[..., :3].reshape(-1, 3) for p in other.patches]


def _wall_gradients(ms, grading, per_patch: dict) -> np.ndarray:
    """dJ/dtheta on every wall site of the grading (n,) (``grading.site_centres``)."""
    out = np.zeros(len(grading.site_centres))
    by_tile: dict = {}
    for i, p in enumerate(ms.patches):
        by_tile.setdefault(p.tile, []).append(i)
    affine = bool(getattr(grading.family, "affine_in_values", False))
    shared = None
    for t in grading.graded_tiles():  # (a hierarchical paving's other levels are not graded)
        members = by_tile[t]
        if affine and shared is not None:
            dT = shared  # affine: the same derivative in every cell
        else:
            dT = tile_derivatives(grading, ms.tiles[t], t)
            shared = dT
        for face, site in grading.sites(t).items():
            out[site] += sum(float(np.sum(per_patch[i] * dT[face][ms.patches[i].patch_in_tile])) for i in members)
    return out


def _field_gradient(grading, g: np.ndarray, D) -> np.ndarray:
    """dJ/d(control values of the field) from the wall gradients (n,) (module notes)."""
    field = grading.field
    if is_real(field):
        return np.array(g.sum())
    y = grading.site_centres
    if isinstance(field, str):  # a channel of D: its values at the wall centres by D's basis (NURBS if weighted)
        return (map_basis(D, y).T @ g).reshape(D.control_points.shape[:3])
    dom = D.domain
    s = spline_parameters(field, (y - dom[:, 0]) / (dom[:, 1] - dom[:, 0]))
    shape = field.coefficients.shape[:3]
    n = int(np.prod(shape))
    basis = SplineFunction(field.degrees, field.knots, np.eye(n).reshape(shape + (n,)), field.weights)
    return (basis.evaluate(s).T @ g).reshape(shape)
