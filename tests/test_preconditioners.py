"""Spline-aware preconditioners: fast diagonalization (Sangalli and Tani 2016) and geometric multigrid whose
prolongations are the knot-insertion refinement matrices."""

import numpy as np
import pytest
import scipy.sparse as sp

import solvers
import tiling
from geometry import primitives as pr
from iga import HeatProblem, ProblemError
from iga.discretisation.multilevel import coarsen_knots, kronecker_sum, prolongations
from iga.discretisation.system import eliminate
from solvers import SolverError
from solvers.kronecker import BlockFastDiagonalization, FastDiagonalization, KroneckerSum
from solvers.multigrid import Multigrid
from tiling import library as L


def _reduced(problem):
    """The Dirichlet-reduced matrix and right-hand side of a single-patch problem, with its free unknowns."""
    K, f, book = problem.assemble()
    faces = list(book["dirichlet"])
    fixed = np.unique(np.concatenate([problem.spaces[p].face_dofs(fc) for p, fc in faces]))
    free = np.setdiff1d(np.arange(problem.ndof), fixed)
    A, rhs = eliminate(K, f, free, fixed, np.zeros(len(fixed)))
    return A, rhs, free, faces


def test_the_kronecker_inverse_is_exact_on_random_factors():
    rng = np.random.default_rng(0)

    def spd(n):
        B = rng.standard_normal((n, n))
        return B @ B.T + n * np.eye(n)

    ks = KroneckerSum([spd(4), spd(5), spd(6)], [spd(4), spd(5), spd(6)], [1.0, 0.3, 2.0])
    x = rng.standard_normal(ks.n)
    assert np.abs(FastDiagonalization(ks)(ks.matvec(x)) - x).max() < 1e-12 * np.abs(x).max()
    assert np.allclose(ks.diagonal(), [ks.matvec(e)[i] for i, e in enumerate(np.eye(ks.n)[:20])][:20] +
                       list(ks.diagonal()[20:]))


def test_block_fast_diagonalization_inverts_a_block_diagonal_of_kronecker_sums():
    rng = np.random.default_rng(5)

    def spd(n):
        B = rng.standard_normal((n, n))
        return B @ B.T + n * np.eye(n)

    blocks = [KroneckerSum([spd(3), spd(4), spd(2)], [spd(3), spd(4), spd(2)], rng.uniform(0.5, 2.0, 3))
              for _ in range(3)]
    dense = [np.stack([ks.matvec(e) for e in np.eye(ks.n)], 1) for ks in blocks]
    A = sp.block_diag(dense, format="csr")
    x = rng.standard_normal(A.shape[0])
    M = BlockFastDiagonalization(blocks, A)
    assert np.abs(M(A @ x) - x).max() < 1e-10 * np.abs(x).max()
    assert solvers.solve(A, A @ x, method="fd-cg", kronecker=blocks, tol=1e-12)[1].iterations == 1
    with pytest.raises(SolverError, match="blocks hold 72 unknowns, the matrix 50"):
        BlockFastDiagonalization(blocks, sp.identity(50, format="csr"))


@pytest.mark.parametrize("p", [2, 3])
def test_fast_diagonalization_is_exact_on_a_box_with_constant_conductivity(p):
    box = pr.box((2.0, 1.0, 0.5), (0.3, -1.0, 2.0), degrees=(p,) * 3, elements=(5, 4, 6))
    problem = HeatProblem(box, conductivity=3.0, source=1.0).dirichlet("boundary", 0.0)
    A, rhs, free, _ = _reduced(problem)
    ks = kronecker_sum(problem, free)
    assert ks is not None and ks.n == A.shape[0]
    x = np.random.default_rng(1).standard_normal(A.shape[0])
    M = FastDiagonalization(ks, A)
    assert np.abs(M(A @ x) - x).max() < 1e-10 * np.abs(x).max()  # M = A^-1 exactly
    s = HeatProblem(box, conductivity=3.0, source=1.0).dirichlet("boundary", 0.0).solve(solver="fd-cg", tol=1e-10)
    assert s.info["solver"]["iterations"] == 1


def test_fast_diagonalization_iterations_do_not_grow_with_degree_or_size_on_a_curved_patch():
    its = {}
    for p, n in ((2, 8), (2, 16), (4, 8), (4, 16)):
        D = pr.refined(pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(p,) * 3), 0.6, axis_point=(0.5, 0.5)), (n,) * 3)
        s = HeatProblem(D, source=1.0).dirichlet("boundary", 0.0).solve(solver="fd-cg", tol=1e-8)
        its[p, n] = s.info["solver"]["iterations"]
    assert max(its.values()) <= 1.5 * min(its.values()) and max(its.values()) < 20


