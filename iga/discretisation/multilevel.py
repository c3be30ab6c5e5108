"""Spline structure for the solvers: Kronecker sums for fast diagonalization, refinement matrices for multigrid.

The :mod:`solvers` package knows matrices only; this module hands it what the
spline spaces know (DESIGN: ``iga -> solvers``):

* :func:`kronecker_sum`: for one unconstrained trivariate patch whose free
  unknowns form a tensor grid (Dirichlet conditions on whole sides), the
  parametric 1-D stiffness and mass matrices of each direction and the
  averaged metric coefficients c_k = mean(k det J (J^-1 J^-T)_kk), so that
  sum_k c_k M x .. K_k .. x M approximates the stiffness matrix (exactly on an
  axis-aligned box with constant conductivity; Sangalli and Tani 2016).
* :func:`prolongations`: the multigrid hierarchy of nested spline spaces,
  coarse to fine by knot insertion (:func:`geometry.knots.insertion_matrix`,
  one Kronecker product per patch).  Levels are the problem's ``refine``
  rounds (every patch, so interfaces and branch refinements stay nested), or,
  for one unconstrained patch, its own knot vectors with every other
  breakpoint removed.  Between the reduced systems (constraints and Dirichlet
  data eliminated) the prolongation of a coarse free unknown is the fine
  function it equals, read at one DOF that each fine reduced unknown owns.
"""

from __future__ import annotations


import numpy as np
import scipy.sparse as sp

from geometry import knots as kn
from geometry.patches.chain import patch_geometry_grid
from solvers.indexing import complement

from iga.discretisation.constraints import needs_constraints, owners_of, prolongation
from iga.errors import ProblemError
from iga.discretisation.space import Space1D, TensorSpace, make_space
from geometry.tolerances import ON_DOMAIN

__all__ = ["kronecker_sum", "elastic_kronecker_sums", "prolongations", "coarsen_knots", "solver_options"]

MIN_COARSE = 1_000  # stop coarsening below this many unknowns


def _tensor_masks(space, free) -> list | None:
    """Per direction the kept indices when the free DOFs form a tensor grid, else None."""
    mask = np.zeros(space.ndof, bool)
    mask[free] = True
    M = mask.reshape(space.shape)
    masks = [M.any(axis=tuple(j for j in range(M.ndim) if j != k)) for k in range(M.ndim)]
    full = masks[0][:, None, None] & masks[1][None, :, None] & masks[2][None, None, :]
    return masks if np.array_equal(M, full) else None


def _single_patch(problem) -> bool:
    return (len(problem.spaces) == 1 and problem.spaces[0].dim == 3
            and not needs_constraints(problem.model, problem.spaces))


def kronecker_sum(problem, free: np.ndarray):
    """A :class:`solvers.kronecker.KroneckerSum` for the free unknowns of ``problem``, or None (see the notes)."""
    if not _single_patch(problem):
        return None
    return _kronecker(problem.spaces[0], free, _metric_coefficients(problem))


def elastic_kronecker_sums(problem, free: np.ndarray) -> list | None:
    """For an :class:`iga.ElasticityProblem` on one unconstrained patch: one Kronecker sum per displacement
    component, for the block fast diagonalization of its diagonal blocks K^aa, or None.

    ``free``: the free unknowns in the component-major numbering; each component's must form a tensor grid
    with a Dirichlet side.  The coefficients are the averages of w |det J| (mu (J^-1 J^-T)_kk + (lambda + mu +
    kappa) (J^-1)_ka^2), the parametric diagonal of block aa (:mod:`iga.elasticity.forms`; kappa = 0 unless cubic).
    """
    if not _single_patch(problem):
        return None
    n = problem.ndof
    x, Jinv, adet, chans = _metric_samples(problem)
    mod = problem.material.moduli(x, chans, "the preconditioner's sample points")
    mu, lmk = mod.mu, mod.lam + mod.mu + (0.0 if mod.kappa is None else mod.kappa)
    G = np.einsum("nki,nki->nk", Jinv, Jinv)
    out = []
    for a in range(3):
        c = np.mean(adet[:, None] * (mu[:, None] * G + lmk[:, None] * Jinv[:, :, a] ** 2), axis=0)
        ks = _kronecker(problem.spaces[0], free[(free >= a * n) & (free < (a + 1) * n)] - a * n,
                        np.maximum(c, ON_DOMAIN * c.max()))
        if ks is None:
            return None
        out.append(ks)
    return out


