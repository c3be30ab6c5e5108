"""Single-patch steady heat transfer: exactness, convergence, balance, output, errors."""

import numpy as np
import pytest
import scipy.sparse as sp

import solvers
from geometry import primitives as pr
from iga import HeatProblem, ProblemError, SingularProblemError, write_vtu
from iga.manufactured import quarter_annulus
from iga.assembly.tensor import banded_form, banded_to_csr_data, block_diagonal_csr, pattern, stiffness_data
from iga.discretisation.space import make_space
from helpers import vtk_cell_values


def test_sum_factorised_stiffness_equals_brute_force():
    rng = np.random.default_rng(0)
    U = [np.r_[0, 0, 0, 0.4, 1, 1, 1], np.r_[0, 0, 0.5, 0.5, 1, 1], np.r_[0, 0, 0, 0, 1, 1, 1, 1]]
    S = make_space(U, (2, 1, 3))
    F = rng.random((1,) + S.qshape)
    variants = ((1, 1), (0, 0), (0, 1))
    K = block_diagonal_csr([(0, pattern(S), banded_to_csr_data(S, banded_form(S, [(F, variants)]))[0])], S.ndof)
    assert (K.T - K).nnz > 0  # the (1,0) x (0,1) term is not symmetric: the transpose map matters below
    sym = stiffness_data(S, {(0, 2): F})[0]  # S + S^T for the pair (r, s) = (0, 2) and (2, 0)
    S02 = banded_to_csr_data(S, banded_form(S, [(F, ((1, 0), (0, 0), (0, 1)))]))[0]
    Ks = block_diagonal_csr([(0, pattern(S), S02)], S.ndof)
    assert np.abs(block_diagonal_csr([(0, pattern(S), sym)], S.ndof).toarray() - (Ks + Ks.T).toarray()).max() < 1e-12
    B = [d.B[:, :, :-1] for d in S.dirs]
    ref = np.einsum("abc,ia,jb,kc,la,mb,nc->ijklmn", F[0], B[0][1], B[1][0], B[2][0], B[0][1], B[1][0], B[2][1])
    assert np.abs(K.toarray() - ref.reshape(S.ndof, S.ndof)).max() < 1e-12 * np.abs(ref).max()


@pytest.mark.parametrize("shape, degrees", [((7, 5, 6), (2, 2, 2)), ((2, 5, 3), (3, 1, 2)), ((9, 4), (3, 1)), ((6,), (2,))])
def test_csr_pattern_matches_the_band_definition(shape, degrees):
    from iga.assembly.tensor import _pattern

    pat = _pattern(shape, degrees)
    # sparsity: the Kronecker product of the 1-D bands
    bands = [sp.csr_matrix(np.abs(np.subtract.outer(np.arange(n), np.arange(n))) <= p) for n, p in zip(shape, degrees)]
    ref = bands[0]
    for b in bands[1:]:
        ref = sp.kron(ref, b, format="csr")
    ref.sort_indices()
    assert np.array_equal(pat.indptr, ref.indptr) and np.array_equal(pat.indices, ref.indices)
    # take: entry (i, j) reads banded[i_1, j_1 - i_1 + p_1, ..., i_d, j_d - i_d + p_d]
    rng = np.random.default_rng(1)
    band = rng.random(tuple(x for n, p in zip(shape, degrees) for x in (n, 2 * p + 1)))
    K = sp.csr_matrix((band.reshape(-1)[pat.take], pat.indices, pat.indptr), shape=(pat.n, pat.n)).toarray()
    idx = np.indices(shape).reshape(len(shape), -1)
    dense = np.zeros((pat.n, pat.n))
    for a in range(pat.n):
        for b in range(pat.n):
            off = idx[:, b] - idx[:, a] + np.array(degrees)
            if np.all(np.abs(idx[:, b] - idx[:, a]) <= np.array(degrees)):
                dense[a, b] = band[tuple(x for k in range(len(shape)) for x in (idx[k, a], off[k]))]
    assert np.array_equal(K, dense)
    # transpose: data[transpose] is the data of K^T in the same pattern
    data = band.reshape(-1)[pat.take]
    KT = sp.csr_matrix((data[pat.transpose], pat.indices, pat.indptr), shape=(pat.n, pat.n)).toarray()
    assert np.array_equal(KT, K.T)


