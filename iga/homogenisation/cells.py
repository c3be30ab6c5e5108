"""Effective conductivity of a periodic tile: the three cell problems of first-order homogenisation.

For a tile paving the unit cell Y = [0, 1]^3 periodically, the corrector
chi_j (j = x, y, z) solves

    -div(k (grad chi_j + e_j)) = 0 in the tile,  chi_j Y-periodic,  k (grad chi_j + e_j) . n = 0 on its walls,

and K_ij = (1/|Y|) int k (delta_ij + d_i chi_j) dV.  In weak form, with
a(u, v) = int k grad u . grad v and b_j(v) = int k d_j v, a(chi_j, v) = -b_j(v)
for all periodic v, so K_ij = int k delta_ij + b_i(chi_j) = int k delta_ij -
a(chi_i, chi_j): symmetric, and below the Voigt bound (int k) I by construction.

Periodicity is a set of identity interfaces: every tile face on the wall
x_k = 0 is glued to the face on x_k = 1 that it matches after the shift
e_k (found by :func:`geometry.patches.multipatch.detect_interfaces` on the tile and
its shifted copy).  The cell problems then use the heat analysis's own
machinery: the tile's basis, the exact regularity proof, the constraints
(:func:`iga.discretisation.constraints.prolongation`) and the sum-factorised assembly; chi
is fixed by one pinned unknown (it is defined up to a constant).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from geometry.numbers import TINY
from geometry import BSpline
from geometry.patches.chain import patches_geometry_derivs_slabs
from geometry.errors import SplineError, show
from geometry.faces import FACE_AXIS
from geometry.patches.multipatch import Interface, MultiPatch, detect_interfaces
from solvers.indexing import complement

from iga.assembly.tensor import derivative_load_form
from iga.discretisation.constraints import prolongation
from iga.elasticity.forms import divergence_terms, metric_rows
from iga.errors import ProblemError
from iga.heat.problem import HeatProblem

__all__ = ["Effective", "effective_conductivity", "effective_stiffness", "periodic_cell"]


@dataclass
class Effective:
    """An effective tensor with its diagnostics: ``tensor`` (3, 3) in the units of the conductivity,
    ``volume_fraction`` (solid volume / cell volume), ``symmetry_error`` (max |K - K^T| / max |K|),
    ``unknowns`` of each cell problem, ``periodic_faces`` glued across the cell, ``condition`` (the 1-norm
    condition number of the cell problems' matrix, estimated); for the conductivity also the cell problem
    and its correctors (ndof, 3), which :meth:`write_vtu` writes."""

    tensor: np.ndarray
    volume_fraction: float
    symmetry_error: float
    unknowns: int
    periodic_faces: int
    condition: float = float("nan")
    problem: object = field(default=None, repr=False)
    correctors: np.ndarray = field(default=None, repr=False)

    def write_vtu(self, path, samples: int = 3):
        """The cell fields as one ``.vtu`` (atomic): the correctors chi_x, chi_y, chi_z (``corrector``), the
        cell's heat flux for a unit macroscopic gradient along x, y, z (``cell_flux_x`` ..) and the
        conductivity, on the tile's patches sampled ``samples`` times per element (conductivity only)."""
        from geometry.patches.sampling import sampled_mesh

        from iga.io.sampling import corrector_fields
        from iga.io.vtu import save_vtu

        if self.correctors is None:
            raise ProblemError("this Effective holds no cell fields: write_vtu needs "
                               "effective_conductivity(..., diagnostics=True)")
        prob = self.problem
        grid = sampled_mesh(prob.model, samples, knots_of=lambda pi: [d.knots for d in prob.spaces[pi].dirs],
                            spaces_key=lambda pi: prob.spaces[pi].key(),
                            fields=corrector_fields(prob, self.correctors))
        return save_vtu(path, grid)


def periodic_cell(tile) -> MultiPatch:
    """The tile's trivariate patches on the unit cell with its own interfaces and the periodic ones.  ``tile``: a
    :class:`tiling.Tile`, or trivariate BSplines in the unit cell (one, or a list: a solid cell is one box)."""
    if isinstance(tile, BSpline):
        patches = [tile]
    elif isinstance(tile, (list, tuple)):
        patches = list(tile)
        bad = [i for i, p in enumerate(patches) if not (isinstance(p, BSpline) and p.dim == 3)]
        if bad:  # a list is the user's own patches: none is dropped without a word
            raise ProblemError(f"tile list item {bad[0]} is a {type(patches[bad[0]]).__name__}"
                               f"{'' if not isinstance(patches[bad[0]], BSpline) else f' of dimension {patches[bad[0]].dim}'}"
                               "; a list of patches to homogenise holds trivariate BSplines in the unit cell only "
                               "(a Tile keeps its surfaces and curves apart)")
    elif hasattr(tile, "patches"):
        patches = list(tile.patches)
    else:
        raise ProblemError(f"cannot homogenise a {type(tile).__name__}: pass a tile (e.g. tiling.library.cross()), "
                           "a trivariate BSpline in the unit cell or a list of them")
    vols = [p for p in patches if getattr(p, "dim", 0) == 3]
    if not vols:
        raise ProblemError(f"tile {show(getattr(tile, 'name', tile))} has no trivariate patches: a surface tile has no "
                           "volume to homogenise; use a volumetric tile")
    try:
        model = MultiPatch.from_splines(vols)
    except SplineError as exc:
        raise ProblemError(f"tile {show(getattr(tile, 'name', ''))}: {exc}") from None
    n = len(vols)
    periodic = []
    for k in range(3):
        shift = np.eye(3)[k]
        both = MultiPatch.from_splines(vols + [v.translate(shift) for v in vols], couple=False).patches
        found, _ = detect_interfaces(both)
        pairs = [i for i in found if (i.a[0] < n) != (i.b[0] < n)]
        for i in pairs:
            (pa, fa), (pb, fb) = (i.a, i.b) if i.a[0] < n else (i.b, i.a)
            periodic.append(Interface("identity", (pa, fa), (pb - n, fb), swap=i.swap, flip=i.flip))
        _check_walls(vols, k, {(p, f) for i in pairs for p, f in (i.a, i.b)}, n)
    model.interfaces += periodic
    return model


def _check_walls(vols, k: int, glued: set, n: int) -> None:
    """Every face on the walls x_k = 0, 1 must have found its partner on the opposite wall."""
    for pi, v in enumerate(vols):
        for face in (("umin", "umax"), ("vmin", "vmax"), ("wmin", "wmax"))[k]:
            axis, side = FACE_AXIS[face]
            pts = np.take(v.points, -1 if side else 0, axis=axis).reshape(-1, 3)
            for wall in (0.0, 1.0):
                if np.all(np.abs(pts[:, k] - wall) < 1e-9):
                    key = (pi, face) if wall == 1.0 else (pi + n, face)
                    if key not in glued:
                        raise ProblemError(f"the tile is not periodic along {'xyz'[k]}: face {face} of patch {pi} on the "
                                           f"wall {'xyz'[k]} = {wall:g} has no matching face on the opposite wall; "
                                           f"homogenisation needs opposite walls that conform{_span_hint(vols, k)}")


def _span_hint(vols, k: int) -> str:
    """A note on the tile's extent along axis k when its control points leave the unit cell."""
    lo = min(float(v.points[..., k].min()) for v in vols)
    hi = max(float(v.points[..., k].max()) for v in vols)
    if lo >= -1e-9 and hi <= 1 + 1e-9:
        return ""
    return f" (a tile lives in the unit cell [0, 1]^3; its control points span {'xyz'[k]} in [{lo:g}, {hi:g}])"


def effective_conductivity(tile, conductivity=1.0, degree_elevation: int = 1, refine: int = 0,
                           diagnostics: bool = False):
    """The effective conductivity tensor (3, 3) of ``tile`` paving the unit cell periodically (module notes).
    ``tile``: a :class:`tiling.Tile`, or trivariate BSplines in the unit cell (one or a list).

    ``conductivity``: W/(m K), a number, a channel name of the tile or a callable of the cell point x (N, 3)
    (isotropic); ``degree_elevation``, ``refine``: the cell problems' spaces, as for :class:`iga.HeatProblem`;
    ``diagnostics``: return the :class:`Effective` (tensor, volume fraction, symmetry error, unknowns)
    instead of the array alone.
    """
    model = periodic_cell(tile)
    prob = HeatProblem(model, conductivity=conductivity, degree_elevation=degree_elevation, refine=refine)
    K, _, _ = prob.assemble()
    c = prolongation(prob.model, prob.spaces, prob.offsets, prob.weights)
    P = c.P
    B, total_k, volume = _loads(prob)  # (ndof, 3) of b_j(N_i) = int k d_j N_i; int k dV; int dV
    A = (P.T @ K @ P).tocsc()
    Br = P.T @ B
    keep = np.arange(1, A.shape[0])  # chi up to a constant: pin the first reduced unknown
    X = np.zeros_like(Br)
    Ak = A[keep][:, keep].tocsc()
    lu = sp.linalg.splu(Ak)
    X[keep] = lu.solve(-np.ascontiguousarray(Br[keep]))
    Keff = total_k * np.eye(3) + Br.T @ X  # K_ij = int k delta_ij + b_i(chi_j)  (the unit cell: |Y| = 1)
    sym = float(np.abs(Keff - Keff.T).max() / max(np.abs(Keff).max(), TINY))
    out = Effective(0.5 * (Keff + Keff.T), volume, sym, int(A.shape[0]),
                    sum(i.kind == "identity" for i in model.interfaces), _condition(Ak, lu) if diagnostics else
                    float("nan"), prob, P @ X)
    return out if diagnostics else out.tensor


def _condition(A, lu) -> float:
    """The 1-norm condition number of A estimated from its factors (Hager-Higham, ``onenormest``)."""
    inv = sp.linalg.LinearOperator(A.shape, matvec=lu.solve, rmatvec=lambda b: lu.solve(b, trans="T"),
                                   dtype=float)
    return float(sp.linalg.onenormest(A) * sp.linalg.onenormest(inv))


def _gauss_slabs(prob, i: int):
    """Per slab of patch ``i``'s Gauss grid: (points (m, 3), channels {name: (m,)}, metric rows c_r, det J (m,),
    quadrature weights (m,)) for the cell-problem loads."""
    space = prob.spaces[i]
    w_rest = np.multiply.outer(space.dirs[1].qw, space.dirs[2].qw).ravel()
    for planes, x, D, chans in patches_geometry_derivs_slabs([prob.model.patches[i]], space.qaxes, 1 << 16,
                                                              rows_multiple=space.dirs[0].g):
        cr, det = metric_rows(D)
        yield (x.reshape(-1, 3), {ch: np.reshape(v, -1) for ch, v in chans.items()}, cr, det,
               np.multiply.outer(space.dirs[0].qw[planes], w_rest).ravel())


def _loads(prob):
    """B (ndof, 3): int k d_j N_i dV per DOF and direction; int k dV; int dV (the solid's volume)."""
    B = np.zeros((prob.ndof, 3))
    total_k = volume = 0.0
    for i in range(len(prob.model.patches)):
        space = prob.spaces[i]
        parts = []
        for xs, flat, cr, det, w in _gauss_slabs(prob, i):
            kval = prob.conductivity.values(xs, flat, f"patch {i}")
            total_k += float(np.sum(kval * np.abs(det) * w))
            volume += float(np.sum(np.abs(det) * w))
            parts.append((cr, kval * np.sign(det) * w))
        shape = (1,) + space.qshape
        c = [[np.concatenate([p[0][r][a] for p in parts]) for a in range(3)] for r in range(3)]
        weight = np.concatenate([p[1] for p in parts])
        for j in range(3):
            B[prob.offsets[i]:prob.offsets[i + 1], j] = derivative_load_form(
                space, divergence_terms(c, weight, j, shape))[0].ravel()
    return B, total_k, volume


def _unit_strains() -> list:
    """The six unit macro strains in Voigt order xx, yy, zz, yz, xz, xy (engineering shears: gamma = 1)."""
    out = []
    for a, b in ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)):
        E = np.zeros((3, 3))
        E[a, b] = E[b, a] = 1.0 if a == b else 0.5
        out.append(E)
    return out


