"""The compiled (numba) assembly and elimination agree with the NumPy path; the AMG preconditioner is robust."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import solvers
import tiling
from tiling import library as tiles
from geometry import MultiPatch, primitives as pr
from geometry.compiled import _fast
from iga import HeatProblem, ProblemError
from iga.assembly import compiled as fast_assembly
from iga.discretisation import system as system_module
from iga.assembly.tensor import banded_form, banded_to_csr_data, load_form, pattern, stiffness_data
from iga.assembly.terms import form_terms
from geometry.patches.chain import grid_values_derivs_slabs
from iga.manufactured import quarter_annulus
from iga.heat.coefficients import TENSOR_PAIRS as _PAIRS
from iga.discretisation.system import eliminate as _eliminate
from iga.discretisation.space import make_space
from solvers.amg import AMGPreconditioner, spectral_radius

from helpers import random_knots, random_spline

pytestmark = [pytest.mark.skipif(not fast_assembly.AVAILABLE, reason="the compiled paths need numba (test extra)"),
              pytest.mark.all_threads]  # kernels on every thread: a race would show


# fixed degrees (each (p3, g3) of the last direction compiles its own kernel; the suite uses p3 = 1 and 2):
# stage 1 sweeps min(4, p1 + 1 - m1) destinations at once, so p1 = 1..4 covers two, three, four, and four
# then one; the case with seed 4 has a discontinuity (multiplicity p + 1), where the band rows of
# neighbouring elements do not overlap
STIFFNESS_DEGREES = [(2, 2, 2), (3, 1, 2), (1, 3, 1), (4, 2, 2), (2, 2, 2), (4, 3, 1), (1, 2, 2)]


@pytest.mark.parametrize("count, symmetric", [(1, False), (2, False), (5, False), (11, False), (1, True),
                                              (4, True), (12, True)])
def test_the_one_compiled_form_kernel_takes_any_number_of_terms(count, symmetric):
    """Random forms of 1 to 12 terms (random fields, random derivative orders per direction; symmetric ones
    closed under swapping the test and trial orders) through the compiled form kernel equal the NumPy
    reference form (banded_form), slab by slab too."""
    rng = np.random.default_rng(100 * count + symmetric)
    degrees = (2, 3, 2) if count % 2 else (1, 2, 2)
    space = make_space([random_knots(rng, p, 3, max_mult=p) for p in degrees], degrees)
    P, fields = 2, 1 + count // 2
    C = rng.standard_normal((fields, P) + space.qshape)
    terms = []
    while len(terms) < count:
        orders = tuple(tuple(int(v) for v in rng.integers(0, 2, 2)) for _ in range(3))
        c = int(rng.integers(0, fields))
        terms.append((c, orders))
        if symmetric and len(terms) < count:
            terms.append((c, tuple((b, a) for a, b in orders)))
    if symmetric and len(terms) % 2:  # an odd count: the last term its own transpose
        terms[-1] = (terms[-1][0], ((1, 1), (0, 0), (1, 1)))
    form = form_terms(terms, fields=fields, symmetric=symmetric)
    pat = pattern(space)
    ref = banded_to_csr_data(space, banded_form(space, [(C[c], orders) for c, orders in terms]), pat)
    got_pat, got = fast_assembly.form_csr(space, C, form)
    assert np.array_equal(got_pat.indices, pat.indices)
    scale = np.abs(ref).max()
    assert scale > 0 and np.abs(got - ref).max() <= 1e-12 * scale
    acc = fast_assembly.FormAccumulator(space, P, form)
    g, planes = space.dirs[0].g, space.dirs[0].nq
    for a in range(0, planes, 2 * g):
        b = min(a + 2 * g, planes)
        acc.add(slice(a, b), C.reshape(fields, P, planes, -1)[:, :, a:b])
    assert np.abs(acc.result()[1] - ref).max() <= 1e-12 * scale


def test_a_form_declared_symmetric_must_be_so():
    with pytest.raises(ProblemError, match="no transposed twin"):
        form_terms([(0, ((1, 0), (0, 0), (0, 0)))], symmetric=True)
    with pytest.raises(ProblemError, match="each 0 or 1"):
        form_terms([(0, ((2, 0), (0, 0), (0, 0)))])
    with pytest.raises(ProblemError, match="reads field 3"):
        form_terms([(3, ((0, 0),) * 3)], fields=2)
    assert form_terms([(0, ((1, 0), (0, 0), (0, 0))), (0, ((0, 1), (0, 0), (0, 0)))], symmetric=True).count == 1


@pytest.mark.parametrize("seed", range(len(STIFFNESS_DEGREES)))
def test_compiled_stiffness_equals_numpy_path(seed):
    rng = np.random.default_rng(seed)
    degrees = STIFFNESS_DEGREES[seed]
    # random interior knots, some repeated up to C^0
    knots = [random_knots(rng, p, 4, max_mult=p) for p in degrees]
    if seed == 4:
        knots = [np.r_[[0.0] * (p + 1), [0.3] * (p + 1), [0.6] * p, [1.0] * (p + 1)] for p in degrees]
    space = make_space(knots, degrees)
    P = 2
    C = rng.standard_normal((6, P) + space.qshape)
    ref_pat = pattern(space)
    ref = stiffness_data(space, {rs: C[j] for j, rs in enumerate(_PAIRS)}, ref_pat)
    pat, data = fast_assembly.form_csr(space, C)
    assert np.array_equal(pat.indptr, ref_pat.indptr) and np.array_equal(pat.indices, ref_pat.indices)
    assert np.abs(data - ref).max() <= 1e-12 * np.abs(ref).max()
    # slab by slab (whole elements of direction 1) gives the same matrix, and the same load vectors
    acc = fast_assembly.FormAccumulator(space, P)
    g, planes = space.dirs[0].g, space.dirs[0].nq
    cuts = sorted({0, planes, *(g * rng.integers(0, planes // g + 1, 2))})
    Cg = C.reshape(6, P, planes, -1)
    L = rng.standard_normal((P,) + space.qshape)
    Lg = L.reshape(P, planes, -1)
    for a, b in zip(cuts[:-1], cuts[1:]):
        if b == planes:
            with pytest.raises(ProblemError, match="incomplete"):
                acc.result()
        acc.add(slice(a, b), Cg[:, :, a:b], Lg[:, a:b])
    assert np.abs(acc.result()[1] - data).max() <= 1e-12 * np.abs(ref).max()
    ref_load = load_form(space, L)
    assert acc.load.shape == ref_load.shape
    assert np.abs(acc.load - ref_load).max() <= 1e-12 * np.abs(ref_load).max()
    with pytest.raises(ProblemError, match="whole elements"):
        acc.add(slice(1, 1 + g), Cg[:, :, 1 : 1 + g])
    with pytest.raises(ProblemError, match="in order"):
        acc.add(slice(0, g), Cg[:, :, 0:g])


def test_compiled_grid_geometry_equals_direct_evaluation():
    rng = np.random.default_rng(3)
    S = random_spline(rng, 3, degrees=(2, 3, 1), rational=True, channels=("k",))
    axes = [np.sort(rng.uniform(0, 1, n)) for n in (12, 7, 9)]
    G = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    rest = 7 * 9
    for compiled in (False, True):
        for rows, x, dx in grid_values_derivs_slabs(S, axes, 2 * rest, 2, compiled=compiled):
            assert (rows.stop - rows.start) % 2 == 0 or rows.stop == 12
            pts = G[rows.start * rest : rows.stop * rest]
            assert np.abs(x - S.evaluate(pts)).max() < 1e-12
            assert np.abs(np.stack(dx, -1) - S.jacobian(pts)).max() < 1e-10


@pytest.mark.parametrize("axis", range(3))
def test_compiled_face_grid_equals_direct_evaluation(axis, monkeypatch):
    # large face grids (one point in one direction) are evaluated by the compiled kernel too
    from geometry.patches import chain as geometry_eval

    rng = np.random.default_rng(axis)
    S = random_spline(rng, 3, degrees=(3, 1, 2), rational=True, channels=("k",))
    axes = [np.sort(rng.uniform(0, 1, n)) for n in (11, 6, 8)]
    axes[axis] = np.array([float(S.knots[axis][-1])])  # the max face
    G = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    monkeypatch.setattr(geometry_eval, "COMPILED_GRID_POINTS", 1)
    x, dx = geometry_eval.grid_values_derivs(S, axes)
    assert np.abs(x - S.evaluate(G)).max() < 1e-12
    assert np.abs(np.stack(dx, -1) - S.jacobian(G)).max() < 1e-10
    monkeypatch.setattr(geometry_eval, "COMPILED_GRID_POINTS", 10**9)  # the NumPy path gives the same
    calls = []
    grid_derivs = _fast.grid_derivs
    monkeypatch.setattr(_fast, "grid_derivs", lambda *a: calls.append(1) or grid_derivs(*a))
    x2, dx2 = geometry_eval.grid_values_derivs(S, axes)
    assert calls == []
    assert np.abs(x2 - x).max() < 1e-12 and np.abs(np.stack(dx2, -1) - np.stack(dx, -1)).max() < 1e-10
    # smaller grids take the compiled kernel only when the caller says its problem is compiled anyway: the
    # choice depends on the input, never on what ran before (small analyses never import numba)
    monkeypatch.setattr(geometry_eval, "COMPILED_PROBLEM_GRID_POINTS", len(G))
    x3, _ = geometry_eval.grid_values_derivs(S, axes, compiled=True)
    assert calls == [1] and np.abs(x3 - x).max() < 1e-12


def _assembled(prob_factory, monkeypatch, compiled):
    if compiled:
        monkeypatch.setattr(fast_assembly, "MIN_POINTS", 0)
    else:
        monkeypatch.setattr(fast_assembly, "AVAILABLE", False)
    K, f, _ = prob_factory().assemble()
    monkeypatch.undo()
    return K, f


@pytest.mark.parametrize("case", ["annulus", "plain", "hierarchy"])
def test_compiled_heat_assembly_equals_numpy_assembly(case, monkeypatch):
    if case == "annulus":  # exact NURBS, variable conductivity and source
        def factory():
            m = quarter_annulus()
            return (HeatProblem(m.geometry, conductivity=m.conductivity, source=m.source,
                                refine=1).dirichlet("umin", 0.0))
    elif case == "plain":
        # constant k and f on patches without placement or map: the fused geometry-metric kernel takes the
        # B-spline patch with curved, non-uniform geometry and the NURBS patch with a channel (not needed, dropped
        # from the coefficients), twice (two patches, one spline); that one is its own geometry, so it is analysed
        # in the NURBS basis, whose first- and zero-order terms (RATIONAL_DIFFUSION) the compiled kernel contracts
        # against the NumPy forms of iga.discretisation.rational
        from geometry import BSpline

        rng = np.random.default_rng(7)
        box = pr.box(degrees=(2, 3, 2), elements=(3, 2, 4))
        nurbs = BSpline(box.degrees, box.knots, np.concatenate(
            [box.coefficients + 0.03 * rng.standard_normal(box.coefficients.shape),
             rng.uniform(1, 2, box.coefficients.shape[:-1] + (1,))], axis=-1),
            rng.uniform(0.7, 1.4, box.coefficients.shape[:-1]), channels=("k",))
        cube = pr.box(degrees=(3, 2, 2), elements=(4, 3, 5))
        bent = BSpline(cube.degrees, cube.knots, cube.coefficients + 0.02 * rng.standard_normal(cube.coefficients.shape))

        def factory():
            # overlapping patches, analysed independently (no automatic coupling)
            model = MultiPatch.from_splines([nurbs, nurbs, bent], couple=False)
            return HeatProblem(model, conductivity=2.5, source=-1.5).dirichlet("umin", 0.0)
    else:  # micro-structure: placements and a rational deformation map, several patches per tile spline
        import tiling
        from geometry import BSpline
        from tiling import library

        box = pr.box(degrees=(2, 2, 2), elements=(2, 1, 1), size=(2, 1, 1))
        w = np.random.default_rng(1).uniform(0.8, 1.25, box.coefficients.shape[:-1])
        D = BSpline(box.degrees, box.knots, box.coefficients, w)
        model = tiling.regular(D, library.cross(0.3), (2, 2, 1))

        def factory():
            return HeatProblem(model, conductivity=2.0, source=1.0).dirichlet("umin", 0.0)
    fused = []  # which groups the fused geometry-metric kernel assembled
    metric_slabs = fast_assembly.metric_slabs
    K0, f0 = _assembled(factory, monkeypatch, compiled=False)
    monkeypatch.setattr(fast_assembly, "metric_slabs", lambda spline, *a: fused.append(spline) or metric_slabs(spline, *a))
    K1, f1 = _assembled(factory, monkeypatch, compiled=True)
    assert len(fused) == (2 if case == "plain" else 0)
    assert abs(K1 - K0).max() <= 1e-12 * abs(K0).max()
    assert np.abs(f1 - f0).max() <= 1e-12 * np.abs(f0).max()


@pytest.mark.parametrize("compiled", [False, True])
def test_mirrored_patch_has_the_same_stiffness(compiled, monkeypatch):
    # x -> -x makes det J < 0 everywhere (a left-handed patch): valid, and the Laplacian is unchanged
    from geometry import BSpline

    cube = pr.box(degrees=(2, 3, 2), elements=(3, 2, 3))
    cp = cube.coefficients.copy()
    cp[..., 0] *= -1
    mirrored = BSpline(cube.degrees, cube.knots, cp)
    K0, f0 = _assembled(lambda: HeatProblem(cube, source=2.0), monkeypatch, compiled)
    K1, f1 = _assembled(lambda: HeatProblem(mirrored, source=2.0), monkeypatch, compiled)
    assert abs(K1 - K0).max() <= 1e-12 * abs(K0).max()
    assert np.abs(f1 - f0).max() <= 1e-12 * np.abs(f0).max() and f0.sum() == pytest.approx(2.0)


def test_fold_between_slabs_is_reported(monkeypatch):
    # x(u) = 2u(1 - u): dx/du changes sign at u = 1/2, which is an element boundary, so every
    # slab alone has one sign; the fold must be caught across slabs
    cube = pr.box(degrees=(2, 1, 1), elements=(1, 1, 1))
    cp = cube.coefficients.copy()
    cp[1, :, :, 0] = 1.0
    cp[2, :, :, 0] = 0.0
    from geometry import BSpline

    folded = BSpline(cube.degrees, cube.knots, cp)
    for compiled in (False, True):
        if compiled:
            monkeypatch.setattr(fast_assembly, "MIN_POINTS", 0)
        with pytest.raises(ProblemError, match="changes sign"):
            HeatProblem(folded, refine=5).dirichlet("vmin", 0.0).assemble()
        monkeypatch.undo()


def test_in_place_elimination_equals_copying(monkeypatch):
    prob = HeatProblem(pr.box(degrees=(2, 2, 2), elements=(5, 4, 3)), source=1.0).dirichlet("umin", 1.0)
    K, f, _ = prob.assemble()
    n = K.shape[0]
    dofs = np.flatnonzero(np.arange(n) % 7 == 0)
    free = np.setdiff1d(np.arange(n), dofs)
    g = np.linspace(0, 1, len(dofs))
    A0, r0 = _eliminate(K.copy(), f, free, dofs, g)
    monkeypatch.setattr(system_module, "_IN_PLACE_NNZ", 0)
    Kw = sp.csr_matrix((K.data.copy(), K.indices.copy(), K.indptr.copy()), shape=K.shape)
    A1, r1 = _eliminate(Kw, f, free, dofs, g, in_place=True)
    assert np.shares_memory(A1.data, Kw.data)  # computed in K's own memory
    assert np.array_equal(A1.indptr, A0.indptr) and np.array_equal(A1.indices, A0.indices)
    assert np.array_equal(A1.data, A0.data) and np.array_equal(r1, r0)
    # a matrix on a shared, read-only pattern never writes into it: those arrays are copied first
    pat = pattern(prob.spaces[0])
    Kr = sp.csr_matrix((K.data.copy(), pat.indices, pat.indptr), shape=K.shape)
    before = pat.indices.copy()
    A2, _ = _eliminate(Kr, f, free, dofs, g, in_place=True)
    assert np.array_equal(pat.indices, before) and abs(A2 - A0).max() == 0
    assert np.shares_memory(A2.data, Kr.data) and not np.shares_memory(A2.indices, pat.indices)


def test_spectral_radius_is_a_close_lower_bound():
    A = HeatProblem(pr.box(degrees=(2, 2, 2), elements=(6, 6, 6))).dirichlet("boundary", 0.0).assemble()[0]
    exact = spla.eigsh(A, k=1, which="LA", return_eigenvectors=False)[0]
    est = spectral_radius(A)
    assert exact * 0.97 <= est <= exact * (1 + 1e-10)


def test_amg_cg_is_robust_to_conductivity_jumps():
    # conductivity jumping by 1000 in a checkerboard-like pattern: the Jacobi-scaled hierarchy keeps
    # the iteration count low (unscaled Chebyshev smoothing needed hundreds)
    def k(x):
        return 1.0 + 999.0 * (np.sin(7 * x[:, 0]) * np.sin(5 * x[:, 1]) > 0.3)

    prob = HeatProblem(pr.box(degrees=(2, 2, 2), elements=(14, 14, 14)), conductivity=k, source=1.0)
    prob.dirichlet("boundary", 0.0)
    amg = prob.solve(solver="amg-cg", tol=1e-10)
    direct = HeatProblem(prob.model, conductivity=k, source=1.0).dirichlet("boundary", 0.0).solve(solver="direct")
    assert np.abs(amg.u - direct.u).max() <= 1e-7 * np.abs(direct.u).max()
    # robust: the jump of 1000 costs a small factor of the iterations without it (22 against 11 measured),
    # where the unscaled hierarchy needed hundreds
    plain = HeatProblem(prob.model, conductivity=1.0, source=1.0).dirichlet("boundary", 0.0).solve(solver="amg-cg",
                                                                                                    tol=1e-10)
    assert amg.info["solver"]["iterations"] <= 3 * plain.info["solver"]["iterations"]


def test_amg_does_not_modify_the_matrix_unless_allowed():
    A = HeatProblem(pr.box(degrees=(2, 2, 2), elements=(8, 8, 8))).dirichlet("boundary", 0.0).assemble()[0]
    A = A[:-1][:, :-1].tocsr() + sp.eye(A.shape[0] - 1)
    b = np.ones(A.shape[0])
    keep = A.data.copy()
    x, info = solvers.solve(A, b, method="amg-cg", tol=1e-10)
    assert np.array_equal(A.data, keep) and info.residual < 1e-9
    x2, _ = solvers.solve(A, b, method="amg-cg", tol=1e-10, overwrite_a=True)
    assert not np.array_equal(A.data, keep)  # scaled in place, as allowed
    assert np.abs(x2 - x).max() < 1e-8 * np.abs(x).max()


def test_amg_rejects_a_non_positive_diagonal():
    A = sp.diags([1.0, -2.0, 3.0]).tocsr()
    with pytest.raises(solvers.SolverError, match="diagonal entry 1"):
        AMGPreconditioner(A)


def test_compiled_box_verdicts_equal_numpy_path(monkeypatch):
    # the certificate's kernel (tiling.implicit._certify_kernels): bounds and monotonicity bits of split sub-boxes
    from tiling.implicit import boxes as ib
    from tiling.implicit.structure import _global_knots
    knots = [_global_knots(0.0, c, c, 3, 6) for c in (2, 1, 1)]
    G = np.random.default_rng(6).uniform(-0.3, 0.3, tuple(len(U) - 4 for U in knots))
    grid = ib.box_grid(knots, 3, (2, 1, 1), 1)
    boxes = np.argwhere(np.ones(grid.shape, bool))
    compiled = ib.judge(G, grid, boxes, 2)
    monkeypatch.setattr(_fast, "AVAILABLE", False)
    plain = ib.judge(G, grid, boxes, 2)
    np.testing.assert_allclose(compiled[0], plain[0], atol=1e-13)
    np.testing.assert_allclose(compiled[1], plain[1], atol=1e-13)
    np.testing.assert_array_equal(compiled[2], plain[2])
    assert np.count_nonzero(compiled[2]) > 10  # the bits were compared where they are set


def test_one_component_layout_is_the_block_diagonal_of_its_patches_strided_or_indexed():
    from iga.assembly.tensor import CSRPattern
    from iga.assembly.vector_csr import VectorCSR

    rng = np.random.default_rng(5)
    sizes = (40, 25, 40, 40, 25, 40)
    pats = {}
    for n in set(sizes):
        A = sp.random(n, n, density=0.2, random_state=n, format="csr") + sp.eye(n, format="csr")
        A.sort_indices()
        pats[n] = CSRPattern(A.indptr.astype(np.int64), A.indices, None, None, n)
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    nnz = np.array([len(pats[n].indices) for n in sizes])
    nnz[4] = 0  # another rank's patch: empty rows
    out = VectorCSR(offsets, nnz, components=1)
    data = {m: rng.standard_normal(len(pats[sizes[m]].indices)) for m in (0, 1, 2, 3, 5)}
    out.put([1], pats[25], {(0, 0): data[1][None]})
    out.put([0, 2, 3], pats[40], {(0, 0): np.stack([data[m] for m in (0, 2, 3)])})  # strides differ: indexed
    out.put([5], pats[40], {(0, 0): data[5][None]})  # one member: strided
    with pytest.raises(ProblemError, match=r"patches \[4\] were not assembled"):
        out.matrix()
    with pytest.raises(ProblemError, match="only patches given no non-zeros"):
        out.skip([3])
    out.skip([4])
    K = out.matrix()
    ref = sp.block_diag([sp.csr_matrix((data[m], pats[n].indices, pats[n].indptr)) if m in data
                         else sp.csr_matrix((n, n)) for m, n in enumerate(sizes)], format="csr")
    ref.sort_indices()
    assert K.has_sorted_indices
    assert np.array_equal(K.indptr, ref.indptr) and np.array_equal(K.indices, ref.indices)
    assert np.array_equal(K.data, ref.data)
    # equal strides (the same tile patch in every cell): written through strided views, the same arrays
    again = VectorCSR(offsets[:4], [len(pats[n].indices) for n in sizes[:3]], components=1)
    again.put([0, 2], pats[40], {(0, 0): np.stack([data[0], data[2]])})
    again.put([1], pats[25], {(0, 0): data[1][None]})
    assert np.array_equal(again.matrix().toarray(), ref[:105, :105].toarray())
    backwards = VectorCSR(offsets[:4], [len(pats[n].indices) for n in sizes[:3]], components=1)
    backwards.put([2, 0], pats[40], {(0, 0): np.stack([data[2], data[0]])})  # decreasing: not strided
    backwards.put([1], pats[25], {(0, 0): data[1][None]})
    assert np.array_equal(backwards.matrix().toarray(), ref[:105, :105].toarray())


@pytest.mark.parametrize("compiled", [False, True])
def test_the_stiffness_of_some_patches_is_their_rows_of_the_whole(compiled, monkeypatch):
    # one MPI rank's share: its patches' rows exactly as in the whole operator, every other row empty
    import tiling
    from tiling import library

    D = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
    prob = HeatProblem(tiling.regular(D, library.cross(), (3, 2, 2)), conductivity=lambda x: 1.0 + x[:, 0],
                       source=1.0, degree_elevation=1)
    if compiled:
        monkeypatch.setattr(fast_assembly, "MIN_POINTS", 0)
    K, f, _ = prob.volume.assemble(prob.conductivity, prob.source)
    n = len(prob.spaces)
    mine = set(np.random.default_rng(2).choice(n, n // 2, replace=False).tolist())
    rest = set(range(n)) - mine
    Km, fm, _ = prob.volume.assemble(prob.conductivity, prob.source, mine)
    Kr, fr, _ = prob.volume.assemble(prob.conductivity, prob.source, rest)
    rows = np.concatenate([np.arange(prob.offsets[i], prob.offsets[i + 1]) for i in sorted(mine)])
    other = np.setdiff1d(np.arange(prob.ndof), rows)
    assert abs(Km[rows] - K[rows]).max() == 0 and Km[other].nnz == 0 and np.all(fm[other] == 0)
    assert abs(Km + Kr - K).max() == 0 and np.array_equal(fm + fr, f)
    blocks = sp.block_diag([K[prob.offsets[i]:prob.offsets[i + 1], prob.offsets[i]:prob.offsets[i + 1]]
                            for i in range(n)], format="csr")
    assert abs(blocks - K).max() == 0 and K.has_sorted_indices  # block-diagonal: patches are not yet glued


def test_a_boundary_mass_inside_the_pattern_is_added_in_place_and_one_outside_is_not_lost():
    from iga.assembly.tensor import add_within

    rng = np.random.default_rng(11)
    K = (sp.random(60, 60, density=0.15, random_state=1, format="csr") + sp.eye(60, format="csr")).tocsr()
    K.sort_indices()
    ref = K.copy()
    r, c = K.nonzero()
    pick = rng.choice(len(r), 40, replace=False)
    M = sp.coo_matrix((rng.standard_normal(80), (np.r_[r[pick], r[pick]], np.r_[c[pick], c[pick]])), shape=K.shape)
    out = add_within(K, M)  # duplicates summed, every entry inside K's pattern: K's own arrays
    assert out is K and abs(out - (ref + M)).max() < 1e-15 and out.nnz == ref.nnz
    K2 = ref.copy()
    outside = sp.coo_matrix(([1.5], ([3], [int(np.setdiff1d(np.arange(60), K2[3].indices)[0])])), shape=K2.shape)
    out2 = add_within(K2, M + outside)
    assert abs(out2 - (ref + M + outside)).max() < 1e-15 and out2.nnz == ref.nnz + 1


def test_the_mass_form_and_the_k_of_t_tangent_take_the_compiled_kernel_on_large_groups(monkeypatch):
    """The transient mass form and the first-order tangent of k(T) are forms of the vocabulary: with the
    compiled threshold lowered they go through the one form kernel and give the NumPy path's matrices."""
    from iga.assembly.terms import SYMMETRIC_PAIRS
    from iga.heat.nonlinear import tangent_forms

    assert SYMMETRIC_PAIRS == _PAIRS  # the kernel's diffusion fields are the conductivity's pair order
    twisted = pr.twisted(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(1.0, 0.5))
    ms = tiling.regular(twisted, tiles.cross(), (2, 2, 1))
    prob = HeatProblem(ms, conductivity=lambda x, T: 1.0 + 0.01 * T + 0.1 * x[:, 0], degree_elevation=1)
    u = np.random.default_rng(5).uniform(20.0, 80.0, prob.ndof)
    found = {}
    for threshold in (10**12, 1):
        monkeypatch.setattr(fast_assembly, "MIN_POINTS", threshold)
        found[threshold] = (prob.mass(lambda x: 2.0e6 + x[:, 1]), *tangent_forms(prob, u))
    groups = prob.volume.groups.values()
    assert any(len(g) > 1 for g in groups) and all(fast_assembly.applies(prob.spaces[g[0]], len(g), 3) for g in groups)
    for ref, got in zip(found[10**12], found[1]):
        assert np.array_equal(got.indices, ref.indices)
        assert abs(got - ref).max() <= 1e-12 * abs(ref).max()


def test_elasticity_in_the_nurbs_basis_takes_the_form_kernel_on_large_groups(monkeypatch):
    # the rewritten forms of the NURBS basis (first- and zero-order terms added, iga.discretisation.rational) go
    # through iga.assembly.forms.terms_data: compiled above the threshold, NumPy below, the same operator
    from iga import ElasticityProblem

    ring = pr.annulus(0.5, 1.0, 1.0, elements=(2, 1, 2))
    form_csr, seen = fast_assembly.form_csr, []
    monkeypatch.setattr(fast_assembly, "form_csr", lambda space, C, form: seen.append(form.count)
                        or form_csr(space, C, form))

    def stiffness(threshold):
        monkeypatch.setattr(fast_assembly, "MIN_POINTS", threshold)
        return ElasticityProblem(ring, youngs=70e9, poisson=0.33, refine=1).dirichlet("wmin", (0, 0, 0)).assemble()[0]

    K_numpy = stiffness(10**12)
    assert seen == []
    K_compiled = stiffness(0)
    assert len(seen) == 6 and max(seen) == 16  # six upper blocks; a rewritten off-diagonal block: 16 terms
    assert abs(K_compiled - K_numpy).max() <= 1e-12 * abs(K_numpy).max()