def _quadratic_problem(k):
    b = pr.box((1, 2, 1.5))
    T = lambda x: x[:, 0] ** 2 + x[:, 1] * x[:, 2]
    if callable(k):  # k = 1 + x: f = -(dk/dx dT/dx + k lap T) = -(2x + 2 (1 + x))
        f = lambda x: -(2 * x[:, 0] + 2 * (1 + x[:, 0]))
    else:
        f = -2.0 * k
    return b, T, f


@pytest.mark.parametrize("k", [1.0, lambda x: 1 + x[:, 0]])
@pytest.mark.parametrize("p", [2, 3])
def test_polynomial_solution_is_reproduced(k, p):
    b, T, f = _quadratic_problem(k)
    s = HeatProblem(b, conductivity=k, source=f, degree=p, refine=1).dirichlet("boundary", T).solve()
    assert s.l2_error(T) < 1e-12
    x = b.evaluate(np.random.default_rng(1).random((20, 3)))[:, :3]
    assert np.abs(s.probe(x) - T(x)).max() < 1e-11


# --------------------------------------------------------- manufactured solution
MS = quarter_annulus()  # exact NURBS quarter shell, variable k, closed-form T and f
ANNULUS, k_var, T_exact, grad_exact, f_exact = MS.geometry, MS.conductivity, MS.temperature, MS.gradient, MS.source


def convergence(p, levels):
    errs = []
    for r in levels:
        s = HeatProblem(ANNULUS, conductivity=k_var, source=f_exact, degree=p, refine=r).dirichlet("boundary", T_exact).solve()
        errs.append((s.l2_error(T_exact), s.h1_error(grad_exact)))
    e = np.array(errs)
    return np.log2(e[:-1] / e[1:])  # rates per refinement, columns L2, H1


@pytest.mark.slow
@pytest.mark.parametrize("p, levels", [(1, (3, 4, 5)), (2, (2, 3, 4)), (3, (3, 4, 5))])
def test_optimal_convergence_rates_on_curved_patch(p, levels):
    rates = convergence(p, levels)
    assert abs(rates[-1, 0] - (p + 1)) < 0.2, rates
    assert abs(rates[-1, 1] - p) < 0.2, rates


# --------------------------------------------------------------- energy balance
def test_energy_balance_neumann_in_robin_out():
    a = pr.annulus(0.5, 1.0, 1.0, elements=(2, 2, 2), channels={"k": 205.0})
    s = HeatProblem(a, conductivity="k", refine=1).neumann("vmin", 1515.8).robin("vmax", 5.0, 30.0).solve()
    b = s.info["balance"]
    assert b["relative_error"] < 1e-8
    area = np.pi / 2 * 0.5 * 1.0
    # Gauss quadrature of the rational (NURBS) area element is accurate, not exact
    assert s.flux("vmin") == pytest.approx(-1515.8 * area, rel=1e-7)
    assert s.flux("vmax") == pytest.approx(-s.flux("vmin"), rel=1e-8)
    T = s.probe(a.evaluate(np.random.default_rng(2).random((50, 3)))[:, :3])
    assert np.all(T > 30.0)