def effective_stiffness(tile, youngs, poisson, degree_elevation: int = 1, refine: int = 0,
                        diagnostics: bool = False):
    """The effective elasticity tensor (6, 6) in Voigt notation (xx, yy, zz, yz, xz, xy; engineering shear
    strains) of ``tile`` (as :func:`effective_conductivity` takes it) paving the unit cell periodically: the
    six cell problems div C (eps(chi_m) + E_m) = 0 with chi_m periodic, C_mn = int E_m : C : (E_n + eps(chi_n)) dV.

    ``youngs`` (Pa) and ``poisson``: numbers, channel names or callables of the cell point, as for
    :class:`iga.ElasticityProblem`; the correctors are fixed against the three translations they are defined
    up to by pinning one unknown of each component; ``diagnostics`` as for :func:`effective_conductivity`.
    """
    from iga.elasticity.volume import ElasticVolume, vector_constraints
    from iga.elasticity.problem import ElasticityProblem

    model = periodic_cell(tile)
    prob = ElasticityProblem(model, youngs, poisson, degree_elevation=degree_elevation, refine=refine)
    K = ElasticVolume(prob.disc).assemble(prob.material)[0]
    c = vector_constraints(prolongation(prob.model, prob.spaces, prob.offsets, prob.weights), prob.ndof)
    B, mean, volume = _stiffness_loads(prob)  # (3 ndof, 6), int E_m : C : E_n dV (6, 6), solid volume
    A = (c.P.T @ K @ c.P).tocsc()
    Br = c.P.T @ B
    nred = A.shape[0] // 3
    keep = complement(A.shape[0], [0, nred, 2 * nred])  # one pinned unknown per component
    X = np.zeros_like(Br)
    Ak = A[keep][:, keep].tocsc()
    lu = sp.linalg.splu(Ak)
    X[keep] = lu.solve(-Br[keep])
    C = mean + Br.T @ X
    sym = float(np.abs(C - C.T).max() / max(np.abs(C).max(), TINY))
    out = Effective(0.5 * (C + C.T), volume, sym, int(A.shape[0]), sum(i.kind == "identity" for i in model.interfaces),
                    _condition(Ak, lu) if diagnostics else float("nan"))
    return out if diagnostics else out.tensor