def _kronecker(space, free: np.ndarray, coefficients: np.ndarray):
    """The Kronecker sum of ``space``'s 1-D matrices on the free tensor grid, or None (no tensor grid, or no
    Dirichlet side at all: the sum would be singular)."""
    from solvers.kronecker import KroneckerSum

    masks = _tensor_masks(space, free)
    if masks is None or all(m.all() for m in masks):
        return None
    K1, M1 = [], []
    for s, m in zip(space.dirs, masks):
        B0, B1 = s.B[0][:, : s.nq], s.B[1][:, : s.nq]
        K1.append(((B1 * s.qw) @ B1.T)[np.ix_(m, m)])
        M1.append(((B0 * s.qw) @ B0.T)[np.ix_(m, m)])
    return KroneckerSum(K1, M1, coefficients)


def _metric_samples(problem, per_dir: int = 6):
    """x (N, 3), J^-1 (N, 3, 3), |det J| (N,) and channels on a grid of parameters of the single patch."""
    P = problem.model.patches[0]
    dom = P.spline.domain
    axes = [lo + (np.arange(per_dir) + 0.5) / per_dir * (hi - lo) for lo, hi in dom]
    x, J, chans = patch_geometry_grid(P, axes)
    return x, np.linalg.inv(J), np.abs(np.linalg.det(J)), chans


def _metric_coefficients(problem) -> np.ndarray:
    """c_k = mean of k det J (J^-1 K J^-T)_kk over a grid of parameters (K the conductivity tensor)."""
    x, Jinv, adet, chans = _metric_samples(problem)
    k = problem.conductivity.values(x, chans, "the preconditioner's sample points")
    if np.ndim(k) == 1:
        G = k[:, None, None] * np.einsum("nki,nli->nkl", Jinv, Jinv)
    else:
        xx, yy, zz, xy, xz, yz = np.moveaxis(np.asarray(k), -1, 0)
        Kt = np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], -2)
        G = np.einsum("nki,nij,nlj->nkl", Jinv, Kt, Jinv)
    c = np.mean(adet[:, None] * np.diagonal(G, axis1=1, axis2=2), axis=0)
    return np.maximum(c, ON_DOMAIN * c.max())


def coarsen_knots(U: np.ndarray, p: int) -> np.ndarray | None:
    """``U`` without every other interior breakpoint (discontinuities kept): a nested coarser space, or None."""
    vals, mult = kn.breakpoints(U)
    inner = np.arange(1, len(vals) - 1)
    removable = inner[mult[inner] < p + 1]
    drop = removable[::2]
    if not len(drop):
        return None
    keep = np.ones(len(vals), bool)
    keep[drop] = False
    return np.repeat(vals[keep], mult[keep])


def _insertion(Uc, Uf, p) -> sp.csr_matrix:
    """(n_fine, n_coarse) knot-insertion matrix from Uc to Uf (Uc's knots a sub-multiset of Uf's)."""
    vc, mc = kn.breakpoints(Uc)
    vf, mf = kn.breakpoints(Uf)
    have = dict(zip(np.round(vc, 14), mc))
    new = [v for v, m in zip(vf, mf) for _ in range(m - have.get(round(v, 14), 0))]
    return sp.csr_matrix(kn.insertion_matrix(Uc, p, new)[1])


def _levels(problem) -> list:
    """Per level (finest first, the problem's own excluded) the list of every patch's (knots, degree) per
    direction."""
    fine = [[(d.knots, d.degree) for d in s.dirs] for s in problem.spaces]
    out = []
    r = problem.space_args[2]
    if r >= 1:
        args = list(problem.space_args)
        for level in range(r - 1, -1, -1):
            args[2] = level
            out.append([[(d.knots, d.degree) for d in make_space(knots, degrees, *args).dirs]
                        for knots, degrees in problem.bases])
        return out
    if not _single_patch(problem):
        return out
    cur = fine[0]
    while int(np.prod([len(U) - p - 1 for U, p in cur])) > MIN_COARSE:
        nxt = [(coarsen_knots(U, p), p) for U, p in cur]
        if all(U is None for U, _ in nxt):
            break
        cur = [(U if U is not None else V, p) for (U, p), (V, _) in zip(nxt, cur)]
        out.append([cur])
    return out


def _reduced(model, spaces, offsets, dirichlet_faces):
    """(P (ndof x nred), dof_master, free reduced unknowns) of a level."""
    if not needs_constraints(model, spaces):
        n = int(offsets[-1])
        P, master = sp.identity(n, format="csr"), np.arange(n)
    else:
        c = prolongation(model, spaces, offsets)
        P, master = c.P, c.dof_master
    fixed = [np.unique(P[spaces[pi].face_dofs(face) + offsets[pi]].indices) for pi, face in dirichlet_faces]
    free = complement(P.shape[1], np.concatenate(fixed) if fixed else [])
    return P, master, free