@pytest.mark.slow
def test_energy_balance_dirichlet_in_robin_out_with_source():
    a = pr.annulus(0.5, 1.0, 1.0, elements=(2, 2, 2))
    s = (HeatProblem(a, conductivity=lambda x: 1 + x[:, 2], source=3.0, refine=1)
         .dirichlet("vmin", lambda x: 100 + x[:, 2]).robin("vmax", 5.0, 30.0).robin("wmax", 2.0, 20.0).solve())
    b = s.info["balance"]
    assert b["relative_error"] < 1e-8
    assert b["source_W"] == pytest.approx(3.0 * np.pi / 4 * (1 - 0.25), rel=1e-7)  # quadrature of NURBS volume
    total = s.flux("vmin") + s.flux("vmax") + s.flux("wmax") + s.flux("umin") + s.flux("umax") + s.flux("wmin")
    assert total == pytest.approx(b["source_W"], rel=1e-8)
    assert s.flux("boundary") == pytest.approx(total, rel=1e-12)
    assert s.flux("vmin") < 0 < s.flux("vmax")
    # independent: the fluxes converge to those of a refined reference, and the Dirichlet data hold
    def solved(r):
        return (HeatProblem(a, conductivity=lambda x: 1 + x[:, 2], source=3.0, refine=r)
                .dirichlet("vmin", lambda x: 100 + x[:, 2]).robin("vmax", 5.0, 30.0).robin("wmax", 2.0, 20.0).solve())

    s2, ref = solved(2), solved(4)
    for tag in ("vmin", "vmax", "wmax"):
        e1, e2 = abs(s.flux(tag) - ref.flux(tag)), abs(s2.flux(tag) - ref.flux(tag))
        assert e1 < 3e-2 * abs(ref.flux(tag)) and e2 < e1 / 2, (tag, e1, e2)  # edge singularity: slow
    inner = a.evaluate(np.column_stack([np.random.default_rng(3).random(10), np.zeros(10), np.random.default_rng(4).random(10)]))[:, :3]
    assert np.abs(s.probe(inner) - (100 + inner[:, 2])).max() < 1e-3


def test_solver_backends_agree():
    a = pr.annulus(0.5, 1.0, 1.0, elements=(2, 2, 2))
    sols = [HeatProblem(a, refine=1).dirichlet("vmin", 1.0).robin("vmax", 2.0, 0.0).solve(solver=m) for m in ("direct", "amg-cg", "cg")]
    for s in sols[1:]:
        assert np.abs(s.u - sols[0].u).max() < 1e-8
    assert sols[1].info["solver"]["iterations"] > 0 and "residual" in sols[1].info["solver"]


# ------------------------------------------------------------------- output
def test_write_vtu_arrays(tmp_path):
    import pyvista as pv

    a = pr.annulus(0.5, 1.0, 1.0, elements=(2, 1, 1), channels={"k": 200.0})
    s = HeatProblem(a, conductivity="k").dirichlet("vmin", 50.0).robin("vmax", 5.0, 30.0).solve()
    path = write_vtu(tmp_path / "out.vtu", s)
    m = pv.read(path)
    for name in ("temperature", "heat_flux", "conductivity", "k"):
        assert name in m.point_data
    for name in ("patch", "tile", "level"):
        assert name in m.cell_data
    assert m.point_data["heat_flux"].shape[1] == 3
    assert np.all(m.compute_cell_sizes()["Volume"] > 0)
    assert np.allclose(m.point_data["conductivity"], 200.0)
    T = m.point_data["temperature"]
    assert 30.0 < T.min() and T.max() <= 50.0 + 1e-9
    assert not list(tmp_path.glob(".out.vtu*"))
    write_vtu(tmp_path / "model.vtu", a)  # geometry only
    assert "k" in pv.read(tmp_path / "model.vtu").point_data


