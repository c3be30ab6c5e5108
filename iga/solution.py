"""Post-processing of a solved heat problem: probes, fluxes, energy balance, errors."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from geometry import SplineFunction

from .coefficients import tensor_matrix
from .errors import ProblemError
from .geometry_eval import patch_geometry_grid, patch_geometry_points
from .model import tag_faces


class Solution:
    """Temperature field of a :class:`iga.HeatProblem`.

    Attributes
    ----------
    u : (ndof,) all coefficients (patch blocks in order)
    info : dict with DOF counts, solver diagnostics (method, iterations,
        residual), timings (s) and the energy balance
    """

    def __init__(self, problem, u, book, dirichlet_dofs, reaction, dirichlet_integrals, solver_info):
        self.problem = problem
        self.u = u
        self._book = book
        # consistent boundary fluxes: the residual K u - f on the prescribed (reduced) unknowns
        self._reaction = np.asarray(reaction, float)
        self._dirichlet_dofs = dirichlet_dofs
        self._dirichlet_integrals = dirichlet_integrals
        self._splines = {}
        self._trees = None
        self.face_flows = self._face_flows()
        self.info = {
            "dofs": problem.ndof,
            "free_dofs": int(problem.reduced_dofs),
            "constraints": dict(getattr(problem, "constraint_stats", {})),
            "patches": len(problem.model.patches),
            "solver": solver_info.as_dict(),
            "timings": dict(problem.timings),
            "balance": self.balance(),
        }

    # ---------------------------------------------------------------- fields
    def temperature_spline(self, pi: int) -> SplineFunction:
        """The temperature on patch ``pi`` as a scalar spline over the patch parameters."""
        if pi not in self._splines:
            space = self.problem.spaces[pi]
            o = self.problem.offsets
            coef = self.u[o[pi] : o[pi + 1]].reshape(space.shape + (1,))
            self._splines[pi] = SplineFunction([d.degree for d in space.dirs], [d.knots for d in space.dirs], coef)
        return self._splines[pi]

    def evaluate(self, pi: int, params):
        """Temperature (N,), gradient (N, 3) in physical space, and x (N, 3) at parameters of patch ``pi``."""
        params = np.asarray(params, float)
        T = self.temperature_spline(pi)
        val = T.evaluate(params)[:, 0]
        dxi = T.jacobian(params)[:, 0, :]
        x, J, chans = patch_geometry_points(self.problem.model.patches[pi], params)
        grad = np.linalg.solve(np.transpose(J, (0, 2, 1)), dxi[:, :, None])[:, :, 0]
        return val, grad, x, chans

    def conductivity_at(self, x, chans, pi):
        """Conductivity at points x (N, 3) of patch ``pi``: (N,) isotropic or (N, 6) tensor components."""
        return self.problem.conductivity.values(x, chans, f"patch {pi}")

    def heat_flux(self, pi: int, params) -> np.ndarray:
        """Heat flux vector q = -K grad T (W/m^2) at parameters of patch ``pi``, (N, 3)."""
        _, grad, x, chans = self.evaluate(pi, params)
        return flux_vector(self.conductivity_at(x, chans, pi), grad)

    # ----------------------------------------------------------------- probes
    def locate(self, points, tol: float = 1e-10):
        """Point inversion: (patch index (N,), parameters (N, 3)) of physical points (N, 3).

        Candidate patches come from bounding boxes; a KD-tree of sampled points
        gives the start of a vectorised Newton iteration per patch.  Raises
        :class:`ProblemError` listing the points found in no patch.
        """
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
            raise ProblemError(f"probe points must be a finite array of shape (N, 3), got {np.shape(points)}")
        if self._trees is None:
            self._trees = []
            for patch in self.problem.model.patches:
                axes = [np.linspace(U[0], U[-1], 4 * len(np.unique(U)) + 2) for U in patch.spline.knots]
                x, _, _ = patch_geometry_grid(patch, axes)
                grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
                pad = 1e-9 * max(1.0, np.abs(x).max())
                self._trees.append((cKDTree(x), grid, x.min(0) - pad, x.max(0) + pad))
        where = np.full(len(pts), -1)
        params = np.zeros((len(pts), 3))
        scale = max(1.0, np.abs(pts).max()) if len(pts) else 1.0
        for pi, (tree, grid, lo, hi) in enumerate(self._trees):
            cand = np.nonzero((where < 0) & np.all((pts >= lo) & (pts <= hi), axis=1))[0]
            if not len(cand):
                continue
            patch = self.problem.model.patches[pi]
            dom = patch.spline.domain
            _, nearest = tree.query(pts[cand])
            xi = grid[nearest].copy()
            for _ in range(30):
                x, J, _ = patch_geometry_points(patch, xi)
                r = x - pts[cand]
                step = np.linalg.solve(J, r[:, :, None])[:, :, 0]
                xi = np.clip(xi - step, dom[:, 0], dom[:, 1])
                if np.max(np.abs(step)) < 1e-14:
                    break
            x, _, _ = patch_geometry_points(patch, xi)
            ok = np.linalg.norm(x - pts[cand], axis=1) <= tol * scale
            where[cand[ok]] = pi
            params[cand[ok]] = xi[ok]
        missing = np.nonzero(where < 0)[0]
        if len(missing):
            show = np.round(pts[missing[:5]], 6).tolist()
            raise ProblemError(f"{len(missing)} probe point(s) lie outside the model, e.g. {show}")
        return where, params

    def probe(self, points) -> np.ndarray:
        """Temperature at physical points (N, 3) -> (N,)."""
        where, params = self.locate(points)
        out = np.empty(len(where))
        for pi in np.unique(where):
            sel = where == pi
            out[sel] = self.temperature_spline(int(pi)).evaluate(params[sel])[:, 0]
        return out

    # ----------------------------------------------------------------- fluxes
    def _face_flows(self) -> dict:
        """Outward heat flow (W) through every face that carries a condition."""
        prob, book = self.problem, self._book
        flows = {}
        for key, q in book["neumann"].items():
            flows[key] = flows.get(key, 0.0) - float(np.sum(q * prob.face_data(*key).dAw))
        for key, (h, Tinf) in book["robin"].items():
            fd = prob.face_data(*key)
            flows[key] = flows.get(key, 0.0) + float(np.sum(h * (fd.trace(self.u) - Tinf) * fd.dAw))
        if self._dirichlet_integrals:
            # split each prescribed unknown's reaction among the faces by their share of int N_i dA
            total = sum(self._dirichlet_integrals.values())
            safe = np.where(total != 0, total, 1.0)
            for key, integ in self._dirichlet_integrals.items():
                flows[key] = flows.get(key, 0.0) - float(np.sum(self._reaction * integ / safe))
        return flows

    def flux(self, tag: str) -> float:
        """Heat flow through the faces tagged ``tag`` in W, outward positive.

        Dirichlet faces use the consistent reaction (residual) flux, Neumann
        faces the prescribed flux, Robin faces h (T - T_inf); insulated faces
        contribute nothing.
        """
        faces = set(tag_faces(self.problem.model, tag))
        return float(sum(self.face_flows.get(f, 0.0) for f in faces))

    def balance(self) -> dict:
        """Global energy balance: inflow + sources = outflow (W), and the relative error."""
        flows = np.array(list(self.face_flows.values())) if self.face_flows else np.zeros(0)
        src = self._book["source"]
        inflow = float(-flows[flows < 0].sum()) + max(src, 0.0)
        outflow = float(flows[flows > 0].sum()) + max(-src, 0.0)
        scale = max(inflow, outflow, 1e-300)
        return {"inflow_W": inflow, "outflow_W": outflow, "source_W": src,
                "relative_error": abs(inflow - outflow) / scale}

    # ------------------------------------------------------------------ errors
    def _quadrature(self, fn):
        """sum over patches and Gauss points of fn(x, T, gradT) * |J| w."""
        total = 0.0
        for pi, (patch, space) in enumerate(zip(self.problem.model.patches, self.problem.spaces)):
            x, J, _ = patch_geometry_grid(patch, space.qaxes)
            w = np.einsum("i,j,k->ijk", *[d.qw for d in space.dirs]).ravel()
            T = self.temperature_spline(pi)
            G = T.evaluate_grid(space.qaxes).reshape(-1)
            dxi = np.stack([T.evaluate_grid(space.qaxes, tuple(int(i == k) for i in range(3))).reshape(-1)
                            for k in range(3)], -1)
            grad = np.linalg.solve(np.transpose(J, (0, 2, 1)), dxi[:, :, None])[:, :, 0]
            total += float(np.sum(fn(x, G, grad) * np.abs(np.linalg.det(J)) * w))
        return total

    def l2_error(self, exact) -> float:
        """|| T - exact ||_L2 over the model; ``exact(x (N, 3)) -> (N,)``."""
        return float(np.sqrt(self._quadrature(lambda x, T, g: (T - exact(x)) ** 2)))

    def h1_error(self, exact_grad) -> float:
        """| T - exact |_H1 (gradient seminorm); ``exact_grad(x) -> (N, 3)``."""
        return float(np.sqrt(self._quadrature(lambda x, T, g: np.sum((g - exact_grad(x)) ** 2, axis=1))))


def flux_vector(K: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Heat flux -K grad T (N, 3) for conductivity K (N,) or (N, 6) tensor components and gradients (N, 3)."""
    if K.ndim == 1:
        return -K[:, None] * grad
    return -np.einsum("nij,nj->ni", tensor_matrix(K), grad)
