"""Steady heat conduction: -div(k grad T) = f with Dirichlet, Neumann and Robin faces.

Units are the user's, consistently: with lengths in m, conductivity in
W/(m K), sources in W/m^3, fluxes in W/m^2 and film coefficients in
W/(m^2 K), temperatures are in K (or degrees C) and heat flows in W.

Weak form (000 Eq. 9): find T = T_D on Dirichlet faces with

    int k grad T . grad v  +  int_Robin h T v  =  int f v  +  int_Neumann q v  +  int_Robin h T_inf v

for all v vanishing on Dirichlet faces.  Each patch uses its own B-spline
basis (000 Remark 2), optionally elevated and refined; Dirichlet data are L2
projected onto the Dirichlet trace space and eliminated through
``u = P u_free + g``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from numbers import Real

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import solvers

from . import ProblemError
from .assembly import banded_form, banded_to_csr_data, block_diagonal_csr, load_form, pattern, stiffness_data
from .geometry_eval import checked_det, patch_geometry_derivs, patch_geometry_grid
from .model import Patch, as_model
from .space import FACE_AXES, make_space


class SingularProblemError(ProblemError, solvers.SolverError):
    """The heat problem has no Dirichlet or Robin condition: its temperature is not unique."""


def _is_number(v) -> bool:
    return isinstance(v, Real) and not isinstance(v, bool)


@dataclass
class FaceData:
    """Quadrature data of one patch face (physical geometry at the face's Gauss points)."""

    patch: int
    face: str
    space: object  # face TensorSpace
    dofs: np.ndarray  # global DOF numbers of the face space, C order
    x: np.ndarray  # (N, 3)
    chans: dict
    dAw: np.ndarray  # (N,) area element times quadrature weight
    normal: np.ndarray  # (N, 3) outward unit normal

    def basis_tables(self):
        return [d.B[0][:, :-1] for d in self.space.dirs]

    def trace(self, u: np.ndarray) -> np.ndarray:
        """Values at the face Gauss points of the global coefficient vector ``u``."""
        Bs, Bt = self.basis_tables()
        U = u[self.dofs].reshape(self.space.shape)
        return np.einsum("ab,aq,br->qr", U, Bs, Bt).ravel()


@dataclass
class _Condition:
    kind: str
    tag: str
    value: object = 0.0
    h: object = None


class HeatProblem:
    """Steady heat transfer on a trivariate patch, a list of patches or a micro-structure.

    Parameters
    ----------
    model : BSpline, list of BSpline, or tiling.Microstructure
    conductivity : number, channel name, or callable ``k(x) -> (N,)`` (W/(m K)); must be > 0
    source : number, channel name, or callable ``f(x) -> (N,)`` (W/m^3)
    degree_elevation, refine : applied to every patch's solution space
        (degree + ``degree_elevation``, an int or one per direction, then
        ``refine`` rounds of knot-span bisection)
    degree : optional solution degrees (int or three) replacing patch degree +
        elevation; continuity at each knot is kept, capped at C^(p-1)
    quadrature_extra : Gauss points per element and direction beyond ``p + 1``

    Boundary conditions refer to the model's tags (``umin`` .. ``wmax``,
    ``boundary``, and for micro-structures ``branch-in``, ``internal`` and user
    tags); faces with no condition are insulated.
    """

    def __init__(self, model, conductivity=1.0, source=0.0, degree_elevation=0, refine: int = 0,
                 quadrature_extra: int = 0, degree=None):
        self.model = as_model(model)
        for name, v in (("refine", refine), ("quadrature_extra", quadrature_extra)):
            if not isinstance(v, (int, np.integer)) or v < 0:
                raise ProblemError(f"{name} must be a non-negative integer, got {v!r}")
        for name, v in (("degree_elevation", degree_elevation), ("degree", 1 if degree is None else degree)):
            vals = [v] if np.isscalar(v) else list(v)
            if len(vals) not in (1, 3) or any(not isinstance(x, (int, np.integer)) or x < (0 if name[0] == "d" and name != "degree" else 1) for x in vals):
                raise ProblemError(f"{name} must be a non-negative integer or three of them (degree: >= 1), got {v!r}")
        if degree is not None and np.isscalar(degree):
            degree = (int(degree),) * 3
        self.conductivity = self._check_field(conductivity, "conductivity", positive=True)
        self.source = self._check_field(source, "source", positive=False)
        t0 = time.perf_counter()
        self.spaces = [make_space(p.spline.knots, p.spline.degrees, quadrature_extra, degree_elevation, refine, degree)
                       for p in self.model.patches]
        self.offsets = np.concatenate([[0], np.cumsum([s.ndof for s in self.spaces])]).astype(np.int64)
        self.ndof = int(self.offsets[-1])
        self.conditions: list[_Condition] = []
        self.timings = {"spaces": time.perf_counter() - t0}

    # ----------------------------------------------------------------- inputs
    def _check_field(self, spec, what, positive):
        if _is_number(spec):
            if not np.isfinite(spec) or (positive and spec <= 0):
                raise ProblemError(f"{what} must be a finite{' positive' if positive else ''} number, got {spec!r}")
            return float(spec)
        if isinstance(spec, str):
            for i, p in enumerate(self.model.patches):
                if spec not in p.channels:
                    raise ProblemError(
                        f"{what} refers to channel {spec!r}, but patch {i} only has channels {list(p.channels)}; "
                        "add the channel to the tile or the deformation map"
                    )
            return spec
        if callable(spec):
            return spec
        raise ProblemError(f"{what} must be a number, a channel name or a callable of x (N, 3), got {type(spec).__name__}")

    def _values(self, spec, x, chans, what, where, positive=False):
        """Evaluate a number / channel / callable at points ``x`` (N, 3) -> (N,)."""
        n = len(x)
        if _is_number(spec):
            v = np.full(n, float(spec))
        elif isinstance(spec, str):
            v = np.asarray(chans[spec], float)
        else:
            try:
                v = np.asarray(spec(x), float)
            except Exception as exc:  # a user callable failed: say which input
                raise ProblemError(f"{what} callable failed on {where}: {exc}") from exc
            if v.shape == ():
                v = np.full(n, float(v))
            if v.shape != (n,):
                raise ProblemError(f"{what} callable must return shape ({n},) for x of shape ({n}, 3), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ProblemError(f"{what} is not finite at some points of {where}")
        if positive and np.any(v <= 0):
            i = int(np.argmin(v))
            raise ProblemError(f"{what} must be positive, but is {v[i]:g} at x = {np.round(x[i], 6).tolist()} on {where}")
        return v

    def _condition_spec(self, value, what):
        if _is_number(value):
            if not np.isfinite(value):
                raise ProblemError(f"{what} must be finite, got {value!r}")
            return float(value)
        if callable(value):
            return value
        raise ProblemError(f"{what} must be a number or a callable of x (N, 3), got {type(value).__name__}")

    def dirichlet(self, tag: str, value=0.0) -> "HeatProblem":
        """Prescribed temperature on the faces tagged ``tag`` (number or callable of x)."""
        self.model.faces(tag)
        self.conditions.append(_Condition("dirichlet", tag, self._condition_spec(value, f"Dirichlet value on {tag!r}")))
        return self

    def neumann(self, tag: str, flux) -> "HeatProblem":
        """Inward heat flux q (W/m^2; q > 0 heats the body) on the faces tagged ``tag``."""
        self.model.faces(tag)
        self.conditions.append(_Condition("neumann", tag, self._condition_spec(flux, f"Neumann flux on {tag!r}")))
        return self

    def robin(self, tag: str, h, ambient) -> "HeatProblem":
        """Convection -k dT/dn = h (T - ambient) on ``tag``; h in W/(m^2 K), must be > 0."""
        self.model.faces(tag)
        hh = self._condition_spec(h, f"film coefficient h on {tag!r}")
        if _is_number(hh) and hh <= 0:
            raise ProblemError(f"film coefficient h on {tag!r} must be positive, got {h!r}")
        self.conditions.append(_Condition("robin", tag, self._condition_spec(ambient, f"ambient temperature on {tag!r}"), hh))
        return self

    # --------------------------------------------------------------- assembly
    def face_data(self, pi: int, face: str) -> FaceData:
        """Geometry and DOFs of one patch face at its Gauss points.

        ``face`` is one of the six patch faces or a slot face id (``u=0.5-``:
        the discontinuity plane u = 0.5 seen from u < 0.5), integrated on the
        one-sided sub-patch and restricted to the model's free region of it.
        """
        if not hasattr(self, "_face_cache"):
            self._face_cache = {}
        key = (pi, face)
        if key in self._face_cache:
            return self._face_cache[key]
        from tiling.microstructure import parse_slot_face

        patch, space = self.model.patches[pi], self.spaces[pi]
        slot = parse_slot_face(face)
        mask = None
        if slot is None:
            k, side = FACE_AXES[face]
            geo = patch
            U = patch.spline.knots[k]
            at = U[-1] if side else U[0]
            dofs = space.face_dofs(face)
        else:
            k, at, sgn = slot
            side = 1 if sgn < 0 else 0  # u=v- is the max face of the sub-patch below the plane
            box = patch.spline.domain.copy()
            box[k] = [box[k, 0], at] if sgn < 0 else [at, box[k, 1]]
            geo = Patch(patch.spline.extract(box), patch.placement, patch.outer, patch.tile, patch.level)
            first = int(np.searchsorted(space.dirs[k].knots, at, side="left"))
            layer = first - 1 if sgn < 0 else first
            dofs = np.take(np.arange(space.ndof).reshape(space.shape), layer, axis=k).ravel()
            rects = self.model.face_regions.get(key)
            if rects is None:
                raise ProblemError(f"patch {pi} has no free region recorded for slot face {face!r}")
            rest = [i for i in range(3) if i != k]
            q1, q2 = np.meshgrid(space.dirs[rest[0]].qpts, space.dirs[rest[1]].qpts, indexing="ij")
            mask = np.zeros(q1.shape, bool)
            for (a1, b1), (a2, b2) in rects:
                mask |= (q1 > a1) & (q1 < b1) & (q2 > a2) & (q2 < b2)
            mask = mask.ravel()
        axes = [d.qpts for d in space.dirs]
        axes[k] = np.array([at])
        x, J, chans = patch_geometry_grid(geo, axes)
        a, b = [i for i in range(3) if i != k]
        cr = np.cross(J[:, :, a], J[:, :, b])
        dA = np.linalg.norm(cr, axis=1)
        if np.any(dA <= 0):
            raise ProblemError(f"patch {pi} face {face} is degenerate (zero area at some Gauss points)")
        inward = np.einsum("ni,ni->n", cr, J[:, :, k])
        sign = np.where(inward > 0, 1.0, -1.0) * (1.0 if side else -1.0)
        fs = space.face_space("umin" if k == 0 else "vmin" if k == 1 else "wmin")
        w = np.multiply.outer(fs.dirs[0].qw, fs.dirs[1].qw).ravel()
        dAw = dA * w if mask is None else dA * w * mask
        fd = FaceData(pi, face, fs, dofs + self.offsets[pi], x, chans, dAw, cr / dA[:, None] * sign[:, None])
        self._face_cache[key] = fd
        return fd

    def _face_matrix(self, fd: FaceData, F: np.ndarray) -> sp.coo_matrix:
        band = banded_form(fd.space, [(F.reshape((1,) + fd.space.qshape), ((0, 0), (0, 0)))])
        pat = pattern(fd.space)
        data = banded_to_csr_data(fd.space, band)[0]
        rows = np.repeat(np.arange(pat.n), np.diff(pat.indptr))
        return sp.coo_matrix((data, (fd.dofs[rows], fd.dofs[pat.indices])), shape=(self.ndof, self.ndof))

    def _face_load(self, fd: FaceData, F: np.ndarray) -> np.ndarray:
        return load_form(fd.space, F.reshape((1,) + fd.space.qshape))[0].ravel()

    def _stiffness_fields(self, i, space):
        """k |J| w J^-1 J^-T at the Gauss grid of patch i (6 symmetric components) and the source load field.

        With c_1 = x_v x x_w, c_2 = x_w x x_u, c_3 = x_u x x_v (the rows of
        det J * J^-1), k |J| J^-1 J^-T = k (c_r . c_s) / |det J|.
        """
        x, D, chans = patch_geometry_derivs(self.model.patches[i], space.qaxes)
        D = [np.ascontiguousarray(dk.T) for dk in D]  # component-major (3, N): contiguous arithmetic

        def cross(a, b):
            return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])

        c = [cross(D[1], D[2]), cross(D[2], D[0]), cross(D[0], D[1])]
        det = checked_det(D[0][0] * c[0][0] + D[0][1] * c[0][1] + D[0][2] * c[0][2], f"patch {i}")
        w = np.multiply.outer(np.multiply.outer(*[d.qw for d in space.dirs[:2]]), space.dirs[2].qw).ravel()
        kval = self._values(self.conductivity, x, chans, "conductivity", f"patch {i}", positive=True)
        fac = kval * w / np.abs(det)
        C = {(r, s): fac * (c[r][0] * c[s][0] + c[r][1] * c[s][1] + c[r][2] * c[s][2])
             for r in range(3) for s in range(r, 3)}
        fval = self._values(self.source, x, chans, "source", f"patch {i}")
        return C, fval * np.abs(det) * w

    def _volume(self):
        """Stiffness (CSR) and source load over all patches, batched per space."""
        blocks, f = [], np.zeros(self.ndof)
        groups: dict = {}
        for i, s in enumerate(self.spaces):
            groups.setdefault(s.key(), []).append(i)
        source_total = 0.0
        for members in groups.values():
            space = self.spaces[members[0]]
            fields = [self._stiffness_fields(i, space) for i in members]  # geometry per patch, vectorised inside
            shape = (len(members),) + space.qshape
            C = {rs: (fields[0][0][rs] if len(members) == 1 else np.stack([fl[0][rs] for fl in fields])).reshape(shape)
                 for rs in fields[0][0]}
            data = stiffness_data(space, C)
            pat = pattern(space)
            for j, i in enumerate(members):
                blocks.append((int(self.offsets[i]), pat, data[j]))
            L = np.stack([fl[1] for fl in fields]).reshape(shape)
            source_total += float(L.sum())
            if np.any(L):
                loads = load_form(space, L)
                for j, i in enumerate(members):
                    f[self.offsets[i] : self.offsets[i + 1]] += loads[j].ravel()
        return block_diagonal_csr(blocks, self.ndof), f, source_total

    def _faces_of(self, cond):
        return self.model.faces(cond.tag)

    def assemble(self):
        """Assemble the unconstrained system. Returns (K, f, bookkeeping dict)."""
        t0 = time.perf_counter()
        K, f, source_total = self._volume()
        t1 = time.perf_counter()
        extra = []
        neumann_faces, robin_faces, dirichlet_faces = {}, {}, {}
        for c in self.conditions:
            for pi, face in self._faces_of(c):
                key = (pi, face)
                fd = self.face_data(pi, face)
                where = f"patch {pi} face {face} (tag {c.tag!r})"
                if c.kind == "dirichlet":
                    dirichlet_faces.setdefault(key, []).append(c)
                elif c.kind == "neumann":
                    q = self._values(c.value, fd.x, fd.chans, "Neumann flux", where)
                    f[fd.dofs] += self._face_load(fd, q * fd.dAw)
                    neumann_faces.setdefault(key, []).append(q)
                else:
                    h = self._values(c.h, fd.x, fd.chans, "film coefficient h", where, positive=True)
                    Tinf = self._values(c.value, fd.x, fd.chans, "ambient temperature", where)
                    extra.append(self._face_matrix(fd, h * fd.dAw))
                    f[fd.dofs] += self._face_load(fd, h * Tinf * fd.dAw)
                    robin_faces.setdefault(key, []).append((h, Tinf))
        clash = set(dirichlet_faces) & (set(neumann_faces) | set(robin_faces))
        if clash:
            pi, face = sorted(clash)[0]
            raise ProblemError(
                f"patch {pi} face {face} has a Dirichlet condition and a Neumann/Robin condition; give each face one kind"
            )
        if extra:
            K = (K + sum(extra)).tocsr()
        self.timings["assembly_volume"] = t1 - t0
        self.timings["assembly_faces"] = time.perf_counter() - t1
        return K, f, {"neumann": neumann_faces, "robin": robin_faces, "dirichlet": dirichlet_faces,
                      "source": source_total}

    def _dirichlet_values(self, dirichlet_faces, P=None):
        """Prescribed unknowns from the Dirichlet data (L2 projection onto the Dirichlet trace space).

        Returns (prescribed unknowns, their values, {face: int_face N_i}).  With ``P``
        (constraints) the unknowns are reduced ones: the masters owning a Dirichlet DOF.
        """
        if not dirichlet_faces:
            return np.zeros(0, np.int64), np.zeros(0), {}
        mats, rhs = [], np.zeros(self.ndof)
        integrals = {}
        for (pi, face), conds in dirichlet_faces.items():
            fd = self.face_data(pi, face)
            g = self._values(conds[-1].value, fd.x, fd.chans, "Dirichlet value", f"patch {pi} face {face}")
            mats.append(self._face_matrix(fd, fd.dAw))
            rhs[fd.dofs] += self._face_load(fd, g * fd.dAw)
            vec = np.zeros(self.ndof)
            vec[fd.dofs] = self._face_load(fd, fd.dAw)
            integrals[(pi, face)] = vec if P is None else P.T @ vec
        M = sum(mats).tocsr()
        # L2 projection in the unconstrained space over all Dirichlet faces; DOFs whose
        # functions have no trace there (e.g. masked parts of slot faces) are not prescribed
        cand = np.unique(np.concatenate([self.face_data(*k).dofs for k in dirichlet_faces]))
        diag = M.diagonal()[cand]
        dofs = cand[diag > 1e-14 * max(diag.max(), 1e-300)]
        Mdd = M[dofs][:, dofs].tocsc()
        vals = np.atleast_1d(spla.spsolve(Mdd, rhs[dofs]) if len(dofs) > 1 else rhs[dofs] / Mdd.toarray().ravel())
        if P is not None:
            # prescribe the reduced unknowns owning a Dirichlet DOF (mean of their members' values);
            # slave DOFs on Dirichlet faces follow their constraints
            owners = P.dof_master[dofs]
            keep = owners >= 0
            red, inv = np.unique(owners[keep], return_inverse=True)
            vals = np.bincount(inv, weights=vals[keep]) / np.bincount(inv)
            dofs = red
        integrals = {k: v[dofs] for k, v in integrals.items()}
        return dofs, vals, integrals

    def _needs_constraints(self) -> bool:
        """Interfaces, or patches with full-multiplicity (discontinuity) knots, need a prolongation."""
        if self.model.interfaces:
            return True
        for s in self.spaces:
            for d in s.dirs:
                _, m = np.unique(d.knots, return_counts=True)
                if np.any(m[1:-1] >= d.degree + 1):
                    return True
        return False

    # ------------------------------------------------------------------ solve
    def solve(self, solver: str = "auto", tol: float = 1e-10, maxiter: int | None = None):
        """Assemble, apply the conditions, solve; returns a :class:`iga.Solution`."""
        from .solution import Solution

        kinds = {c.kind for c in self.conditions}
        if not ({"dirichlet", "robin"} & kinds):
            raise SingularProblemError(
                "the heat problem has no Dirichlet or Robin condition, so its temperature is only defined up to a "
                "constant (the system is singular); add problem.dirichlet(tag, T) or problem.robin(tag, h, T_inf)"
            )
        K, f, book = self.assemble()
        t0 = time.perf_counter()
        P = None
        self.constraint_stats = {}
        if self._needs_constraints():
            from .constraints import prolongation

            P, self.constraint_stats = prolongation(self)
        nred = self.ndof if P is None else P.shape[1]
        dofs, g, integrals = self._dirichlet_values(book["dirichlet"], P)
        free = np.setdiff1d(np.arange(nred), dofs)
        if P is None:  # one unconstrained patch: eliminate by column selection
            A = K[free][:, free].tocsr()
            rhs = f[free] - K[free][:, dofs] @ g if len(dofs) else f[free]
        else:
            Pf, Pd = P[:, free].tocsc(), P[:, dofs].tocsc()
            A = (Pf.T @ K @ Pf).tocsr()
            rhs = Pf.T @ (f - K @ (Pd @ g)) if len(dofs) else Pf.T @ f
        self.timings["constraints"] = time.perf_counter() - t0
        x, info = solvers.solve(A, rhs, method=solver, tol=tol, maxiter=maxiter)
        ured = np.zeros(nred)
        ured[dofs] = g
        ured[free] = x
        u = ured if P is None else P @ ured
        self.timings["solve"] = info.setup_s + info.solve_s
        self.reduced_dofs = int(len(free))
        return Solution(self, u, K, f, book, dofs, integrals, info, P)
