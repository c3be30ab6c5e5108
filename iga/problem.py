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

from .errors import ProblemError, SingularProblemError
from .constraints import induced_elimination
from . import fast_assembly
from .assembly import banded_form, banded_to_csr_data, block_diagonal_csr, load_form, pattern, stiffness_data
from .geometry_eval import checked_det, patches_geometry_derivs, patches_geometry_derivs_slabs
from .model import Patch, as_model
from .space import FACE_AXES, make_space


_IN_PLACE_NNZ = 1 << 22  # in-place Dirichlet elimination from this many entries (numba)
_CHUNK_POINTS = 1 << 18  # Gauss points evaluated together: bounds the batch's memory
# Gauss points per slab of the compiled assembly (at least one element): the fused geometry-metric
# pass (6 doubles per point) takes larger slabs, so that the direction-2/1 contractions are shared by
# more planes (1M-unknown cube: 1.8 s instead of 2.0 s); the general pass keeps about 40 MB of fields
_COMPILED_SLAB_POINTS = 1 << 18
_FUSED_SLAB_POINTS = 1 << 20


_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # symmetric stiffness components


def _chunks(members, points_each):
    """Split ``members`` into batches of at most about ``_CHUNK_POINTS`` Gauss points."""
    size = max(1, _CHUNK_POINTS // max(int(points_each), 1))
    return [members[i : i + size] for i in range(0, len(members), size)]


def _eliminate(K: sp.csr_matrix, f: np.ndarray, free: np.ndarray, dofs: np.ndarray, g: np.ndarray,
               in_place: bool = False):
    """``K[free][:, free]`` and ``f[free] - K[free][:, dofs] @ g`` in O(nnz) array operations.

    SciPy's column fancy indexing is several times slower on large matrices;
    here the kept rows are sliced once and their columns filtered by a map.
    ``in_place``: K may be destroyed; for large matrices the compiled kernel
    (numba) then compacts K inside its own arrays, so no second matrix is
    allocated (on the 1M-unknown cube this saves 1.4 GB and most of the time).
    """
    n = K.shape[0]
    ug = np.zeros(n)
    ug[dofs] = g
    rhs = f[free] - (K @ ug)[free] if len(dofs) else f[free].copy()
    if in_place and fast_assembly.AVAILABLE and K.nnz >= _IN_PLACE_NNZ:
        return fast_assembly.compact_rows_cols(K, free), rhs
    Kr = K[free]  # row selection (fast in SciPy)
    col = np.full(n, -1, np.int64)
    col[free] = np.arange(len(free))
    new = col[Kr.indices]
    keep = new >= 0
    dropped = np.flatnonzero(~keep)  # few: the Dirichlet columns of the kept rows
    indptr = Kr.indptr - np.searchsorted(dropped, Kr.indptr)
    idx = new[keep]
    A = sp.csr_matrix((Kr.data[keep], idx.astype(np.int32) if len(free) < 2**31 else idx, indptr),
                      shape=(len(free), len(free)))
    return A, rhs


def _solve_mass(M: sp.csc_matrix, b: np.ndarray) -> np.ndarray:
    """Solve the SPD boundary mass system of the Dirichlet projection.

    Jacobi-preconditioned CG to 1e-14 (mass matrices are well conditioned once
    their diagonal is scaled; 10x faster than SuperLU on a 14k-DOF cube
    boundary), with a sparse LU fallback if CG stalls.
    """
    if M.shape[0] <= 200:
        return np.atleast_1d(np.linalg.solve(M.toarray(), b))
    d = M.diagonal()
    x, info = spla.cg(M, b, rtol=1e-14, atol=0.0, maxiter=2000, M=sp.diags(1.0 / d))
    if info != 0 or not np.all(np.isfinite(x)):
        x = spla.splu(M.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(b)
    return x


def _by_space(fds) -> dict:
    """Indices of face data grouped by face space."""
    out: dict = {}
    for i, fd in enumerate(fds):
        out.setdefault(fd.space.key(), []).append(i)
    return out


def _cross(a, b, axis=-1):
    """Cross product along ``axis`` written out (np.cross is slow for many small vectors)."""
    a, b = np.moveaxis(a, axis, 0), np.moveaxis(b, axis, 0)
    c = np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
    return np.moveaxis(c, 0, axis)


def _metric_fields(D, kval, fval, w):
    """NumPy twin of :func:`iga._assembly_kernels.metric_fields`: C (6, M), L (M,), det (M,) from D [(P, n, 3)] * 3."""
    Du, Dv, Dw = (np.moveaxis(d.reshape(-1, 3), 1, 0) for d in D)  # (3, M) component-major views
    c = (_cross(Dv, Dw, 0), _cross(Dw, Du, 0), _cross(Du, Dv, 0))
    det = Du[0] * c[0][0] + Du[1] * c[0][1] + Du[2] * c[0][2]
    adet = np.abs(det)
    L = fval * adet * w
    with np.errstate(divide="ignore", invalid="ignore"):  # zero det: reported by checked_det
        fac = kval * w / adet
    C = np.empty((6, len(det)))
    for j, (r, t) in enumerate(_PAIRS):
        out = C[j]
        np.multiply(c[r][0], c[t][0], out=out)
        out += c[r][1] * c[t][1]
        out += c[r][2] * c[t][2]
        out *= fac
    return C, L, det


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
        """Geometry and DOFs of one patch face at its Gauss points (see :meth:`faces_data`)."""
        return self.faces_data([(pi, face)])[0]

    def faces_data(self, keys) -> list[FaceData]:
        """Geometry and DOFs of patch faces ``[(patch, face), ...]`` at their Gauss points.

        ``face`` is one of the six patch faces or a slot face id (``u=0.5-``:
        the discontinuity plane u = 0.5 seen from u < 0.5), integrated on the
        one-sided sub-patch and restricted to the model's free region of it.
        Faces of patches that share a tile spline are evaluated together (one
        tile evaluation, one deformation-map evaluation); results are cached.
        """
        from tiling.microstructure import parse_slot_face

        cache = self.__dict__.setdefault("_face_cache", {})
        groups: dict = {}
        for pi, face in keys:
            if (pi, face) in cache:
                continue
            if not (0 <= pi < len(self.model.patches)):
                raise ProblemError(f"patch index {pi} out of range (the model has {len(self.model.patches)} patches)")
            if face not in FACE_AXES and parse_slot_face(face) is None:
                raise ProblemError(f"unknown face {face!r}; use umin .. wmax or a slot face id such as 'u=0.5-'")
            gk = (id(self.model.patches[pi].spline), self.spaces[pi].key(), face)
            groups.setdefault(gk, []).append(pi)
        for (_, _, face), members in groups.items():
            for chunk in _chunks(members, self.spaces[members[0]].nq_total // min(self.spaces[members[0]].qshape)):
                self._face_group(chunk, face)
        return [cache[(pi, face)] for pi, face in keys]

    def _face_group(self, members, face):
        """Fill the face cache for ``face`` of patches ``members`` (same tile spline and space)."""
        from tiling.microstructure import parse_slot_face

        cache = self._face_cache
        patch0, space = self.model.patches[members[0]], self.spaces[members[0]]
        slot = parse_slot_face(face)
        if slot is None:
            k, side = FACE_AXES[face]
            U = patch0.spline.knots[k]
            at = U[-1] if side else U[0]
            geos = [self.model.patches[pi] for pi in members]
            dofs = space.face_dofs(face)
        else:
            k, at, sgn = slot
            side = 1 if sgn < 0 else 0  # u=v- is the max face of the sub-patch below the plane
            box = patch0.spline.domain.copy()
            box[k] = [box[k, 0], at] if sgn < 0 else [at, box[k, 1]]
            sub = patch0.spline.extract(box)
            geos = [Patch(sub, p.placement, p.outer, p.tile, p.level) for p in (self.model.patches[pi] for pi in members)]
            first = int(np.searchsorted(space.dirs[k].knots, at, side="left"))
            layer = first - 1 if sgn < 0 else first
            dofs = np.take(np.arange(space.ndof).reshape(space.shape), layer, axis=k).ravel()
        axes = [d.qpts for d in space.dirs]
        axes[k] = np.array([at])
        x, Dx, chans = patches_geometry_derivs(geos, axes)
        a, b = [i for i in range(3) if i != k]
        cr = _cross(Dx[a], Dx[b])
        dA = np.linalg.norm(cr, axis=-1)
        if np.any(dA <= 0):
            bad = members[int(np.argmax(np.any(dA <= 0, axis=1)))]
            raise ProblemError(f"patch {bad} face {face} is degenerate (zero area at some Gauss points)")
        inward = np.einsum("pni,pni->pn", cr, Dx[k])
        sign = np.where(inward > 0, 1.0, -1.0) * (1.0 if side else -1.0)
        normal = cr / dA[..., None] * sign[..., None]
        fs = space.face_space("umin" if k == 0 else "vmin" if k == 1 else "wmin")
        w = np.multiply.outer(fs.dirs[0].qw, fs.dirs[1].qw).ravel()
        dAw = dA * w
        if slot is not None:
            rest = [i for i in range(3) if i != k]
            q1, q2 = np.meshgrid(space.dirs[rest[0]].qpts, space.dirs[rest[1]].qpts, indexing="ij")
            for j, pi in enumerate(members):
                rects = self.model.face_regions.get((pi, face))
                if rects is None:
                    raise ProblemError(f"patch {pi} has no free region recorded for slot face {face!r}")
                mask = np.zeros(q1.shape, bool)
                for (a1, b1), (a2, b2) in rects:
                    mask |= (q1 > a1) & (q1 < b1) & (q2 > a2) & (q2 < b2)
                dAw[j] *= mask.ravel()
        for j, pi in enumerate(members):
            cache[(pi, face)] = FaceData(pi, face, fs, dofs + self.offsets[pi], x[j], {c: v[j] for c, v in chans.items()},
                                         dAw[j], normal[j])

    def _face_field(self, spec, fds, what, tag, positive=False) -> list[np.ndarray]:
        """A number / channel / callable evaluated on several faces at once -> one (N_f,) array per face."""
        if not fds:
            return []
        x = np.concatenate([fd.x for fd in fds])
        common = [c for c in fds[0].chans if all(c in fd.chans for fd in fds)]
        chans = {c: np.concatenate([fd.chans[c] for fd in fds]) for c in common}
        first = fds[0]
        where = f"the faces tagged {tag!r} (e.g. patch {first.patch} face {first.face})"
        v = self._values(spec, x, chans, what, where, positive)
        return np.split(v, np.cumsum([len(fd.x) for fd in fds])[:-1])

    def _face_loads(self, fds, Fs) -> np.ndarray:
        """Global vector sum over faces of int F N_i (F per face at its Gauss points)."""
        return np.asarray(self._face_loads_matrix(fds, Fs).sum(axis=1)).ravel()

    def _face_loads_matrix(self, fds, Fs) -> sp.csc_matrix:
        """Sparse (ndof, n_faces): column f holds int F_f N_i over face f (one load_form per face space)."""
        rows, cols, vals = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0)]
        for idx in _by_space(fds).values():
            space = fds[idx[0]].space
            L = load_form(space, np.stack([Fs[i] for i in idx]).reshape((len(idx),) + space.qshape))
            rows.append(np.stack([fds[i].dofs for i in idx]).ravel())
            cols.append(np.repeat(idx, space.ndof))
            vals.append(L.reshape(-1))
        return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.ndof, len(fds)))

    def _face_matrix(self, fds, Fs) -> sp.csr_matrix:
        """Global sparse sum over faces of int F N_i N_j (F per face at its Gauss points)."""
        rows, cols, vals = [], [], []
        for idx in _by_space(fds).values():
            space = fds[idx[0]].space
            F = np.stack([Fs[i] for i in idx]).reshape((len(idx),) + space.qshape)
            data = banded_to_csr_data(space, banded_form(space, [(F, ((0, 0), (0, 0)))]))
            pat = pattern(space)
            dofs = np.stack([fds[i].dofs for i in idx])
            local_rows = np.repeat(np.arange(pat.n), np.diff(pat.indptr))
            rows.append(dofs[:, local_rows].ravel())
            cols.append(dofs[:, pat.indices].ravel())
            vals.append(data.ravel())
        if not rows:
            return sp.csr_matrix((self.ndof, self.ndof))
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.ndof, self.ndof))

    def _stiffness_slabs(self, members, space, compiled=False):
        """k |J| w J^-1 J^-T on the Gauss grid of patches ``members`` (same tile spline and space), by slabs.

        Yields ``(planes, C, L)``: ``planes`` a slice of whole elements' Gauss
        planes along the first axis, C (6, P, n) the six symmetric components
        in the order (0,0), (1,1), (2,2), (0,1), (0,2), (1,2) and L (P, n) the
        source load field on those planes (n points per patch, C order).
        With c_1 = x_v x x_w, c_2 = x_w x x_u, c_3 = x_u x x_v (the rows of
        det J * J^-1), k |J| J^-1 J^-T = k (c_r . c_s) / |det J|.  Slabs hold
        about 16k points (compiled: 2^18, or 2^20 in the fused pass; at least
        one element): the full-grid geometry never exists.  ``compiled``: the
        arithmetic runs in the numba kernels of :mod:`iga.fast_assembly` (same
        formulas), geometry and metric fused for patches without placement or
        map and with constant k and f (:func:`iga.fast_assembly.metric_slabs`).
        """
        patches = [self.model.patches[i] for i in members]
        P = len(members)
        where = f"patch {members[0]}" if P == 1 else f"patches {members[0]}..{members[-1]}"
        lo, hi = np.inf, -np.inf  # det range over all slabs: a sign change between slabs is a fold too
        if (compiled and _is_number(self.conductivity) and _is_number(self.source)
                and all(p.placement is None and p.outer is None for p in patches)):
            # x = spline(xi), k and f constant: geometry and metric in one compiled pass (the patches of
            # the group are the same spline, so one evaluation serves them all)
            for planes, C, L, det in fast_assembly.metric_slabs(patches[0].spline, space, _FUSED_SLAB_POINTS,
                                                                self.conductivity, self.source):
                a, b = checked_det(det, where)
                lo, hi = min(lo, a), max(hi, b)
                n = len(L)
                yield planes, np.broadcast_to(C[:, None], (6, P, n)), np.broadcast_to(L, (P, n))
            checked_det(np.array([lo, hi]), where)
            return
        # compiled: larger slabs, since the kernels re-contract the p + 1 coefficient rows a slab
        # touches (a 2^18-point slab holds about 40 MB of fields); NumPy: cache-sized temporaries
        w_rest = np.multiply.outer(space.dirs[1].qw, space.dirs[2].qw).ravel()  # weights of one plane
        slabs = patches_geometry_derivs_slabs(patches, space.qaxes, _COMPILED_SLAB_POINTS if compiled else 1 << 14,
                                              rows_multiple=space.dirs[0].g, compiled=compiled)
        for planes, x, D, chans in slabs:
            n = x.shape[1]
            flat = {ch: np.reshape(v, -1) for ch, v in chans.items()}
            kval = self._values(self.conductivity, x.reshape(-1, 3), flat, "conductivity", where, positive=True)
            fval = self._values(self.source, x.reshape(-1, 3), flat, "source", where)
            w = np.multiply.outer(space.dirs[0].qw[planes], w_rest).ravel()
            wv = np.broadcast_to(w, (P, n)).reshape(-1)
            if compiled:
                C, L, det = fast_assembly.metric_fields(D, kval, fval, wv)
            else:
                C, L, det = _metric_fields(D, kval, fval, wv)
            a, b = checked_det(det, where)
            lo, hi = min(lo, a), max(hi, b)
            yield planes, C.reshape(6, P, n), L.reshape(P, n)
        checked_det(np.array([lo, hi]), where)

    def _volume(self):
        """Stiffness (CSR) and source load over all patches, batched over patches sharing a tile and space."""
        blocks, f = [], np.zeros(self.ndof)
        groups: dict = {}
        for i, s in enumerate(self.spaces):
            groups.setdefault((s.key(), id(self.model.patches[i].spline)), []).append(i)
        source_total = 0.0
        for group in groups.values():
            space = self.spaces[group[0]]
            for members in _chunks(group, space.nq_total):
                P, N = len(members), space.nq_total
                shape = (P,) + space.qshape
                rest = N // space.dirs[0].nq
                if fast_assembly.applies(space, P):  # compiled: each slab goes straight into the CSR data and loads
                    acc = fast_assembly.StiffnessAccumulator(space, P)
                    for planes, Cs, Ls in self._stiffness_slabs(members, space, compiled=True):
                        source_total += float(Ls.sum())
                        acc.add(planes, Cs, Ls if np.any(Ls) else None)
                    pat, data = acc.result()
                    loads = acc.load
                else:
                    C, L = np.empty((6, P, N)), np.empty((P, N))
                    for planes, Cs, Ls in self._stiffness_slabs(members, space):
                        C[:, :, planes.start * rest : planes.stop * rest] = Cs
                        L[:, planes.start * rest : planes.stop * rest] = Ls
                    pat = pattern(space)
                    data = stiffness_data(space, {rs: C[j].reshape(shape) for j, rs in enumerate(_PAIRS)}, pat)
                    del C
                    source_total += float(L.sum())
                    loads = load_form(space, L.reshape(shape)) if np.any(L) else None
                for j, i in enumerate(members):
                    blocks.append((int(self.offsets[i]), pat, data[j]))
                if loads is not None:
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
        neumann_faces, robin_faces, dirichlet_faces = {}, {}, {}
        self.faces_data([key for c in self.conditions for key in self._faces_of(c)])
        robin_fds, robin_F = [], []
        for c in self.conditions:
            keys = self._faces_of(c)
            fds = self.faces_data(keys)
            if c.kind == "dirichlet":
                for key in keys:
                    dirichlet_faces.setdefault(key, []).append(c)
            elif c.kind == "neumann":
                qs = self._face_field(c.value, fds, "Neumann flux", c.tag)
                f += self._face_loads(fds, [q * fd.dAw for q, fd in zip(qs, fds)])
                for key, q in zip(keys, qs):
                    neumann_faces.setdefault(key, []).append(q)
            else:
                hs = self._face_field(c.h, fds, "film coefficient h", c.tag, positive=True)
                Ts = self._face_field(c.value, fds, "ambient temperature", c.tag)
                robin_fds += fds
                robin_F += [h * fd.dAw for h, fd in zip(hs, fds)]
                f += self._face_loads(fds, [h * T * fd.dAw for h, T, fd in zip(hs, Ts, fds)])
                for key, h, T in zip(keys, hs, Ts):
                    robin_faces.setdefault(key, []).append((h, T))
        clash = set(dirichlet_faces) & (set(neumann_faces) | set(robin_faces))
        if clash:
            pi, face = sorted(clash)[0]
            raise ProblemError(
                f"patch {pi} face {face} has a Dirichlet condition and a Neumann/Robin condition; give each face one kind"
            )
        if robin_fds:
            K = (K + self._face_matrix(robin_fds, robin_F)).tocsr()
        self.timings["assembly_volume"] = t1 - t0
        self.timings["assembly_faces"] = time.perf_counter() - t1
        return K, f, {"neumann": neumann_faces, "robin": robin_faces, "dirichlet": dirichlet_faces,
                      "source": source_total}

    def _dirichlet_values(self, dirichlet_faces, P=None):
        """Prescribed unknowns from the Dirichlet data (L2 projection onto the Dirichlet trace space).

        Returns a dict: ``dofs`` (prescribed unknowns) and ``values``; ``G``, a
        sparse (unknowns x faces) matrix whose column f holds int_f N_i dA, with
        ``keys`` its faces; and ``slave_rows`` / ``slave_values``: Dirichlet DOFs
        that are constrained by others (with ``P``), which fix a combination of
        unknowns rather than one (see :func:`iga.constraints.induced_elimination`).
        """
        empty = np.zeros(0, np.int64)
        if not dirichlet_faces:
            return {"dofs": empty, "values": np.zeros(0), "G": None, "keys": [], "slave_rows": empty,
                    "slave_values": np.zeros(0)}
        keys = list(dirichlet_faces)
        fds = self.faces_data(keys)
        by_cond: dict = {}
        for j, key in enumerate(keys):
            by_cond.setdefault(id(dirichlet_faces[key][-1]), []).append(j)
        gs = [None] * len(keys)
        for idx in by_cond.values():
            cond = dirichlet_faces[keys[idx[0]]][-1]
            for j, g in zip(idx, self._face_field(cond.value, [fds[j] for j in idx], "Dirichlet value", cond.tag)):
                gs[j] = g
        M = self._face_matrix(fds, [fd.dAw for fd in fds])
        rhs = self._face_loads(fds, [g * fd.dAw for g, fd in zip(gs, fds)])
        G = self._face_loads_matrix(fds, [fd.dAw for fd in fds])  # column per face: int N_i dA
        # L2 projection in the unconstrained space over all Dirichlet faces; DOFs whose
        # functions have no trace there (e.g. masked parts of slot faces) are not prescribed
        cand = np.unique(np.concatenate([fd.dofs for fd in fds]))
        diag = M.diagonal()[cand]
        dofs = cand[diag > 1e-14 * max(diag.max(), 1e-300)]
        Mdd = M[dofs][:, dofs].tocsc()
        vals = _solve_mass(Mdd, rhs[dofs])
        slave_rows, slave_vals = empty, np.zeros(0)
        if P is not None:
            # prescribe the reduced unknowns owning a Dirichlet DOF (mean of their members' values);
            # Dirichlet DOFs of slave classes constrain combinations of unknowns (handled in solve)
            owners = P.dof_master[dofs]
            keep = owners >= 0
            slave_rows, slave_vals = dofs[~keep], vals[~keep]
            red, inv = np.unique(owners[keep], return_inverse=True)
            vals = np.bincount(inv, weights=vals[keep]) / np.bincount(inv)
            dofs = red
            G = (P.T @ G).tocsc()
        return {"dofs": dofs, "values": vals, "G": G.tocsr(), "keys": keys, "slave_rows": slave_rows,
                "slave_values": slave_vals}

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
        dd = self._dirichlet_values(book["dirichlet"], P)
        dofs, g = dd["dofs"], dd["values"]
        free = np.setdiff1d(np.arange(nred), dofs)
        reaction_dofs = dofs
        self.constraint_stats.update({"prescribed": int(len(dofs)), "induced_rank": 0})
        if P is None:  # one unconstrained patch: eliminate by row and column selection
            Kd = K[reaction_dofs]  # rows needed for the reaction fluxes; K itself is consumed
            A, rhs = _eliminate(K, f, free, dofs, g, in_place=True)
            del K
        else:
            Pf, Pd = P[:, free].tocsc(), P[:, dofs].tocsc()
            offset = Pd @ g
            if len(dd["slave_rows"]):
                # slave DOFs on Dirichlet faces fix combinations of free unknowns: eliminate them
                Ps = P[dd["slave_rows"]]
                T, x0, touched = induced_elimination(Ps[:, free], dd["slave_values"] - Ps[:, dofs] @ g)
                offset = offset + Pf @ x0
                Pf = (Pf @ T).tocsc()
                reaction_dofs = np.concatenate([dofs, free[touched]])
                self.constraint_stats["induced_rank"] = int(len(free) - T.shape[1])
            A = (Pf.T @ K @ Pf).tocsr()
            rhs = Pf.T @ (f - K @ offset)
        self.timings["constraints"] = time.perf_counter() - t0
        x, info = solvers.solve(A, rhs, method=solver, tol=tol, maxiter=maxiter, overwrite_a=True)  # A is ours
        if P is None:
            u = np.zeros(nred)
            u[dofs] = g
            u[free] = x
            reaction = Kd @ u - f[reaction_dofs]
        else:
            u = Pf @ x + offset
            reaction = (P.T @ (K @ u - f))[reaction_dofs]
        self.timings["solve"] = info.setup_s + info.solve_s
        self.reduced_dofs = int(A.shape[0])
        Gd = dd["G"][reaction_dofs].toarray() if dd["G"] is not None else np.zeros((len(reaction_dofs), 0))
        integrals = {key: Gd[:, j] for j, key in enumerate(dd["keys"])}
        return Solution(self, u, book, reaction_dofs, reaction, integrals, info)