# --------------------------------------------------------------- bad input
def test_bad_input_raises_project_errors(tmp_path):
    a = pr.annulus(0.5, 1.0, 1.0)
    with pytest.raises(ProblemError, match="unknown boundary tag 'top'"):
        HeatProblem(a).dirichlet("top", 1.0)
    with pytest.raises(ProblemError, match="finite positive number"):
        HeatProblem(a, conductivity=-1.0)
    with pytest.raises(ProblemError, match="finite positive number"):
        HeatProblem(a, conductivity=float("nan"))
    with pytest.raises(ProblemError, match="channel 'k'"):
        HeatProblem(a, conductivity="k")
    with pytest.raises(ProblemError, match="conductivity must be positive"):
        HeatProblem(a, conductivity=lambda x: x[:, 2] - 0.5).dirichlet("vmin", 1.0).solve()
    with pytest.raises(SingularProblemError, match="no Dirichlet, Robin or radiation"):
        HeatProblem(a).neumann("vmin", 1.0).solve()
    assert issubclass(SingularProblemError, solvers.SolverError) and issubclass(SingularProblemError, ProblemError)
    s = HeatProblem(a).dirichlet("vmin", 1.0).solve()
    with pytest.raises(ProblemError, match="outside the model"):
        s.probe([[5.0, 5.0, 5.0]])
    with pytest.raises(ProblemError, match="does not exist"):
        write_vtu(tmp_path / "no" / "x.vtu", s)
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    import os

    if os.geteuid() != 0:  # root ignores permission bits
        with pytest.raises(ProblemError, match="not writable"):
            write_vtu(ro / "x.vtu", s)
    with pytest.raises(ProblemError, match=r"Dirichlet condition \(tag 'vmin'\) and a neumann condition \(tag 'vmin'\); "
                                           "give each face one kind: one tag cannot carry both"):
        HeatProblem(a).dirichlet("vmin", 1.0).neumann("vmin", 2.0).solve()
    with pytest.raises(ProblemError, match="film coefficient"):
        HeatProblem(a).robin("vmin", -5.0, 1.0)


def test_jacobian_check_accepts_left_handed_patches_and_rejects_zeros_folds_and_nan():
    from iga.discretisation.jacobians import checked_det

    assert checked_det(np.array([-2.0, -0.5, -1.0]), "patch 0") == (-2.0, -0.5)
    assert checked_det(np.array([3.0, 1.0]), "patch 0") == (1.0, 3.0)
    for det, msg in (([1.0, 0.0, 2.0], "vanishes"), ([-1.0, 0.5], "changes sign"), ([1.0, np.nan], "not finite"),
                     ([np.inf, 1.0], "not finite"), ([-np.inf, -1.0], "not finite")):
        with pytest.raises(ProblemError, match=msg):
            checked_det(np.array(det), "patch 0")


def test_solver_errors():
    A = sp.csr_matrix(np.array([[1.0, -1.0], [-1.0, 1.0]]))
    with pytest.raises(solvers.SolverError, match="singular"):
        solvers.solve(A, np.array([1.0, 0.0]), method="direct")
    with pytest.raises(solvers.SolverError, match="non-finite"):
        solvers.solve(sp.csr_matrix(np.array([[np.nan]])), np.array([1.0]))
    with pytest.raises(solvers.SolverError, match="unknown solver"):
        solvers.solve(sp.identity(3, format="csr"), np.ones(3), method="magic")
    n = 200
    L = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n), format="csr")
    with pytest.raises(solvers.SolverError, match="did not converge: relative residual .* after 3 iterations"):
        solvers.solve(L, np.ones(n), method="cg", maxiter=3)


@pytest.mark.parametrize("case", ["rational annulus", "polynomial box", "composed micro-structure"])
def test_bezier_vtu_is_exact(tmp_path, case):
    # VTK evaluates each Bezier hexahedron (type 79) at random local coordinates: the point it
    # finds lies on the exact geometry and the temperature there equals the solution's probe
    import pyvista as pv

    import tiling
    from tiling import library as L

    T = lambda x: 1 + x[:, 0] ** 2 - x[:, 1] * x[:, 2]  # noqa: E731
    if case == "rational annulus":
        model = pr.annulus(0.5, 1.0, 1.0, angle=np.pi / 2)
    elif case == "polynomial box":
        model = pr.box((1.0, 2.0, 0.5), degrees=(2, 1, 3), elements=(2, 1, 2))
    else:
        model = tiling.hierarchical(ANNULUS, L.heat_sink_t1(), (2, 1), 2)  # tiles composed into a NURBS map
    s = HeatProblem(model, refine=1).dirichlet("boundary", T).solve()
    out = write_vtu(tmp_path / "exact.vtu", s, cells="bezier")
    g = pv.read(out)
    assert set(g.celltypes) == {79} and g.cell_data["HigherOrderDegrees"].shape == (g.n_cells, 3)
    assert ("RationalWeights" in g.point_data) == (case != "polynomial box")
    for name in ("patch", "tile", "level"):
        assert name in g.cell_data
    x, t = vtk_cell_values(g, np.random.default_rng(3))
    assert np.abs(t - s.probe(x)).max() < 1e-10
    assert [p.name for p in tmp_path.iterdir()] == ["exact.vtu"]  # nothing temporary left behind
    with pytest.raises(ProblemError, match="cells must be"):
        write_vtu(tmp_path / "x.vtu", s, cells="quadratic")