def prolongations(problem, dirichlet_faces, free: np.ndarray, dof_master: np.ndarray | None) -> list | None:
    """Prolongation matrices between the reduced free unknowns of nested levels (finest first), or None."""
    levels = _levels(problem)
    if not levels:
        return None
    fine_spaces = [[(d.knots, d.degree) for d in s.dirs] for s in problem.spaces]
    rows = owners_of(np.arange(problem.ndof) if dof_master is None else dof_master)[free]
    out = []
    for coarse in levels:
        Pc, master_c, free_c = _reduced(problem.model, *_level_spaces(coarse), dirichlet_faces)
        blocks, cache = [], {}
        for cf, cc in zip(fine_spaces, coarse):
            key = tuple((Uf.tobytes(), Uc.tobytes(), p) for (Uf, p), (Uc, _) in zip(cf, cc))
            if key not in cache:  # patches with equal spaces share their refinement matrix
                R = sp.csr_matrix(np.ones((1, 1)))
                for (Uf, p), (Uc, _) in zip(cf, cc):
                    R = sp.kron(R, _insertion(Uc, Uf, p), format="csr")
                cache[key] = R
            blocks.append(cache[key])
        out.append((sp.block_diag(blocks, format="csr") @ Pc[:, free_c])[rows].tocsr())
        fine_spaces, rows = coarse, owners_of(master_c)[free_c]
        if len(free_c) <= MIN_COARSE:
            break
    return out


def _level_spaces(spaces_knots):
    """(spaces, offsets) of a coarse level, patches with equal knots and degrees sharing one space."""
    shared: dict = {}

    def space(dirs):
        key = tuple((U.tobytes(), p) for U, p in dirs)
        if key not in shared:
            shared[key] = TensorSpace([Space1D(U, p, p + 1) for U, p in dirs])
        return shared[key]

    spaces = [space(dirs) for dirs in spaces_knots]
    return spaces, np.concatenate([[0], np.cumsum([s.ndof for s in spaces])]).astype(np.int64)


#: ``auto`` factorises coupled patches (a prolongation) up to this many unknowns, one patch up to
#: :data:`solvers.AUTO_DIRECT_LIMIT`: patches glued at faces fill in far less than one 3-D patch.  Measured
#: (SuperLU, minimum-degree ordering; solve seconds, direct against AMG-CG): the demo sink 4,672 unknowns
#: 0.011 / 0.061, 14,544: 0.066 / 0.32, 62,800: 0.71 / 2.0; a 6^3 cross lattice 23,652: 0.22 / 0.23, 10^3:
#: 108,900: 3.9 / 0.86; an elastic 4^3 cross lattice 21,600: 0.46 / 0.98.  (One p = 2 patch of 5.8k: 0.67 / 0.08.)
MULTIPATCH_DIRECT_LIMIT = 25_000


def direct_limit(constraints, solver: str) -> dict:
    """The ``direct_limit`` option of ``auto`` for coupled patches (:data:`MULTIPATCH_DIRECT_LIMIT`), none for
    one unconstrained patch or another solver."""
    return {"direct_limit": MULTIPATCH_DIRECT_LIMIT} if solver == "auto" and constraints is not None else {}


def solver_options(problem, solver: str, constraints, dd, book) -> dict:
    """The spline structure a solver needs: a Kronecker sum (fd-cg, auto) or prolongations (gmg-cg).

    ``constraints`` / ``dd`` / ``book``: the problem's prolongation, Dirichlet data and assembly bookkeeping.
    """
    if solver not in ("fd-cg", "gmg-cg", "auto"):
        return {}
    nred = problem.ndof if constraints is None else constraints.P.shape[1]
    free = complement(nred, dd.dofs)
    if solver in ("fd-cg", "auto"):
        ks = kronecker_sum(problem, free) if constraints is None else None
        if ks is None and solver == "fd-cg":
            raise ProblemError("solver 'fd-cg' (fast diagonalization) needs one unconstrained trivariate patch "
                               "with Dirichlet conditions on whole sides (at least one); use 'gmg-cg' or "
                               "'amg-cg' for this problem")
        return {"kronecker": ks} if ks is not None else direct_limit(constraints, solver)
    P = None if len(dd.slave_rows) else prolongations(problem, list(book["dirichlet"]), free,
                                                      None if constraints is None else constraints.dof_master)
    if not P:
        raise ProblemError("solver 'gmg-cg' needs nested levels: refine >= 1 (or one unconstrained patch with "
                           "several knot spans), and no Dirichlet data on child branch faces; use 'amg-cg'")
    return {"prolongations": P}
