"""Block relaxation of strongly coupled unknowns (solvers.clusters) and its use by the AMG preconditioner."""

import numpy as np
import pytest
import scipy.sparse as sp

import solvers
from geometry import primitives as pr
from iga import HeatProblem
from solvers.amg import AMGPreconditioner
from solvers.clusters import ClusterScaling


def _laplacian(n: int) -> sp.csr_matrix:
    """The 7-point Laplacian on an n^3 grid with a unit diagonal (off-diagonal -1/6: no strong coupling)."""
    T = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    I = sp.identity(n)
    A = sp.kron(sp.kron(T, I), I) + sp.kron(sp.kron(I, T), I) + sp.kron(sp.kron(I, I), T)
    return sp.csr_matrix(A / 6.0)


def _unit(A) -> sp.csr_matrix:
    d = 1 / np.sqrt(A.diagonal())
    out = sp.csr_matrix(sp.diags(d) @ A @ sp.diags(d))
    out.sort_indices()
    return out


def _planted(n=8):
    """The Laplacian with stiff springs 50 (e_i - e_j)(e_i - e_j)^T planted between neighbours: pairs
    and one chain of three, each a cluster of the Jacobi-scaled matrix."""
    A = _laplacian(n).tolil()
    groups = [(0, 1), (10, 11), (100, 100 + n), (200, 201, 202), (300, 300 + n * n)]
    for g in groups:
        for i, j in zip(g[:-1], g[1:]):
            A[i, i] += 50.0
            A[j, j] += 50.0
            A[i, j] -= 50.0
            A[j, i] -= 50.0
    return _unit(sp.csr_matrix(A)), groups


def test_the_planted_clusters_are_found_and_the_scaling_is_an_exact_congruence():
    A, groups = _planted()
    cs = ClusterScaling.of(A)
    assert cs.count == len(groups) and cs.unknowns == sum(len(g) for g in groups) and cs.largest == 3
    for g in groups:  # each planted group is one cluster, and nothing else is clustered
        assert len({int(cs.labels[i]) for i in g}) == 1 and cs.labels[g[0]] >= 0
    assert np.count_nonzero(cs.labels >= 0) == cs.unknowns
    Ab = cs.scale(A)
    rng = np.random.default_rng(1)
    x = rng.standard_normal(A.shape[0])
    np.testing.assert_allclose(cs.factor(Ab @ cs.factor_t(x)), A @ x, atol=1e-12)  # A = L Ab L^T
    np.testing.assert_allclose(cs.lower(cs.factor(x)), x, atol=1e-12)  # L^-1 L = I
    np.testing.assert_allclose(cs.lower_t(cs.factor_t(x)), x, atol=1e-12)
    assert abs(Ab - Ab.T).max() == 0.0  # exactly symmetric, as pyamg's symmetric hierarchy assumes
    np.testing.assert_allclose(Ab.diagonal(), 1.0, atol=1e-12)
    for g in groups:  # identity blocks on the clusters
        np.testing.assert_allclose(Ab[np.ix_(g, g)].toarray(), np.eye(len(g)), atol=1e-12)
    B = rng.standard_normal((A.shape[0], 2))
    np.testing.assert_allclose(cs.candidates(B), cs.factor_t(B), atol=0)
    np.testing.assert_allclose(cs.factor(Ab @ cs.candidates(B)), A @ B, atol=1e-12)  # L^T B is Ab's image of B


def test_no_strong_coupling_means_no_clusters_and_the_point_scaled_preconditioner():
    A = _laplacian(8)
    assert ClusterScaling.of(A) is None
    M = AMGPreconditioner(A)
    assert "clusters" not in M.info
    r = np.random.default_rng(2).standard_normal(A.shape[0])
    np.testing.assert_array_equal(M(r), AMGPreconditioner(A, block_theta=None)(r))


def test_components_larger_than_the_limit_are_split_at_stricter_thresholds():
    A, _ = _planted()
    assert ClusterScaling.of(A, max_size=2).largest == 2  # the chain of equal springs cannot split: left out
    assert ClusterScaling.of(A, max_size=1) is None
    # a chain a - b - c with a stiff a-b spring and a softer b-c one: one cluster of three, or {a, b} alone
    # once three is too many (split at (1 + 0.5) / 2 = 0.75, where only a-b is coupled strongly enough)
    L = _laplacian(6).tolil()
    for (i, j), k in (((40, 41), 60.0), ((41, 42), 30.0)):
        L[i, i] += k
        L[j, j] += k
        L[i, j] -= k
        L[j, i] -= k
    A = _unit(sp.csr_matrix(L))
    assert 0.5 < abs(A[41, 42]) < 0.75 < abs(A[40, 41])
    whole, split = ClusterScaling.of(A), ClusterScaling.of(A, max_size=2)
    assert whole.count == 1 and whole.unknowns == 3
    assert split.count == 1 and split.labels[40] == split.labels[41] >= 0 and split.labels[42] == -1