# ------------------------------------------------------- anisotropic conductivity
def _rotation():
    a, b = 0.7, -0.4
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return Rz @ Rx


def _anisotropic_case():
    """K = R diag(5, 1, 0.2) R^T; T = sin(n . x) + 0.3 (m . x)^2 with n, m the first two principal axes.

    K grad T = 5 cos(n . x) n + 0.6 (m . x) m, so -div(K grad T) = 5 sin(n . x) - 0.6: the source sees the
    eigenvalue of each principal direction, which a transposed or mis-ordered tensor would get wrong.
    """
    R = _rotation()
    K = R @ np.diag([5.0, 1.0, 0.2]) @ R.T
    n, m = R[:, 0], R[:, 1]

    def T(x):
        return np.sin(x @ n) + 0.3 * (x @ m) ** 2

    def grad(x):
        return np.cos(x @ n)[:, None] * n + 0.6 * (x @ m)[:, None] * m

    def f(x):
        return 5.0 * np.sin(x @ n) - 0.6

    return K, T, grad, f


@pytest.mark.parametrize("compiled", [False, True])
def test_anisotropic_conductivity_against_rotated_analytic_solution(compiled, monkeypatch):
    from iga.assembly import compiled as fast_assembly

    if compiled:
        pytest.importorskip("numba")
        monkeypatch.setattr(fast_assembly, "MIN_POINTS", 0)
    K, T, grad, f = _anisotropic_case()
    cube = pr.box(degrees=(2, 2, 2))
    errs = []
    for r in (1, 2, 3):
        s = HeatProblem(cube, conductivity=K, source=f, refine=r).dirichlet("boundary", T).solve(tol=1e-12)
        errs.append(s.l2_error(T))
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert errs[-1] < 2e-5 and abs(rates[-1] - 3) < 0.3, (errs, rates)
    # the flux -K grad T at points, against the analytic one
    params = np.random.default_rng(0).random((20, 3))
    q = s.heat_flux(0, params)
    assert np.abs(q + grad(params) @ K.T).max() < 1e-2 * np.abs(grad(params) @ K.T).max()


def test_anisotropic_conductivity_from_six_channels_and_isotropic_equivalence():
    K, T, grad, f = _anisotropic_case()
    comps = [K[0, 0], K[1, 1], K[2, 2], K[0, 1], K[0, 2], K[1, 2]]
    names = ("kxx", "kyy", "kzz", "kxy", "kxz", "kyz")
    cube = pr.box(degrees=(2, 2, 2), channels=dict(zip(names, comps)))
    a = HeatProblem(cube, conductivity=list(names), source=f, refine=2).dirichlet("boundary", T).solve(tol=1e-12)
    b = HeatProblem(cube, conductivity=K, source=f, refine=2).dirichlet("boundary", T).solve(tol=1e-12)
    assert np.abs(a.u - b.u).max() < 1e-10
    # a multiple of the identity given as a tensor is the isotropic problem
    c = HeatProblem(cube, conductivity=3.0 * np.eye(3), source=f, refine=1).dirichlet("boundary", T).solve(tol=1e-12)
    d = HeatProblem(cube, conductivity=3.0, source=f, refine=1).dirichlet("boundary", T).solve(tol=1e-12)
    assert np.abs(c.u - d.u).max() < 1e-12