@pytest.mark.slow
def test_multigrid_contraction_does_not_depend_on_the_refinement_level():
    rates = []
    for n in (10, 20, 40):
        problem = HeatProblem(pr.box(degrees=(2, 2, 2), elements=(n,) * 3), source=1.0).dirichlet("boundary", 0.0)
        A, b, free, faces = _reduced(problem)
        P = prolongations(problem, faces, free, None)
        mg = Multigrid(A, P)
        x, r0 = np.zeros_like(b), []
        for _ in range(8):  # the V-cycle as a stationary iteration: x <- x + M (b - A x)
            r = b - A @ x
            r0.append(np.linalg.norm(r))
            x += mg(r)
        rates.append((r0[-1] / r0[2]) ** (1 / 5))  # mean contraction once the first cycles are past
    assert max(rates) < 0.5  # a real multigrid: every cycle gains more than a factor two
    assert max(rates) <= 1.5 * min(rates)  # and does not slow down when the mesh is refined


def test_knot_coarsening_gives_nested_spaces():
    U = np.array([0, 0, 0, 0.1, 0.25, 0.5, 0.5, 0.5, 0.7, 0.9, 1, 1, 1.0])
    C = coarsen_knots(U, 2)
    assert C is not None and len(C) < len(U)
    vals, m = np.unique(C, return_counts=True)
    assert 0.5 in vals and m[list(vals).index(0.5)] == 3  # the discontinuity is kept
    assert all(np.sum(U == v) >= c for v, c in zip(vals, m))  # every coarse knot is a fine knot


@pytest.mark.parametrize("build,kw,hot,cold", [
    (lambda: tiling.hierarchical(pr.box((0.06, 0.06, 0.03)), L.heat_sink_t2(), (2, 2), levels=2), dict(refine=1),
     "branch-in", "exterior"),
    (lambda: tiling.regular(pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5)),
                            L.cross(), (2, 2, 2)), dict(degree_elevation=1, refine=2), "umin", "umax")])
def test_multigrid_on_micro_structures_gives_the_amg_answer(build, kw, hot, cold):
    ms = build()
    out = {}
    for solver in ("amg-cg", "gmg-cg"):
        problem = HeatProblem(ms, conductivity=200.0, **kw).dirichlet(hot, 80.0).robin(cold, 50.0, 20.0)
        out[solver] = problem.solve(solver=solver, tol=1e-10)
    a, g = out["amg-cg"], out["gmg-cg"]
    assert g.info["solver"]["method"] == "gmg-cg" and g.info["solver"]["mg_levels"] >= 2
    assert np.abs(a.u - g.u).max() < 1e-6 * np.abs(a.u).max()
    assert g.info["solver"]["iterations"] <= a.info["solver"]["iterations"]


def test_auto_uses_fast_diagonalization_for_one_large_patch():
    box = pr.box(degrees=(2, 2, 2), elements=(14, 14, 14))
    s = HeatProblem(box, source=1.0).dirichlet("umin", 0.0).neumann("umax", 1.0).solve()
    assert s.info["solver"]["method"] == "fd-cg"
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    s = HeatProblem(ms, degree_elevation=1, refine=1).dirichlet("umin", 0.0).neumann("umax", 1.0).solve()
    assert s.info["solver"]["method"] != "fd-cg"


def test_petsc_without_petsc4py_says_how_to_install_it(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "petsc4py", None)  # as if it were not installed
    with pytest.raises(SolverError, match=r"petsc4py: pip install -e \"\.\[mpi\]\""):
        solvers.solve(sp.identity(8, format="csr"), np.ones(8), method="petsc")
    with pytest.raises(SolverError, match="petsc4py"):
        HeatProblem(pr.box(degrees=(1, 1, 1), elements=(2, 2, 2))).dirichlet("umin", 1.0).solve(solver="petsc")


def test_preconditioner_bad_input():
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    with pytest.raises(ProblemError, match="fd-cg.*one unconstrained trivariate patch"):
        HeatProblem(ms).dirichlet("umin", 0.0).solve(solver="fd-cg")
    with pytest.raises(ProblemError, match="gmg-cg.*refine >= 1"):
        HeatProblem(ms).dirichlet("umin", 0.0).solve(solver="gmg-cg")
    robin_only = HeatProblem(pr.box(degrees=(2, 2, 2), elements=(4, 4, 4))).robin("boundary", 5.0, 20.0)
    with pytest.raises(ProblemError, match="fd-cg"):
        robin_only.solve(solver="fd-cg")  # no Dirichlet side: the Kronecker sum would be singular
    A = sp.identity(8, format="csr")
    with pytest.raises(SolverError, match="kronecker"):
        solvers.solve(A, np.ones(8), method="fd-cg")
    with pytest.raises(SolverError, match="prolongations"):
        solvers.solve(A, np.ones(8), method="gmg-cg")
    with pytest.raises(SolverError, match="prolongation 0 has 3 rows"):
        solvers.solve(A, np.ones(8), method="gmg-cg", prolongations=[sp.identity(3, format="csr")])
    with pytest.raises(SolverError, match="positive"):
        KroneckerSum([np.eye(2)], [np.eye(2)], [-1.0])