def test_bad_block_theta_and_indefinite_clusters_are_refused():
    A, _ = _planted()
    for bad in (0.0, 1.5, "0.5", np.nan, True):
        with pytest.raises(solvers.SolverError, match="block_theta"):
            AMGPreconditioner(A, block_theta=bad)
    C = sp.csr_matrix(np.array([[1.0, -1.5, 0.0], [-1.5, 1.0, 0.1], [0.0, 0.1, 1.0]]))  # positive diagonal
    with pytest.raises(solvers.SolverError, match="not positive definite"):
        AMGPreconditioner(C)


def _thin_layers(n: int, thickness: float = 1e-3):
    """A unit box of n x n x n linear elements with three more element layers ``thickness`` thick along z:
    across them the unknowns are nearly rigidly coupled, which point relaxation cannot smooth along the
    layers."""
    box = pr.box(degrees=(1, 1, 1), elements=(n, n, 1))
    return box.insert_knots(2, np.r_[np.linspace(0, 1, n + 1)[1:-1], 0.25 + np.arange(3) * 0.25 + thickness])[0]


def test_thin_element_layers_are_relaxed_together(monkeypatch):
    box = _thin_layers(16)

    def solve():
        pb = HeatProblem(box, source=lambda x: 1.0 + x[:, 0]).dirichlet("wmin", 0.0).robin("wmax", 2.0, 1.0)
        return pb.solve(solver="amg-cg", tol=1e-10)

    blocks = solve()
    info = blocks.info["solver"]
    assert info["clusters"] == 17 * 17 * 3 and info["largest_cluster"] == 2  # one pair per node and layer
    with monkeypatch.context() as m:
        m.setattr(ClusterScaling, "of", classmethod(lambda cls, A, *a, **k: None))
        points = solve()
    assert "clusters" not in points.info["solver"]
    assert info["iterations"] <= 0.6 * points.info["solver"]["iterations"]
    exact = HeatProblem(box, source=lambda x: 1.0 + x[:, 0]).dirichlet("wmin", 0.0).robin("wmax", 2.0, 1.0)
    u = exact.solve(solver="direct").u
    for s in (blocks, points):
        assert np.abs(s.u - u).max() <= 1e-7 * np.abs(u).max()


@pytest.mark.slow
def test_thin_layers_under_elasticity_are_relaxed_by_node(monkeypatch):
    from iga import ElasticityProblem

    box = _thin_layers(12)

    def solve():
        pb = ElasticityProblem(box, youngs=1.0, poisson=0.3).dirichlet("wmin", 0.0)
        return pb.traction("wmax", [0.1, 0.0, -1.0]).solve(solver="amg-cg", tol=1e-10)

    blocks = solve()
    info = blocks.info["solver"]
    assert info["clusters"] == 13 * 13 * 3 and info["largest_cluster"] == 6  # pairs of nodes, three unknowns each
    with monkeypatch.context() as m:
        m.setattr(ClusterScaling, "of", classmethod(lambda cls, A, *a, **k: None))
        points = solve()
    assert info["iterations"] <= 0.5 * points.info["solver"]["iterations"]
    exact = ElasticityProblem(box, youngs=1.0, poisson=0.3).dirichlet("wmin", 0.0)
    u = exact.traction("wmax", [0.1, 0.0, -1.0]).solve(solver="direct").u
    for s in (blocks, points):
        assert np.abs(s.u - u).max() <= 1e-7 * np.abs(u).max()


def test_nodes_are_coupled_by_their_whole_block():
    # two nodes of three unknowns, unit diagonal: a block -0.6 I couples them (Frobenius norm over sqrt(3):
    # 0.6 >= 0.5); one entry -0.6 alone does not (0.35), though it would couple two scalar unknowns
    def two_nodes(B):
        return sp.csr_matrix(np.block([[np.eye(3), B], [B.T, np.eye(3)]]))

    whole = ClusterScaling.of(two_nodes(-0.6 * np.eye(3)), node=3)
    assert whole.count == 1 and whole.unknowns == 6 and whole.largest == 6
    one = two_nodes(np.diag([-0.6, 0.0, 0.0]))
    assert ClusterScaling.of(one, node=3) is None
    assert ClusterScaling.of(one).unknowns == 2  # unknown by unknown: the pair (0, 3)
