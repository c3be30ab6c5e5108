"""Block scaling by clusters of strongly coupled unknowns: what a point smoother cannot damp on thin features.

A patch much thinner in one direction than in the others (a sliver that a
V-rep Boolean or a trimmed cell leaves, a bridge pressed flat) couples the
unknowns on its two faces almost rigidly: in the Jacobi-scaled matrix
Â = S A S (unit diagonal) their entry is close to -1.  An error equal on
both faces and oscillating along the sliver is then smooth for the strong
coupling and rough for the weak one, so neither the point smoother (Jacobi,
Chebyshev) nor the aggregates' constants reduce it: the classical
anisotropy failure of point relaxation, whose classical cure is to relax the
strongly coupled unknowns together (line or block relaxation; Trottenberg,
Oosterlee and Schueller 2001, Sec. 5.1).

Here the unknowns joined by couplings ``|Â_ij| >= theta`` form clusters (the
connected components of that graph, SciPy's csgraph; a component larger than
``MAX_SIZE`` unknowns is split by the same rule at the stricter threshold
(1 + theta) / 2, and so on), and Â is scaled symmetrically by the Cholesky
factors of its diagonal blocks on them:

    Â_b = L^-1 Â L^-T,    Â_C = L_C L_C^T on every cluster C,

so that Â_b has identity diagonal blocks.  Any point smoother on Â_b is a
block smoother on Â, and the near-null space carries over as L^T B.  The
winged-duck V-model (126k free unknowns, about 13,000 clusters of 2-28 at
theta 0.5): 296 AMG-CG iterations without, 36 with (docs/performance.md).
Vector problems in node-major order (elasticity) cluster whole nodes, two
nodes being coupled by the Frobenius norm of their 3 x 3 block over sqrt(3)
(1 for a block -I): thin layers under elasticity 45 -> 17 iterations, box u
cylinder 85 -> 57.  Unknowns
outside clusters keep the point scaling, so a model without strong
couplings gets exactly the point-scaled operator.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

#: coupling |Â_ij| (unit diagonal) from which two unknowns are relaxed together (docs/performance.md)
THETA = 0.5
#: largest cluster factored densely (unknowns); larger components are split at stricter thresholds
MAX_SIZE = 64


class ClusterScaling:
    """The block-diagonal factor L (and L^-1) of the clusters of a unit-diagonal symmetric CSR matrix.

    ``labels`` (n,): each unknown's cluster, -1 outside any; ``count``, ``unknowns``: clusters and the
    unknowns in them; ``largest``: the largest cluster's size.  Build with :meth:`of`, which returns None
    where no two unknowns are coupled that strongly.  Only the clusters' rows are read and factored, so
    the cost is that of the clusters, not of the matrix.
    """

    def __init__(self, A: sp.csr_matrix, labels: np.ndarray):
        n = A.shape[0]
        self.labels = labels
        inside = labels >= 0
        sizes = np.bincount(labels[inside])
        self.count, self.unknowns, self.largest = len(sizes), int(inside.sum()), int(sizes.max())
        order = np.argsort(np.where(inside, labels, len(sizes)), kind="stable")[: self.unknowns]
        start = np.concatenate([[0], np.cumsum(sizes)])
        pos = np.empty(n, np.int64)  # each clustered unknown's place in its cluster
        pos[order] = np.arange(self.unknowns) - np.repeat(start[:-1], sizes)
        C = A[order].tocoo()  # the clusters' rows only
        r, c = order[C.row], C.col
        keep = labels[c] == labels[r]
        r, c, v = r[keep], c[keep], C.data[keep]
        E_rows, E_cols, low, lowinv = [], [], [], []
        for k in np.unique(sizes):  # one batch of dense k x k factorisations per cluster size
            members = np.flatnonzero(sizes == k)
            rank = np.full(len(sizes), -1)
            rank[members] = np.arange(len(members))
            e = rank[labels[r]] >= 0
            blocks = np.zeros((len(members), k, k))
            blocks[rank[labels[r[e]]], pos[r[e]], pos[c[e]]] = v[e]
            L = np.linalg.cholesky(blocks)
            idx = order[start[members][:, None] + np.arange(k)]  # (m, k) global unknowns of each cluster
            a, b = np.tril_indices(k)
            E_rows.append(idx[:, a].ravel())
            E_cols.append(idx[:, b].ravel())
            low.append(L[:, a, b].ravel())
            lowinv.append(np.linalg.inv(L)[:, a, b].ravel())
        rows, cols = np.concatenate(E_rows), np.concatenate(E_cols)
        diag = (rows == cols).astype(float)
        #: L - I and L^-1 - I: non-zero on the clusters' blocks only
        self.dL = sp.csr_matrix((np.concatenate(low) - diag, (rows, cols)), shape=(n, n))
        self.dLinv = sp.csr_matrix((np.concatenate(lowinv) - diag, (rows, cols)), shape=(n, n))

    @classmethod
    def of(cls, A: sp.csr_matrix, theta: float = THETA, max_size: int = MAX_SIZE, node: int = 1
           ) -> ClusterScaling | None:
        """The clusters of ``A`` (symmetric, unit diagonal): components of ``|A_ij| >= theta`` between distinct
        nodes, of 2 to ``max_size`` unknowns; a larger component is split by the same rule at a stricter
        threshold, (1 + theta) / 2, until its parts fit.  None where there are none.  ``node``: unknowns
        per node (3 for node-major vector problems, whose nodes are clustered whole: unknown i is in node
        i // node, and two nodes are coupled by the Frobenius norm of their block over sqrt(node), 1 for a
        block -I; entries below theta / node are left out of it).  Raises numpy's LinAlgError where a
        cluster's block is not positive definite (A is not)."""
        n, m = A.shape[0], -(-A.shape[0] // node)
        # entries below theta / node cannot make two nodes strongly coupled on their own: left out
        at = np.flatnonzero(np.abs(A.data) >= theta / node)  # the unit diagonal among them
        if len(at) <= n:
            return None
        rows = (np.searchsorted(A.indptr, at, side="right") - 1) // node
        cols = A.indices[at] // node
        off = rows != cols
        rows, cols, strength = rows[off], cols[off], np.abs(A.data[at[off]])
        if node > 1:  # a node pair's coupling: |block|_F / sqrt(node), 1 for a block -I
            S = sp.coo_matrix((strength ** 2, (rows, cols)), shape=(m, m)).tocsr().tocoo()  # duplicates summed
            rows, cols, strength = S.row, S.col, np.sqrt(S.data / node)
        labels = _components(rows, cols, strength, m, theta, max_size // node)
        if labels.max() < 0:
            return None
        return cls(A, labels[np.arange(n) // node])

    def scale(self, A: sp.csr_matrix) -> sp.csr_matrix:
        """L^-1 A L^-T (A symmetric, the matrix the clusters were found on): identity blocks on the clusters.

        With E = L^-1 - I, non-zero on the clusters only: A + D, D = F + F^T + E F^T, F = E A.  The products
        touch the clusters' rows only, D is made exactly symmetric (its rounding would make the scaled
        matrix slightly unsymmetric), and A is merged with it once."""
        E = self.dLinv
        F = (E @ A).tocsr()
        D = F + F.T + E @ F.T
        out = (A + (D + D.T) * 0.5).tocsr()
        out.sort_indices()
        return out

    def lower(self, x: np.ndarray) -> np.ndarray:
        """L^-1 x."""
        return x + self.dLinv @ x

    def lower_t(self, x: np.ndarray) -> np.ndarray:
        """L^-T x."""
        return x + self.dLinv.T @ x

    def factor(self, x: np.ndarray) -> np.ndarray:
        """L x."""
        return x + self.dL @ x

    def factor_t(self, x: np.ndarray) -> np.ndarray:
        """L^T x."""
        return x + self.dL.T @ x

    def candidates(self, B: np.ndarray) -> np.ndarray:
        """The near-null space of the scaled matrix: L^T B (B (n, k) that of A)."""
        return self.factor_t(np.asarray(B))

    @property
    def info(self) -> dict:
        """Clusters relaxed together, the unknowns in them and the largest one's size."""
        return {"clusters": self.count, "clustered_unknowns": self.unknowns, "largest_cluster": self.largest}


def _components(rows, cols, strength, m: int, theta: float, limit: int) -> np.ndarray:
    """Cluster label of each of m nodes (-1 alone) from the couplings (rows, cols, strength): components of
    the couplings ``>= theta`` with 2 to ``limit`` nodes; the nodes of larger ones are split again from
    their own couplings at (1 + theta) / 2 (all such components at once), up to a threshold of 0.99."""
    labels = np.full(m, -1)
    count = 0
    while len(rows) and theta <= 0.99:
        keep = strength >= theta
        rows, cols, strength = rows[keep], cols[keep], strength[keep]
        G = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(m, m))
        _, comp = csgraph.connected_components(G, directed=False)
        sizes = np.bincount(comp)
        good = (sizes >= 2) & (sizes <= limit)
        fit = good[comp]  # components of two or more nodes: every node in one has a coupling
        ranks = np.cumsum(good) - 1
        labels[fit] = count + ranks[comp[fit]]
        count += int(good.sum())
        big = sizes > limit  # split again, from the couplings inside them only
        inside = big[comp[rows]]
        rows, cols, strength = rows[inside], cols[inside], strength[inside]
        theta = (1 + theta) / 2
    return labels