@pytest.mark.parametrize("method", ["direct", "amg-cg", "cg", "auto"])
def test_a_prepared_solver_solves_many_right_hand_sides_as_single_solves_do(method):
    problem = HeatProblem(pr.twisted(pr.box(degrees=(2, 2, 2)), 0.4, axis_point=(0.5, 0.5)), refine=2)
    problem.dirichlet("umin", 0.0)
    A, _, free, _ = _reduced(problem)
    A = (A + 50.0 * problem.mass(1.0)[free][:, free]).tocsr()  # a step matrix M / dt + K
    solve = solvers.prepare(A, method, tol=1e-11)
    rng = np.random.default_rng(5)
    x_prev = None
    for _ in range(3):
        b = rng.standard_normal(A.shape[0])
        x, info = solve(b, x_prev)
        reference, _ = solvers.solve(A, b, method="direct")
        assert np.abs(x - reference).max() <= 1e-8 * np.abs(reference).max()
        assert info.setup_s == 0.0 and info.method == solve.name
        x_prev = x
    # started from the solution, an iterative solver stops at once; a factorisation is applied as before
    _, again = solve(b, x)
    assert again.iterations <= 1
    with pytest.raises(SolverError, match="right-hand side must have shape"):
        solve(np.ones(3))
    with pytest.raises(SolverError, match="non-finite"):
        solve(np.full(A.shape[0], np.nan))


def test_a_prepared_solver_refuses_what_it_cannot_prepare():
    A = sp.diags([1.0, 2.0, 3.0]).tocsr()
    with pytest.raises(SolverError, match="prepared solver is one of"):
        solvers.prepare(A, "fd-cg")
    with pytest.raises(SolverError, match="tol"):
        solvers.prepare(A, "cg", tol=2.0)
    with pytest.raises(SolverError, match="square"):
        solvers.prepare(np.eye(3))
    with pytest.raises(SolverError, match="positive diagonal"):
        solvers.prepare(sp.diags([1.0, -2.0, 3.0]).tocsr(), "cg")


def test_auto_factorises_coupled_patches_further_than_one_patch():
    import iga.discretisation.multilevel as ml

    model = tiling.regular(pr.box(degrees=(2, 2, 2)), L.cross(), (3, 3, 2))
    s = HeatProblem(model, degree_elevation=1, refine=1).dirichlet("wmin", 0.0).dirichlet("wmax", 1.0).solve()
    assert solvers.AUTO_DIRECT_LIMIT < s.info.free_dofs <= ml.MULTIPATCH_DIRECT_LIMIT
    assert s.info.solver.method.startswith("direct")  # coupled patches: factorised
    one = HeatProblem(pr.box(degrees=(2, 2, 2)), refine=4).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    assert one.info.free_dofs > solvers.AUTO_DIRECT_LIMIT and one.info.solver.method == "fd-cg"  # one patch
    with pytest.raises(SolverError, match="direct_limit"):
        solvers.solve(sp.identity(3, format="csr"), np.ones(3), direct_limit=-1)


def test_the_node_major_copy_equals_the_coo_round_trip():
    """solvers.amg.permuted_padded: A[i, j] at (slots[i], slots[j]), unit rows where no slot lands, sorted
    indices, against building the same matrix through COO."""
    from solvers.amg import permuted_padded
    from solvers.indexing import complement

    rng = np.random.default_rng(0)
    for n, nred in ((300, 120), (50, 100)):
        A = sp.random(n, n, density=0.05, random_state=1, format="csr")
        A = (A + A.T + sp.identity(n)).tocsr()
        slots = rng.permutation(3 * nred)[:n]
        size = 3 * (int(slots.max()) // 3 + 1)
        free = complement(size, slots)
        C = sp.coo_matrix(A)
        ref = sp.csr_matrix((np.concatenate([C.data, np.ones(len(free))]),
                             (np.concatenate([slots[C.row], free]), np.concatenate([slots[C.col], free]))),
                            shape=(size, size))
        got = permuted_padded(A, slots, size)
        assert got.has_sorted_indices
        assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
        assert np.array_equal(got.data, ref.data)