def _stiffness_loads(prob):
    """B (3 ndof, 6) of int sigma(E_m) : eps(N_i e_a) dV, the mean int E_m : C : E_n dV (6, 6) and int dV."""
    from iga.elasticity.forms import lame

    strains = _unit_strains()
    n = prob.ndof
    B = np.zeros((3 * n, 6))
    mean = np.zeros((6, 6))
    volume = 0.0
    for i in range(len(prob.model.patches)):
        space = prob.spaces[i]
        parts = []
        for xs, flat, cr, det, w in _gauss_slabs(prob, i):
            lam, mu = lame(prob.youngs.values(xs, flat, f"patch {i}"), prob.poisson.values(xs, flat, f"patch {i}"),
                           f"patch {i}")
            dv = np.abs(det) * w
            volume += float(dv.sum())
            for m, Em in enumerate(strains):
                for q, Eq in enumerate(strains):
                    mean[m, q] += float(np.sum((lam * np.trace(Em) * np.trace(Eq) + 2 * mu * np.sum(Em * Eq)) * dv))
            parts.append((cr, lam, mu, np.sign(det) * w))
        shape = (1,) + space.qshape
        c = [[np.concatenate([p[0][r][a] for p in parts]) for a in range(3)] for r in range(3)]
        lam, mu, sw = (np.concatenate([p[k] for p in parts]) for k in (1, 2, 3))
        for m, E in enumerate(strains):
            S = lam[:, None, None] * np.trace(E) * np.eye(3) + 2 * mu[:, None, None] * E  # sigma(E_m) (M, 3, 3)
            for a in range(3):
                terms = [((sw * sum(S[:, a, d] * c[r][d] for d in range(3))).reshape(shape),
                          tuple((int(k == r), None) for k in range(3))) for r in range(3)]
                B[a * n + prob.offsets[i] : a * n + prob.offsets[i + 1], m] = \
                    derivative_load_form(space, terms)[0].ravel()
    return B, mean, volume
